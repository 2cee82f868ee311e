"""The session file on disk: written atomically after every change, read back at start-up (JSON, never pickle)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from studio.state import Session


def save_session(session: Session, path: Path) -> None:
    """Write a session as JSON via a temporary file and an atomic rename."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(session.to_dict(), indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def load_session(path: Path) -> Session:
    """A session from a JSON file; ValueError naming the problem."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    try:
        return Session.from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
