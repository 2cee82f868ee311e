"""Which code made a result: a digest of the ``core`` package's sources, and the git commit when there is one.

A study's cells record the digest of the code that ran them; resuming a study with other code refuses the cells
run before (or reruns them on request), so one median never pools two versions of an algorithm (rehearsal 6: a
resumed study reused four seeds of the old NSGA-II and ran the fifth with a changed one, without a word).
"""

from __future__ import annotations

import subprocess
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the core package


def code_digest() -> str:
    """12 hex digits of SHA-256 over every ``core/**/*.py`` file's path and bytes, taken when ``core`` was imported:
    equal iff the library's code is (docs, tests, the studio and data files are not in it), and the code this process
    runs even after the files are edited (review of session 30: read at the first call, a long-lived worker named the
    edited files while the old modules ran)."""
    import core

    return core.CODE_DIGEST


def libraries() -> dict[str, str]:
    """The versions of the libraries whose code the results depend on."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in ("numpy", "scipy", "numba", "pymoo", "moocore"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            pass
    return out


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


def code_version() -> dict[str, object]:
    """``{"digest": ..., "commit": ..., "libraries": {...}}``: what a study records of the code that made it."""
    return {"digest": code_digest(), "commit": git_commit(), "libraries": libraries()}
