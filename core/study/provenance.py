"""Which code made a result: a digest of the ``core`` package's sources, and the git commit when there is one.

A study's cells record the digest of the code that ran them; resuming a study with other code refuses the cells
run before (or reruns them on request), so one median never pools two versions of an algorithm (rehearsal 6: a
resumed study reused four seeds of the old NSGA-II and ran the fifth with a changed one, without a word).
"""

from __future__ import annotations

import hashlib
import subprocess
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the core package


@cache
def code_digest() -> str:
    """12 hex digits of SHA-256 over every ``core/**/*.py`` file's path and bytes: equal iff the library's code
    is (docs, tests, the studio and data files are not in it)."""
    h = hashlib.sha256()
    for path in sorted(ROOT.rglob("*.py")):
        h.update(str(path.relative_to(ROOT)).encode("utf-8") + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:12]


@cache
def git_commit() -> str | None:
    """The checkout's commit (12 hex digits, ``+dirty`` when ``core`` differs from it), or None outside a git
    checkout or without git."""
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        tracked = subprocess.run(["git", "-C", str(ROOT), "ls-files", "--", "__init__.py"], capture_output=True,
                                 text=True, timeout=10)
        if head.returncode != 0 or not tracked.stdout.strip():  # not ours: core installed inside another repository
            return None
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "."], capture_output=True,
                               text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip()[:12] + ("+dirty" if dirty.stdout.strip() else "")


def code_version() -> dict[str, str | None]:
    """``{"digest": ..., "commit": ...}``: what a result records of the code that made it."""
    return {"digest": code_digest(), "commit": git_commit()}
