"""One numba cache directory per version of the compiled sources.

numba reuses a cached kernel while the file that defines it is unchanged, but it does not look at the kernels it
calls from other modules: after an edit of ``evolve/ahead.py`` alone, CMOEMT's and MOEA/D-CMT's compiled loops
kept the old ``ahead.stale`` inlined (a mutation audit ran against stale machine code). So the cache lives in a
subdirectory named by a hash of every ``core`` module that mentions numba: any change to one of them starts a
fresh cache (the next runs compile again, about a minute on 2 cores for the studio's warm-up).

The base is ``NUMBA_CACHE_DIR`` (the scripts set ``.venv/numba-cache``), else ``numba-cache`` in a writable
virtual environment; with neither, numba's default (``__pycache__``) is left alone. Each start marks its own
directory as used and removes the other versions' directories beyond the ``KEEP`` most recently used, once they
have been idle for ``IDLE_S``. A process of an older version still running when its directory goes only compiles
again: numba loads nothing from a missing directory and makes it anew when it saves a kernel.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.util
import os
import re
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]  # core
KEEP, IDLE_S = 3, 3600.0
_FINGERPRINT = re.compile(r"[0-9a-f]{16}")


def kernel_fingerprint(root: Path = ROOT) -> str:
    """16 hex digits of sha256 over the path and bytes of every ``.py`` file under ``root`` that mentions numba."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        data = p.read_bytes()
        if b"numba" in data:
            h.update(p.relative_to(root).as_posix().encode() + b"\0" + data + b"\0")
    return h.hexdigest()[:16]


def cache_dir(fingerprint: str) -> str | None:
    """The numba cache directory for these sources, or None to leave numba's default."""
    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base:
        venv = sys.prefix != sys.base_prefix and os.access(sys.prefix, os.W_OK)
        if not venv:
            return None
        base = os.path.join(sys.prefix, "numba-cache")
    if os.path.basename(os.path.normpath(base)) == fingerprint:  # a child process: set by its parent already
        return base
    return os.path.join(base, fingerprint)


WARM_MARK = "warmed"  # left in a version's directory by the studio's warm-up once it has compiled everything


def warm_mark(fingerprint: str | None = None) -> Path | None:
    """The file ``clm-studio --warm-up`` leaves in these sources' cache directory when it is done (it holds numba's
    version: another numba compiles again); None without a cache directory of our own (numba's default)."""
    where = cache_dir(kernel_fingerprint() if fingerprint is None else fingerprint)
    return None if where is None else Path(where) / WARM_MARK


def _numba_version() -> str:
    from importlib.metadata import version

    return version("numba")


def mark_warm() -> None:
    """Leave the warm-up's mark; a cache directory that cannot be written is left alone (numba compiles elsewhere
    then, and the warm-up still did its work)."""
    mark = warm_mark()
    if mark is None:
        return
    try:
        mark.parent.mkdir(parents=True, exist_ok=True)
        mark.write_text(_numba_version())
    except OSError:
        pass


def is_warm() -> bool | None:
    """Whether the warm-up has compiled these sources' kernels with this numba; None without a cache of our own."""
    mark = warm_mark()
    if mark is None:
        return None
    try:
        return mark.read_text() == _numba_version()
    except OSError:
        return False


