"""``clm-studio``: serve the design studio on localhost.

    clm-studio [--host 127.0.0.1] [--port 8080] [--session FILE]

Opens on the paper's Stephenson-I X3 design, animating, against the compound-cycloid target
(or on the session in FILE, which is then saved back after every change). Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import ipaddress
import sys
import threading
from pathlib import Path

from core.kinematics.memory import keep_freed_memory
from studio.app import Studio
from studio.session_file import load_session, save_session
from studio.state import Session


def is_loopback(host: str) -> bool:
    """True for this machine only: localhost, 127.0.0.0/8, ::1."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def exposure_warning(host: str, port: int) -> str | None:
    """The warning printed when the studio listens beyond this machine (None on loopback)."""
    if is_loopback(host):
        return None
    return (f"clm-studio: warning: listening on {host} port {port}: anyone who can reach this machine can drive "
            f"the studio and read and overwrite its session; there is no authentication. For a colleague, keep "
            f"the default --host 127.0.0.1 and share it through an SSH tunnel (ssh -L {port}:127.0.0.1:{port} ...).")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="clm-studio", description="Design studio for closed-chain legged mechanisms.")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; the next free one if taken)")
    p.add_argument("--session", type=Path, metavar="FILE",
                   help="session JSON to open if it exists, and to save to after every change")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the studio until Ctrl-C; returns the exit status."""
    args = _parser().parse_args(argv)
    keep_freed_memory()
    try:
        if args.session is not None and args.session.exists():
            session = load_session(args.session)
        else:
            session = Session.default()
        if args.session is not None:
            save_session(session, args.session)  # fail now, not on the first autosave
        studio = Studio(session, args.host, args.port, session_path=args.session)
    except (OSError, ValueError) as exc:
        print(f"clm-studio: error: {exc}", file=sys.stderr)
        return 2
    warning = exposure_warning(args.host, studio.server.get_port())
    if warning is not None:
        print(warning, file=sys.stderr, flush=True)
    print(f"CLM Studio: {studio.url}  (Ctrl-C to stop)", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        studio.close()
    print("CLM Studio stopped.", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
