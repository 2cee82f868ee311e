"""The session file on disk: written atomically after every change, read back at start-up (JSON, never pickle)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from core.formats.session import MAX_SESSION_BYTES, parse_json
from studio.state import Session


def save_session(session: Session, path: Path) -> None:
    """Write a session as JSON via a temporary file and an atomic rename; ValueError, the file left as it was,
    when the session has outgrown what a session file may hold (it would not load again)."""
    data = (json.dumps(session.to_dict(), separators=(",", ":")) + "\n").encode("utf-8")
    if len(data) > MAX_SESSION_BYTES:
        raise ValueError(f"the session has grown to {len(data) / 2**20:.0f} MB, past the "
                         f"{MAX_SESSION_BYTES // 2**20} MB a session file may hold, so {path} keeps its last save; "
                         "delete branches in the History panel to save again")
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def load_session(path: Path) -> Session:
    """A session from a JSON file; ValueError naming the problem."""
    try:
        if not path.is_file():
            raise ValueError("not a regular file")
        if path.stat().st_size > MAX_SESSION_BYTES:
            raise ValueError(f"a session is at most {MAX_SESSION_BYTES // 2**20} MB")
        return Session.from_dict(parse_json(path.read_bytes()))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
