"""Writing result files safely: atomically (a kill mid-write never leaves half a file or loses the previous
one), and into an output folder checked writable before any work starts."""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

if sys.platform == "win32":  # no fcntl there: importing it stopped every clm command on Windows
    import msvcrt
else:
    import fcntl


def atomic_write(path: Path, text: str | bytes) -> None:
    """Write ``text`` (UTF-8) or bytes to ``path`` through a temporary file in the same folder, fsync, then
    rename."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as e:  # name the file asked for, not the temporary one
        raise OSError(e.errno, e.strerror, str(path)) from None
    data = text.encode("utf-8") if isinstance(text, str) else text
    try:
        if hasattr(os, "fchmod"):  # mkstemp's 0600 made readable as any file written (no fchmod on Windows < 3.13)
            os.fchmod(fd, 0o644)
        f = os.fdopen(fd, "wb")
    except BaseException:
        os.close(fd)  # before the removal: Windows removes no open file
        Path(tmp).unlink(missing_ok=True)
        raise
    try:
        with f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def check_out_dir(out: str | Path, files: Iterable[str] = ()) -> Path:
    """The output folder, created and proven writable (a probe file is written and removed); ValueError
    naming the problem: an empty name, a file in the way, no permission, or one of ``files`` being a folder."""
    if str(out).strip() == "":
        raise ValueError("--out is empty; name the output folder")
    d = Path(out)
    if d.exists() and not d.is_dir():
        raise ValueError(f"--out {str(d)!r} exists and is not a folder")
    made = new_folders(d)
    try:
        d.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=d, prefix=".clm-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        remove_empty(made)  # a refused new/a/<too long> left new/a behind
        raise ValueError(f"--out {str(d)!r}: cannot write there ({e.strerror})") from None
    for name in files:
        if (d / name).is_dir():
            raise ValueError(f"--out {str(d)!r}: {name} is a folder; it would be overwritten by a file")
    return d


def new_folders(d: Path) -> list[Path]:
    """The folders ``d.mkdir(parents=True)`` would make, ``d`` first: what to remove again after a refusal."""
    made = []
    for p in [d, *d.parents]:
        if p.exists():
            break
        made.append(p)
    return made


def remove_empty(folders: Iterable[Path]) -> None:
    """Remove ``folders`` (innermost first) that are empty: rmdir leaves one that anything was put in since."""
    for p in folders:
        try:
            p.rmdir()
        except OSError:  # not empty, never made (a name too long), or gone
            pass


def backslash_hint(path: str | Path) -> str:
    """A word for a Windows path typed on a system whose folder separator is '/' (lab rehearsal), else ""."""
    return " ('\\' is not a folder separator here: use '/')" if "\\" in str(path) and os.sep == "/" else ""


LOCK_TRIES = 100  # takes of a folder's lock file before giving up (it was removed under each one)
LOCK_WAIT = 0.05  # s between takes on Windows while the file is held by another program
LOCK_AT = 1 << 30  # Windows: the byte locked, far past the holder's note (another process cannot read a locked byte)


def try_lock(f: IO[Any]) -> bool:
    """Lock the open file ``f`` for this process without waiting: False when another process holds it. The lock
    goes with the process, however it ends: ``flock``, or on Windows a lock on byte ``LOCK_AT`` (locking reads from
    the file's position; past its end is allowed, and leaves the note before it readable)."""
    if sys.platform == "win32":
        at = f.tell()
        f.seek(LOCK_AT)
        try:
            msvcrt.locking(f.fileno(), msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        finally:
            f.seek(at)
        return True
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def unlock(f: IO[Any]) -> None:
    """Give up :func:`try_lock`'s lock on ``f``."""
    if sys.platform == "win32":
        f.seek(LOCK_AT)
        msvcrt.locking(f.fileno(), msvcrt.LK_UNLCK, 1)
    else:
        fcntl.flock(f, fcntl.LOCK_UN)


def holder(f: IO[str]) -> str:
    """What the process holding ``f``'s lock wrote into it ("4242 clm study"), "" if unreadable."""
    try:
        f.seek(0)
        return f.read(4096).strip()
    except OSError:
        return ""


@contextmanager
def dir_lock(directory: str | Path, what: str, remove: bool = False) -> Iterator[None]:
    """Hold ``DIR/.lock`` while ``what`` ("clm design") writes into ``DIR``: a second command into the same folder
    is refused (ValueError naming the process) instead of writing over the first's files. The lock goes with the
    process, however it ends. ``remove``: take the file away at the end (a run's folder lists its outputs only);
    a command that opened the file as it went locks the new one instead."""
    d = Path(directory)
    path = d / ".lock"
    for _ in range(LOCK_TRIES):
        d.mkdir(parents=True, exist_ok=True)
        try:
            f = open(path, "a+")  # noqa: SIM115 - held until the end
        except FileNotFoundError:  # the folder was removed since (a refused study's cleanup): make it again
            continue
        except PermissionError:
            if sys.platform != "win32":
                raise
            time.sleep(LOCK_WAIT)  # being removed while a scanner or indexer held it open: it goes in a moment
            continue
        if not try_lock(f):
            pid, _, who = holder(f).partition(" ")  # "4242 clm study": the holder, not this command
            f.close()
            raise ValueError(f"{d}: another {who or 'command'} is writing into it (process {pid or '?'}); wait for "
                             "it to end, or choose another --out")
        if _names(f, path):
            break
        f.close()  # removed by the holder that just finished: lock the file there now
    else:
        raise ValueError(f"{d}: its lock file {path.name} could not be taken in {LOCK_TRIES} tries (removed or held "
                         "open by another program?); choose another --out")
    try:
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()} {what}")
        f.flush()
        yield
    finally:
        if sys.platform == "win32":  # an open file cannot be removed there: let it go first
            unlock(f)
            f.close()
            if remove:
                with suppress(OSError):  # opened by another command since: its lock now
                    path.unlink()
        else:
            if remove and _names(f, path):  # still ours (never another command's newer lock)
                path.unlink(missing_ok=True)
            unlock(f)
            f.close()


def _names(f: IO[Any], path: Path) -> bool:
    """Whether ``path`` is the file ``f`` has open (not removed, nor replaced by another)."""
    try:
        return os.fstat(f.fileno()).st_ino == os.stat(path).st_ino
    except FileNotFoundError:
        return False


MAX_RESULT_BYTES = 512 * 2**20
"""The largest result.json read back (clm compare, clm design --overwrite, clm-charts)."""


def read_design_result(path: Path) -> dict[str, Any]:
    """A ``clm design`` result.json as data; ValueError naming the file when it is not one (too large, not a
    regular file, not JSON, another format)."""
    from core.analysis.targets import read_user_file
    from core.optimize.run import RESULT_FORMAT

    text = read_user_file(path, MAX_RESULT_BYTES, "result file")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON: {e.msg.removesuffix(' at')} at line {e.lineno}") from None
    except RecursionError:
        raise ValueError(f"{path}: not a 'clm design' result: nested too deep") from None
    if not isinstance(data, dict) or data.get("format") != RESULT_FORMAT:
        raise ValueError(f"{path}: not a 'clm design' result")
    return data


def slug(text: str) -> str:
    """A file-name-safe version of a name (``stephenson1/X3`` -> ``stephenson1-X3``)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "design"


def stage_file(k: int, name: str) -> str:
    """``<k>_<stage>.csv``: a stage's members in a ``clm design --out`` folder."""
    return f"{k}_{name}.csv"


def chart_file(k: int, name: str) -> str:
    """``pareto-<k>_<stage>.png``: the stage's chart clm-charts draws into the same folder."""
    return f"pareto-{k}_{slug(name)}.png"
