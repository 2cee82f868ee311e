"""``clm-studio``: serve the design studio on localhost.

    clm-studio [--host 127.0.0.1] [--port 8080] [--session FILE] [--token [TOKEN]]
    clm-studio --warm-up     # compile the numeric kernels into numba's cache, then exit (studio.warmup)

Opens on the paper's Stephenson-I X3 design, animating, against the compound-cycloid target
(or on the session in FILE, which is then saved back after every change). The studio sits behind
``studio.gate``: no other web page can drive it, and with ``--token`` only a browser that opened the
printed URL (which carries the token) gets in. Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import signal
import sys
import threading
import time
from pathlib import Path
from typing import NoReturn

from core.kinematics.kernel_cache import is_warm
from core.kinematics.memory import keep_freed_memory
from studio.address import exposure_warning, url_for
from studio.app import Studio
from studio.gate import Gate, check_token, new_token
from studio.session_file import SessionLock, load_session, save_session
from studio.state import Session


class _Parser(argparse.ArgumentParser):
    """argparse whose errors are one line (``clm-studio: error: ...``, exit 2), without the usage block."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _port(text: str) -> int:
    if not text.strip().isdigit() or not 0 <= int(text) <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number 0-65535, got {text!r}")
    return int(text)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="clm-studio", description="Design studio for closed-chain legged mechanisms.")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=_port, default=8080,
                   help="port 0-65535 (default 8080; the next free one if taken; 0: any free one)")
    p.add_argument("--session", type=Path, metavar="FILE",
                   help="session JSON to open if it exists, and to save to after every change")
    p.add_argument("--token", nargs="?", const="", metavar="TOKEN",
                   help="admit only browsers that open the printed URL, which carries this token (without a "
                        "value: a random one, which also keeps it out of the process list)")
    p.add_argument("--warm-up", action="store_true",
                   help="compile the numeric kernels (every stage with every algorithm, tiny) and exit: the first "
                        "Run of a fresh install then starts at once (scripts/studio does it once per change)")
    return p


def cold_note() -> str | None:
    """What the studio says at its start when these sources' kernels have not been compiled by ``--warm-up`` (a QA
    session's first CMOES run took 86 s, 80 of them compiling, with nothing said at the start); None when they
    have, or when numba's cache is not ours to look at."""
    if is_warm() is not False:
        return None
    return ("CLM Studio: the numeric kernels of this version are not compiled yet: the first run of each kind "
            "compiles its own (up to a minute; the Stages status says so). `clm-studio --warm-up` compiles them all "
            "now; ./scripts/studio does it by itself.")


def main(argv: list[str] | None = None) -> int:
    """Run the studio until Ctrl-C; returns the exit status."""
    args = _parser().parse_args(argv)
    keep_freed_memory()
    if args.warm_up:
        from studio.warmup import warm_up

        t = time.perf_counter()
        print("CLM Studio: compiling the numeric kernels (numba caches them on disk)", flush=True)
        warm_up(lambda line: print(line, flush=True))
        print(f"CLM Studio: kernels ready in {time.perf_counter() - t:.0f} s", flush=True)
        return 0
    studio: Studio | None = None
    gate: Gate | None = None
    lock: SessionLock | None = None
    said: str | None = None
    if args.session is not None and args.session.is_symlink():
        # Saved through the link to its file: each save replaced the link itself with a file, the real one was
        # never written again, and the lock (on the resolved path) no longer kept a second studio off it (QA, s. 37).
        args.session = args.session.resolve()
    # SIGTERM (kill, systemd, docker stop) stops the studio as Ctrl-C does: the run stopped between generations and
    # kept with its pick, the session saved; it ended the process at once, losing the run's last seconds (QA, s. 37).
    previous = signal.signal(signal.SIGTERM, _interrupt) if threading.current_thread() is threading.main_thread() \
        else None
    try:  # Ctrl-C from here on stops the studio cleanly, whenever it comes (even while the address is printed)
        try:
            token = None if args.token is None else check_token(args.token) if args.token else new_token()
            if args.session is not None and not args.session.parent.is_dir():  # it read "[Errno 2] ... s.json.tmp"
                raise ValueError(f"--session {args.session}: there is no folder {args.session.parent}; create it, "
                                 "or give a session file in a folder that exists")
            if args.session is not None:
                lock = SessionLock(args.session)  # one studio per session file
            if args.session is not None and args.session.exists():
                session = load_session(args.session)
            else:
                session = Session.default()
            if args.session is not None:
                save_session(session, args.session)  # fail now, not on the first autosave
            # viser checks no Host, Origin or token: it listens on a free loopback port behind the gate. It also
            # prints its own address box; the one line below is the address to open.
            with contextlib.redirect_stdout(io.StringIO()):
                studio = Studio(session, "127.0.0.1", 0, session_path=args.session)
            gate = Gate(args.host, args.port, studio.server.get_port(), token, on_page=studio.page_requested)
            port = gate.get_port()
        except (OSError, ValueError) as exc:
            if studio is not None:
                with contextlib.redirect_stdout(io.StringIO()):
                    studio.close()
                studio = None
            print(f"clm-studio: error: {exc}", file=sys.stderr)
            return 2
        warning = exposure_warning(args.host, port, token is not None)
        if warning is not None:
            print(warning, file=sys.stderr, flush=True)
        if lock is not None:
            lock.note(url_for(args.host, port, None))  # the address without the token: the lock file is not secret
        print(f"CLM Studio: {url_for(args.host, port, token)}  (Ctrl-C to stop)", flush=True)
        if (note := cold_note()) is not None:
            print(note, flush=True)
        # A timed wait: Ctrl-C's KeyboardInterrupt is raised in this thread, but the kernel may deliver SIGINT to
        # any of the server's threads, and then an untimed wait here never wakes (1 in 8 stops hung so).
        idle = threading.Event()
        while not idle.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        if gate is not None:
            gate.close()
        if studio is not None:
            studio.close()
            said = studio.final_save()  # a session that could not be saved goes to the cache, and says where
        if lock is not None:
            lock.release()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if said is not None:
        print(f"clm-studio: {said}", file=sys.stderr, flush=True)
        print("CLM Studio stopped.", flush=True)
        return 1
    print("CLM Studio stopped.", flush=True)
    return 0


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


if __name__ == "__main__":
    sys.exit(main())
