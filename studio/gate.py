"""The studio's front door: what ``clm-studio`` listens on, in front of viser (which checks nothing).

viser's server listens on a free loopback port; this gate listens where the user asked and relays a
connection only if its first request passes:

- a studio bound to loopback answers only to a loopback ``Host`` (a web page that rebinds its own name to
  127.0.0.1 is refused);
- a websocket's ``Origin``, when a browser sends one, is the page's own address (another web page cannot
  open the studio's websocket and drive it);
- with a token (``--token``): the ``token`` query parameter of the printed URL, or the cookie the gate sets
  when it sees that parameter (the page's scripts and websocket carry no query). Compared in constant time.

Anything else gets ``403 Forbidden`` and is closed; after the first request a connection's bytes are relayed
unchanged. An admitted request for the page itself (``GET /``) is also reported to ``on_page``: the studio holds
its scene still while a new page loads. Plain HTTP: the token keeps out whoever lacks the URL, not someone who
can read the traffic.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import hmac
import re
import secrets
import threading
from collections.abc import Callable
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qsl, urlencode, urlsplit

from studio.address import is_loopback

TOKEN = re.compile(r"[A-Za-z0-9_.~-]{8,128}")
MAX_HEAD_BYTES = 64 * 1024  # a request head larger than this is refused (viser's client sends < 2 kB)
HEAD_TIMEOUT = 10.0  # seconds a client may take to send its request head
PORT_TRIES = 100  # like viser: if the port is taken, the next free one


def new_token() -> str:
    """A random token for the URL (128 bits, URL-safe)."""
    return secrets.token_urlsafe(16)


def check_token(token: str) -> str:
    """The token if usable in a URL as it is; ValueError naming the allowed form otherwise."""
    if not TOKEN.fullmatch(token):
        raise ValueError("--token: expected 8 to 128 characters from A-Z a-z 0-9 _ . ~ -, "
                         f"got {len(token)} characters" + ("" if token.isascii() else " (not ASCII)"))
    return token


def host_name(authority: str) -> str:
    """``localhost`` of ``localhost:8080``, ``::1`` of ``[::1]:8080``."""
    if authority.startswith("["):
        return authority[1:].split("]", 1)[0]
    return authority.rsplit(":", 1)[0] if authority.count(":") == 1 else authority


class Gate:
    """Relays admitted connections to ``127.0.0.1:upstream_port``; refuses the rest (see the module doc).

    Args:
        host, port: where to listen (port 0: any free port; a taken port: the next free one).
        upstream_port: the studio's viser server, on loopback.
        token: the secret the URL must carry (see :func:`check_token`), or None for none.
        on_page: called (in the gate's thread) for each admitted request of the page (see :func:`is_page`).
    """

    def __init__(self, host: str, port: int, upstream_port: int, token: str | None = None,
                 on_page: Callable[[], None] | None = None) -> None:
        self.host = host
        self._on_page = on_page
        self.upstream_port = upstream_port
        self._want_port = port
        self._loopback = is_loopback(host)
        self._token = None if token is None else check_token(token).encode()
        self._cookie = f"clm_studio_{upstream_port}"  # cookies ignore ports: one name per studio
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._port = 0
        self._error: Exception | None = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="clm-studio-gate", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None or self._port == 0:
            why = getattr(self._error, "strerror", None) or self._error or "no free port"
            raise OSError(f"--host {host} --port {port}: cannot listen there ({why})")

    def get_port(self) -> int:
        return self._port

    def close(self) -> None:
        """Stop listening and drop open connections."""
        if self._loop is not None and self._stop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(5.0)

    # The event loop thread ------------------------------------------------------------------

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except Exception as exc:  # reported by __init__, which waits for this thread to be ready
            self._error = exc
        finally:
            self._ready.set()
            loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        tasks: set[asyncio.Task[None]] = set()

        async def on_connect(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            task = asyncio.current_task()
            assert task is not None
            tasks.add(task)
            try:
                await self._handle(reader, writer)
            except asyncio.CancelledError:
                # Closing the gate cancels the connections it relays. Ending quietly: Python 3.11's stream
                # server asks a cancelled handler for its exception in a callback and prints a traceback.
                writer.close()
            finally:
                tasks.discard(task)

        server = None
        ports = [0] if self._want_port == 0 else range(self._want_port, self._want_port + PORT_TRIES)
        for port in ports:
            try:
                server = await asyncio.start_server(on_connect, self.host, port, limit=MAX_HEAD_BYTES)
                break
            except OSError as exc:
                self._error = exc
                if exc.errno != errno.EADDRINUSE:
                    break
        if server is None:
            return
        self._error = None
        self._port = server.sockets[0].getsockname()[1]
        self._ready.set()
        async with server:
            await self._stop.wait()
            server.close()
            for t in list(tasks):
                t.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
        except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError, ConnectionError):
            writer.close()
            return
        decision = self.decide(head)
        if decision is not None:  # a response of our own: redirect or refusal
            writer.write(decision)
            with contextlib.suppress(ConnectionError):
                await writer.drain()
            writer.close()
            return
        if self._on_page is not None and is_page(head):
            self._on_page()
        try:
            up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.upstream_port)
        except OSError:
            writer.write(_response(502, "Bad Gateway", "CLM Studio is not running behind this address."))
            writer.close()
            return
        up_writer.write(head)
        await asyncio.gather(_pipe(reader, up_writer), _pipe(up_reader, writer), return_exceptions=True)

    # The decision (pure) --------------------------------------------------------------------

    def decide(self, head: bytes) -> bytes | None:
        """None to relay a request with this head; else the response to send instead (303 or 4xx)."""
        lines = head.decode("latin-1").split("\r\n")
        parts = lines[0].split(" ")
        if len(parts) != 3 or not parts[2].startswith("HTTP/"):
            return _response(400, "Bad Request", "Not an HTTP request.")
        headers: dict[str, str] = {}
        for line in lines[1:]:
            name, sep, value = line.partition(":")
            if sep:
                headers[name.strip().lower()] = value.strip()
        host = headers.get("host", "")
        if self._loopback and not is_loopback(host_name(host)):
            return _response(403, "Forbidden", "This CLM Studio answers only to localhost.")
        websocket = headers.get("upgrade", "").lower() == "websocket"
        origin = headers.get("origin")
        if websocket and origin is not None and origin.lower() not in (f"http://{host}".lower(),
                                                                      f"https://{host}".lower()):
            return _response(403, "Forbidden", "Another web page may not open the studio's connection.")
        if self._token is None or self._matches(self._cookie_value(headers.get("cookie", ""))):
            return None
        target = urlsplit(parts[1])
        query = parse_qsl(target.query, keep_blank_values=True)
        given = [v for k, v in query if k == "token"]
        if given and self._matches(given[-1]):
            if websocket:
                return None
            # Remember the token in a cookie and drop it from the address bar.
            rest = urlencode([(k, v) for k, v in query if k != "token"])
            location = (target.path or "/") + (f"?{rest}" if rest else "")
            cookie = f"{self._cookie}={self._token.decode()}; Path=/; HttpOnly; SameSite=Strict"
            return _response(303, "See Other", "", extra=f"Location: {location}\r\nSet-Cookie: {cookie}\r\n")
        return _response(403, "Forbidden", "This CLM Studio needs its token: open the full URL clm-studio printed "
                                           "(it ends in ?token=...).")

    def _cookie_value(self, header: str) -> str | None:
        try:
            morsel = SimpleCookie(header).get(self._cookie)
        except CookieError:
            return None
        return None if morsel is None else morsel.value

    def _matches(self, value: str | None) -> bool:
        assert self._token is not None
        return value is not None and hmac.compare_digest(value.encode("utf-8", "replace"), self._token)


def is_page(head: bytes) -> bool:
    """Is this request head a browser's ``GET`` of the page (``/``, ``/index.html``, with any query), not one of
    its scripts, styles or its websocket?"""
    first = head.split(b"\r\n", 1)[0].split(b" ")
    if len(first) != 3 or first[0] != b"GET" or b"\r\nupgrade:" in head.lower():
        return False
    path = first[1].split(b"?", 1)[0]
    return path in (b"/", b"/index.html")


def _response(status: int, reason: str, body: str, extra: str = "") -> bytes:
    data = body.encode() + (b"\n" if body else b"")
    return (f"HTTP/1.1 {status} {reason}\r\nContent-Type: text/plain; charset=utf-8\r\n"
            f"Content-Length: {len(data)}\r\nConnection: close\r\nCache-Control: no-store\r\n{extra}\r\n"
            ).encode("latin-1") + data


async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Copy bytes until either side closes."""
    try:
        while chunk := await reader.read(65536):
            writer.write(chunk)
            await writer.drain()
    finally:
        writer.close()
