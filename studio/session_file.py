"""The session file on disk: written atomically after every change, read back at start-up (JSON, never pickle)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import stat
import time
from pathlib import Path
from typing import IO

from core.formats.files import holder, try_lock, unlock
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
    mode = None
    if path.exists():  # its owner's choices stay: a 600 file became 644, a read-only one a writable one (QA, s. 37)
        mode = stat.S_IMODE(path.stat().st_mode)
        if not mode & stat.S_IWUSR:
            raise ValueError(f"{path} is read-only (mode {mode:o}): the studio does not write over it; make it "
                             "writable, or give another --session")
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_bytes(data)
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):  # (a folder in its place: the write's own error is the one to say)
            tmp.unlink(missing_ok=True)  # a full disk left a partial s.json.tmp beside the session (QA, session 37)
        raise


def rescue_session(session: Session, path: Path) -> Path:
    """Write a session that could not be saved to ``path`` into the user's cache instead (``unsaved/``, named after
    ``path`` and the time); the file written. OSError if that fails too."""
    folder = LOCK_DIR.parent / "unsaved"
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{path.stem}-{time.strftime('%Y%m%d-%H%M%S')}.json"
    out.write_bytes((json.dumps(session.to_dict(), separators=(",", ":")) + "\n").encode("utf-8"))
    return out


def read_session_bytes(content: bytes) -> Session:
    """A session from an upload's bytes; ValueError naming the problem."""
    if len(content) > MAX_SESSION_BYTES:
        raise ValueError(f"a session is at most {MAX_SESSION_BYTES // 2**20} MB")
    return Session.from_dict(parse_json(content))


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


# Where studios note which session files they hold: in the user's cache, not beside the session (no litter there).
LOCK_DIR = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "clm-studio" / "sessions"


class SessionLock:
    """One studio per session file. Two studios on one file each saved after every change and the last save won:
    a second one's topology switch and its branch were lost. The lock is an flock on a file named after the
    session's path (the session itself is replaced on every save, so it cannot carry the lock); it goes with the
    process, however it ends."""

    def __init__(self, path: Path) -> None:
        self.path = path
        key = hashlib.sha256(str(path.resolve()).encode("utf-8")).hexdigest()[:20]
        try:
            LOCK_DIR.mkdir(parents=True, exist_ok=True)
            self._file: IO[str] | None = open(LOCK_DIR / f"{key}.lock", "a+")  # noqa: SIM115 - held until release()
        except OSError:  # no writable cache (a read-only home): the studio still runs, unguarded
            self._file = None
            return
        if not try_lock(self._file):
            who = holder(self._file) or "?"
            self._file.close()
            self._file = None
            pid, _, url = who.partition(" ")
            at = f", {url}" if url else ""
            raise ValueError(f"{path} is open in another clm-studio (process {pid}{at}); use that one, stop it "
                             "first, or give another --session")
        self.note("")

    def note(self, url: str) -> None:
        """Say who holds it (this process, at ``url``), for the message a second studio gets."""
        if self._file is not None:
            self._file.seek(0)
            self._file.truncate()
            self._file.write(f"{os.getpid()} {url}".strip())
            self._file.flush()

    def release(self) -> None:
        if self._file is not None:
            unlock(self._file)
            self._file.close()
            self._file = None