def prune(where: str, keep: int = KEEP, idle_s: float = IDLE_S) -> list[str]:
    """Mark ``where`` as used now and remove its sibling version directories beyond the ``keep`` most recently
    used that have been idle ``idle_s`` seconds; returns the removed paths. Errors are ignored: a cache that
    cannot be tidied still works."""
    here = Path(where)
    try:
        here.mkdir(parents=True, exist_ok=True)
        os.utime(here)
        others = [p for p in here.parent.iterdir()
                  if p != here and p.is_dir() and _FINGERPRINT.fullmatch(p.name)]
        others.sort(key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:
        return []
    removed, now = [], time.time()
    for p in others[keep:]:
        try:
            if now - p.stat().st_mtime < idle_s:
                continue
        except OSError:
            continue
        shutil.rmtree(p, ignore_errors=True)
        removed.append(str(p))
    return removed


def configure() -> None:
    """Point numba's cache for ``core``'s own kernels at this version's directory (before any is compiled).

    Only functions defined under ``core`` are affected: a locator for them goes first in numba's list, so a process
    that imports ``core`` keeps its own ``NUMBA_CACHE_DIR`` and numba configuration for its kernels (rehearsal 8: an
    integrator's kernels moved into CLM's version directory, which the next CLM version prunes). numba is not
    imported for it: the locator is installed when ``numba.core.caching`` is (at once if it already is)."""
    where = cache_dir(kernel_fingerprint())
    if where is None:
        return
    prune(where)
    caching = sys.modules.get("numba.core.caching")
    if caching is not None:
        _install(caching, where)
    else:
        sys.meta_path.insert(0, _AfterImport("numba.core.caching", lambda module: _install(module, where)))


def _install(caching: Any, where: str) -> None:
    """Put a locator for the functions under ``core`` first in numba's list (once). Where that cannot be done (a
    numba without these internals, or ``NUMBA_CACHE_LOCATOR_CLASSES`` set, which replaces the list), numba's
    ``CACHE_DIR`` is pointed at this version's directory for the whole process, as before session 31: a stale
    kernel is worse than a host's kernels cached beside ours. Never raises: it runs inside ``import numba``."""
    try:
        from numba.core import config

        if getattr(config, "CACHE_LOCATOR_CLASSES", None):
            config.CACHE_DIR = where
            return
        _add_locator(caching, where)
    except Exception:  # noqa: BLE001 - an import of numba must not fail for our cache
        try:
            from numba.core import config

            config.CACHE_DIR = where
        except Exception:  # noqa: BLE001
            pass


def _add_locator(caching: Any, where: str) -> None:
    classes = caching.CacheImpl._locator_classes
    if any(getattr(c, "_clm_root", None) == str(ROOT) for c in classes):
        return

    class CoreLocator(caching.UserProvidedCacheLocator):
        _clm_root = str(ROOT)

        def __init__(self, py_func: Any, py_file: str) -> None:
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = os.path.join(where, self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            try:
                inside = Path(py_file).resolve().is_relative_to(ROOT)
            except (OSError, ValueError):
                return None
            if not inside or not os.path.exists(py_file):
                return None
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()
            except OSError:
                return None
            return self

    classes.insert(0, CoreLocator)


class _AfterImport(importlib.abc.MetaPathFinder):
    """Runs ``then(module)`` right after the module ``name`` is first imported (once; it stays in ``sys.meta_path``
    and answers nothing after)."""

    def __init__(self, name: str, then: Any) -> None:
        self.name, self.then, self.done = name, then, False

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> Any:
        # Stays in sys.meta_path (removing itself while another thread walks the list could skip a finder there);
        # answers once, and not to its own find_spec below.
        if fullname != self.name or self.done:
            return None
        self.done = True
        spec = importlib.util.find_spec(fullname)
        loader = getattr(spec, "loader", None)
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        run, then = loader.exec_module, self.then

        def exec_module(module: Any) -> None:
            run(module)
            then(module)

        loader.exec_module = exec_module
        return spec


class CompileTimer:
    """Seconds numba spends compiling kernels while installed (``with CompileTimer() as t: ...; t.seconds``), read
    at any time: a fresh install's first run of a stage compiles for ~30 s, which a run's time should name apart
    from its compute. Every thread's compiles count (numba's listeners are global), each thread's outermost compile
    once; a compile already under way in another thread when the timer starts counts from then to its end (numba
    compiles one kernel at a time, so the run waits for it). numba's own TimingListener kept one depth for all
    threads, went to -1 on such a compile's end and counted nothing after it."""

    def __init__(self) -> None:
        from numba.core.event import Listener

        timer = self

        class _Outermost(Listener):
            def on_start(self, event: Any) -> None:
                timer._start()

            def on_end(self, event: Any) -> None:
                timer._end()

        self._listener = _Outermost()
        self._installed: Any = None
        self._lock = threading.Lock()
        self._depth: dict[int, int] = {}
        self._began: dict[int, float] = {}
        self._total = 0.0
        self._entered = 0.0
        self._late: dict[int, float] = {}  # per thread compiling before the timer: when its last compile ended
        self._added: dict[int, float] = {}  # per thread, the windows counted into _total

    def _start(self) -> None:
        me = threading.get_ident()
        with self._lock:
            depth = self._depth.get(me, 0)
            if depth == 0:
                self._began[me] = time.perf_counter()
            self._depth[me] = depth + 1

    def _end(self) -> None:
        me = threading.get_ident()
        with self._lock:
            depth = self._depth.get(me, 0)
            if depth == 0:  # it started before the timer did: its last such end is its outermost compile's
                self._late[me] = time.perf_counter()
                # [entered, now] covers what this thread compiled since (a callee the outer compile typed counted
                # as its own window, and twice: the review of session 29 read 0.54 s for 0.30).
                self._total -= self._added.pop(me, 0.0)
                return
            self._depth[me] = depth - 1
            if depth == 1:
                window = time.perf_counter() - self._began.pop(me)
                self._total += window
                self._added[me] = self._added.get(me, 0.0) + window

    @property
    def seconds(self) -> float:
        """Compile time so far, a compile under way counted up to now (the studio says it every half second while
        a first run compiles: counted only at its end, a 24 s kernel read 0 s for 24 s; review of session 30)."""
        with self._lock:
            now = time.perf_counter()
            return (self._total + sum(t - self._entered for t in self._late.values())
                    + sum(now - began for began in self._began.values()))

    def __enter__(self) -> CompileTimer:
        from numba.core.event import install_listener

        self._entered = time.perf_counter()
        self._installed = install_listener("numba:compile", self._listener)
        self._installed.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._installed.__exit__(*exc)
