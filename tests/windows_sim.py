"""Run ``clm`` as on Windows, on Linux: ``python tests/windows_sim.py ARGS...`` (or ``-c CODE``); used by
tests/test_locks_on_windows.py.

The modules that ask which system they run on (core.formats.files, core.optimize.workers,
core.kinematics.memory) are given Windows's
answer, "win32", and what Windows has in place of fcntl: ``msvcrt.locking``, which locks from the file's current
position (an flock here, so two opens of one file conflict; an unlock must match a lock's position and size; each
call's position is printed at exit), and reads
that fail over a byte another process has locked (``WINSIM_LOCKS`` notes who locked what; ``WINSIM_BUSY=n``: the
first n opens of a lock file are refused, as while another process removes it). For every
module: no ``os.fchmod`` (Windows before Python 3.13), no ``os.O_NONBLOCK``, ``ctypes.CDLL(None)`` a TypeError, and
no removal of a file that any process still has open (Python's ``open`` does not share delete: WinError 32). The
standard library stays this system's (it cannot import as Windows's here); that core.formats.files imports on
Windows is checked apart.
"""

from __future__ import annotations

import atexit
import ctypes
import glob
import hashlib
import os
import sys
import types
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fcntl as posix  # noqa: E402

from core.cli import build_parser  # noqa: E402
from core.formats import files  # noqa: E402
from core.kinematics import memory  # noqa: E402
from core.optimize import workers  # noqa: E402

build_parser()  # every command's module imported
positions: list[int] = []


LOCKS = Path(os.environ.get("WINSIM_LOCKS", "/tmp/winsim-locks"))  # which byte of which file each process locked


def registry(fd: int) -> Path:
    name = hashlib.sha1(os.readlink(f"/proc/self/fd/{fd}").encode()).hexdigest()
    return LOCKS / f"{name}.{os.getpid()}"


held: dict[int, tuple[int, int]] = {}  # fd -> (position, bytes) it locked


def locking(fd: int, mode: int, n: int) -> None:
    at = os.lseek(fd, 0, os.SEEK_CUR)
    positions.append(at)
    LOCKS.mkdir(parents=True, exist_ok=True)
    if mode == msvcrt.LK_NBLCK:
        posix.flock(fd, posix.LOCK_EX | posix.LOCK_NB)  # BlockingIOError, an OSError, when another holds it
        held[fd] = (at, n)
        registry(fd).write_text(str(at))
    else:
        if held.get(fd) != (at, n):  # Windows unlocks only a region locked as such, else EACCES
            raise PermissionError(13, "Permission denied")
        del held[fd]
        posix.flock(fd, posix.LOCK_UN)
        real_unlink(registry(fd))


class Guarded:
    """A file whose reads fail over a byte another process has locked, as Windows's do."""

    def __init__(self, f: Any) -> None:
        self._f = f

    def __getattr__(self, name: str) -> Any:
        return getattr(self._f, name)

    def read(self, n: int = -1) -> Any:
        at = self._f.tell()
        stem = registry(self._f.fileno()).name.rsplit(".", 1)[0]
        for other in LOCKS.glob(f"{stem}.*"):
            off = int(other.read_text() or -1)
            if other.suffix != f".{os.getpid()}" and at <= off and (n < 0 or off < at + n):
                raise PermissionError(13, "The process cannot access the file because another process has locked "
                                      "a portion of the file")
        return self._f.read(n)


busy = [int(os.environ.get("WINSIM_BUSY", "0"))]  # opens of a .lock refused first, as while it is being removed


def guarded_open(file: Any, *args: Any, **kwargs: Any) -> Any:
    if busy[0] > 0 and os.fspath(file).endswith(".lock"):
        busy[0] -= 1
        raise PermissionError(13, "Permission denied", os.fspath(file))
    return Guarded(open(file, *args, **kwargs))


def is_open(path: object) -> bool:
    """Whether any process has the file open."""
    target = os.path.realpath(os.fspath(path))  # type: ignore[arg-type]
    for fds in glob.glob("/proc/[0-9]*/fd"):
        try:
            names = os.listdir(fds)
        except OSError:
            continue
        for fd in names:
            try:
                if os.readlink(f"{fds}/{fd}") == target:
                    return True
            except OSError:
                pass
    return False


def refusing(remove):  # type: ignore[no-untyped-def]
    def unlink(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if kwargs.get("dir_fd") is None and is_open(path):
            raise PermissionError(13, "The process cannot access the file because it is being used by another "
                                  "process", os.fspath(path))
        return remove(path, *args, **kwargs)
    return unlink


def cdll(name, *args, **kwargs):  # type: ignore[no-untyped-def]
    if name is None:
        raise TypeError("argument of type 'NoneType' is not iterable")
    return real_cdll(name, *args, **kwargs)


msvcrt = types.ModuleType("msvcrt")
msvcrt.LK_NBLCK, msvcrt.LK_UNLCK = 2, 0  # type: ignore[attr-defined]
msvcrt.locking = locking  # type: ignore[attr-defined]
windows = types.SimpleNamespace(platform="win32")
files.sys, files.msvcrt, files.open = windows, msvcrt, guarded_open  # type: ignore[attr-defined]
del files.fcntl  # type: ignore[attr-defined]
workers.sys = memory.sys = windows  # type: ignore[attr-defined]
del os.fchmod, os.O_NONBLOCK
real_unlink = os.unlink
os.unlink = os.remove = refusing(os.unlink)
real_cdll, ctypes.CDLL = ctypes.CDLL, cdll  # type: ignore[misc]
atexit.register(lambda: print(f"locking at {sorted(set(positions))}", file=sys.stderr))

if __name__ == "__main__":
    if sys.argv[1] == "-c":
        exec(sys.argv[2])
    else:
        from core.cli import main

        sys.exit(main(sys.argv[1:]))
