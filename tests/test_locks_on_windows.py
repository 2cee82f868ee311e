"""The folder and session locks on a system without fcntl (Windows): importing fcntl at the top of core.formats.files
stopped every clm command and the studio there (review of session 34). Windows is simulated in a child process: no
fcntl, sys.platform "win32", and an msvcrt whose byte locks are flocks, so two opens of one file conflict."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import fcntl as posix, sys, types
calls = []
msvcrt = types.ModuleType("msvcrt")
msvcrt.LK_NBLCK, msvcrt.LK_UNLCK = 2, 0
def locking(fd, mode, n):
    calls.append((mode, n))
    posix.flock(fd, posix.LOCK_EX | posix.LOCK_NB if mode == msvcrt.LK_NBLCK else posix.LOCK_UN)
msvcrt.locking = locking
sys.modules["msvcrt"], sys.modules["fcntl"] = msvcrt, None  # import fcntl now raises ImportError
sys.platform = "win32"
from core.formats.files import dir_lock
folder = sys.argv[1]
with dir_lock(folder, "clm design"):
    try:
        with dir_lock(folder, "clm study"):
            print("second lock taken")
    except ValueError as e:
        print(e)
with dir_lock(folder, "clm study"):  # given up when the first ended
    print("taken again")
print(calls)
"""


def test_a_folder_lock_works_without_fcntl(tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "run")], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    # Windows refuses to read a locked byte; here the holder's note is readable, as it is on POSIX
    assert lines[0].startswith(f"{tmp_path / 'run'}: another clm design is writing into it (process ")
    assert lines[1] == "taken again"
    assert lines[2] == "[(2, 1), (2, 1), (0, 1), (2, 1), (0, 1)]"  # lock, refused lock, unlock, lock, unlock


def test_only_the_lock_helpers_import_fcntl() -> None:
    found = []
    for path in sorted([*(ROOT / "core").rglob("*.py"), *(ROOT / "studio").rglob("*.py")]):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) else []
            if "fcntl" in names or "msvcrt" in names:
                found.append(str(path.relative_to(ROOT)))
    assert found == ["core/formats/files.py", "core/formats/files.py"]
