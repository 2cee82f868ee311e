"""Scene frames paced by what the pages have drawn: no page falls behind the server.

A page applies scene messages once per animation frame, so a page that draws 5 frames a second
(software WebGL) facing 40 frames a second queues them, and what it shows trails the server by seconds.
After each scene frame the studio sends every page a probe (viser's localStorage read, answered in order
after the messages before it, at the page's next animation frame); the next frame waits until every page
has answered. Frames then go at the rate the slowest page draws, never faster than asked. A page that has
not answered for ``STALL`` seconds (a frozen or closed tab) no longer holds the others back.

The probe is not a GUI message, so viser's client draws its scene for it: it follows scene frames only
(GUI-only pushes are applied on arrival without a draw).
"""

from __future__ import annotations

import threading
import time
import uuid

import viser
from viser import _messages

STALL = 2.0  # seconds without an answer after which a page no longer paces the pushes
PROBE_KEY = "clm-studio-pace"


class Pacer:
    """Tracks one outstanding probe per page; ``ready()`` says whether the pages have caught up."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._lock = threading.Lock()
        self._pending: dict[int, tuple[str, float]] = {}  # client id -> (probe id, sent at)
        self.answered = 0
        self.waits = 0
        server._websock_server.register_handler(_messages.LocalStorageGetItemResponseMessage, self._on_answer)
        server.on_client_disconnect(lambda client: self._forget(client.client_id))

    def _on_answer(self, client_id: int, message: _messages.LocalStorageGetItemResponseMessage) -> None:
        with self._lock:
            probe = self._pending.get(client_id)
            if probe is not None and probe[0] == message.request_uuid:
                del self._pending[client_id]
                self.answered += 1

    def _forget(self, client_id: int) -> None:
        with self._lock:
            self._pending.pop(client_id, None)

    def ready(self) -> bool:
        """True when no page is still busy with an earlier push (stalled pages excepted)."""
        now = time.monotonic()
        with self._lock:
            busy = any(now - sent < STALL for _, sent in self._pending.values())
        if busy:
            self.waits += 1
        return not busy

    def probe(self) -> None:
        """After a push: ask every page without an outstanding probe to answer once it has handled it."""
        self.server.flush()  # the push leaves now, ahead of the probes
        now = time.monotonic()
        for client in list(self.server.get_clients().values()):
            with self._lock:
                old = self._pending.get(client.client_id)
                if old is not None and now - old[1] < STALL:
                    continue
                probe_id = uuid.uuid4().hex
                self._pending[client.client_id] = (probe_id, now)
            client._websock_connection.queue_message(
                _messages.LocalStorageGetItemRequestMessage(key=PROBE_KEY, request_uuid=probe_id))
            client.flush()
