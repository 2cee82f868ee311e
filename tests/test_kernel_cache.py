"""numba's cache is kept per version of the compiled sources: numba itself does not notice an edit of a kernel that
another module's kernel calls (a mutation audit ran CMOEMT's loop with an edited ``ahead.stale`` still inlined)."""

from __future__ import annotations

from pathlib import Path

import pytest

from core.kinematics.kernel_cache import cache_dir, kernel_fingerprint


def test_the_fingerprint_follows_the_modules_that_mention_numba_only(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    kernel, plain = tmp_path / "sub" / "kernel.py", tmp_path / "plain.py"
    kernel.write_text("import numba\n\n@numba.njit(cache=True)\ndef f(x):\n    return x + 1\n")
    plain.write_text("def g():\n    return 1\n")
    before = kernel_fingerprint(tmp_path)
    plain.write_text("def g():\n    return 2\n")
    assert kernel_fingerprint(tmp_path) == before
    kernel.write_text(kernel.read_text().replace("x + 1", "x + 2"))
    assert kernel_fingerprint(tmp_path) != before and len(before) == 16


def test_the_cache_is_a_subdirectory_per_fingerprint_and_child_processes_keep_theirs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert cache_dir("abc") == str(tmp_path / "abc")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "abc"))  # a worker started by a process that set it
    assert cache_dir("abc") == str(tmp_path / "abc")


def test_this_process_compiles_into_this_versions_cache() -> None:
    from core.analysis import fourier

    where = cache_dir(kernel_fingerprint())
    if where is None:
        pytest.skip("neither NUMBA_CACHE_DIR nor a writable virtual environment: numba's default cache")
    fourier._peak.enable_caching()  # what cache=True did: its locator says where the kernel goes
    path = fourier._peak._cache._cache_path
    assert Path(path).parent == Path(where) and Path(where).name == kernel_fingerprint()


@pytest.mark.parametrize("first", ["numba", "core"])
def test_importing_core_leaves_a_host_processs_own_kernels_and_settings_alone(tmp_path: Path, first: str) -> None:
    # Rehearsal 8: import core rewrote NUMBA_CACHE_DIR and numba's CACHE_DIR for the whole process, so an integrator's
    # kernels went into CLM's version directory (which the next CLM version prunes) and so did their children's.
    import os
    import subprocess
    import sys
    import textwrap

    (tmp_path / "hostmod.py").write_text("import numba\n\n\n@numba.njit(cache=True)\ndef hf(x):\n    return x + 1\n")
    base = tmp_path / "cache"
    second = "core" if first == "numba" else "numba"
    code = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(tmp_path)!r})
        import {first}
        import {second}
        from numba.core import config
        assert os.environ["NUMBA_CACHE_DIR"] == config.CACHE_DIR == {str(base)!r}, (os.environ["NUMBA_CACHE_DIR"],
                                                                                   config.CACHE_DIR)
        import numpy as np
        import hostmod
        from core.analysis import fourier
        assert hostmod.hf(1) == 2
        fourier.descriptors(np.random.default_rng(0).random((2, 40, 2)))
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(base), PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    index = [p.relative_to(base) for p in base.rglob("*.nbi")]
    host = [p for p in index if p.name.startswith("hostmod.")]
    ours = [p for p in index if p.name.startswith("fourier.")]
    assert host and all(p.parts[0] != kernel_fingerprint() for p in host)  # numba's own layout under the base
    assert ours and all(p.parts[0] == kernel_fingerprint() for p in ours)


def test_a_start_keeps_its_own_and_the_most_recent_versions_and_removes_idle_old_ones(tmp_path: Path) -> None:
    import os
    import time

    from core.kinematics.kernel_cache import prune

    now = time.time()
    ages_h = {"0000000000000001": 1000.0, "0000000000000002": 50.0, "0000000000000003": 3.0,
              "0000000000000004": 2.0, "0000000000000005": 0.1, "00000000000000ff": 2000.0}
    for name, age in ages_h.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "kernel.nbi").write_bytes(b"x")
        os.utime(tmp_path / name, (now - age * 3600, now - age * 3600))
    (tmp_path / "analysis_05f3a0").mkdir()  # numba's own layout and other files are not ours to remove
    os.utime(tmp_path / "analysis_05f3a0", (now - 9e6, now - 9e6))
    here = tmp_path / "00000000000000ff"  # this start's version: old, but used now
    removed = prune(str(here), keep=2, idle_s=3600.0)
    left = sorted(p.name for p in tmp_path.iterdir())
    # the two most recent others (0.1 h, 2 h) stay; beyond them, 3 h and older go unless used within the hour
    assert sorted(Path(p).name for p in removed) == ["0000000000000001", "0000000000000002", "0000000000000003"]
    assert left == ["0000000000000004", "0000000000000005", "00000000000000ff", "analysis_05f3a0"]
    assert time.time() - here.stat().st_mtime < 60
    os.utime(tmp_path / "0000000000000004", (now - 600, now - 600))  # beyond keep, but used 10 min ago
    (tmp_path / "0000000000000006").mkdir()
    assert prune(str(here), keep=1, idle_s=3600.0) == []  # 6 is the newest other; 4 and 5 used within the hour
    assert prune(str(here), keep=0, idle_s=0.0) != [] and sorted(p.name for p in tmp_path.iterdir()) == [
        "00000000000000ff", "analysis_05f3a0"]


def test_a_cache_that_cannot_be_tidied_still_works(tmp_path: Path) -> None:
    from core.kinematics.kernel_cache import prune

    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert prune(str(blocker / "0000000000000001")) == []


def test_a_process_whose_cache_directory_was_pruned_compiles_and_saves_again(tmp_path: Path) -> None:
    # What prune relies on: numba loads nothing from a missing directory and makes it anew when it saves.
    import os
    import subprocess
    import sys
    import textwrap

    (tmp_path / "kern.py").write_text("import numba\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    script = textwrap.dedent("""
        import shutil, sys
        sys.path.insert(0, sys.argv[1])
        import kern
        assert kern.twice(2) == 4
        shutil.rmtree(sys.argv[2])          # pruned by a newer version's start
        assert kern.twice(2.5) == 5.0       # a new signature: compiled, and saved into a new directory
        print("ok")
    """)
    cache = tmp_path / "cache" / "0000000000000001"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-c", script, str(tmp_path), str(cache)], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
    assert any(p.suffix == ".nbi" for p in cache.rglob("*"))


def test_the_compile_timer_counts_a_compile_another_thread_began_before_it_and_every_one_after() -> None:
    """Review of session 28: numba's TimingListener keeps one depth for every thread; a compile under way in another
    thread when the timer started ended at depth -1, and nothing was counted after it (8.5 s read 0.00 s)."""
    import threading
    import time

    import numba
    import numpy as np
    from numba.core import event

    from core.kinematics.kernel_cache import CompileTimer

    def make(k: int):
        src = "def f(x):\n    s = 0.0\n" + "".join(f"    s += np.sin(x * {i}) * np.cos(x + {i})\n" for i in range(k))
        ns = {"np": np}
        exec(src + "    return s\n", ns)
        return numba.njit(cache=False)(ns["f"])

    started = threading.Event()

    class Flag(event.Listener):
        def on_start(self, e):
            started.set()

        def on_end(self, e):
            pass

    slow, fast, later = make(120), make(10), make(10)
    other = threading.Thread(target=lambda: slow(1.0))
    with event.install_listener("numba:compile", Flag()):
        other.start()
        assert started.wait(30)
    with CompileTimer() as t:
        t0 = time.perf_counter()
        fast(1.0)  # waits for the other thread's compile (numba compiles one at a time), then compiles
        other.join()
        waited = time.perf_counter() - t0
        first = t.seconds
        assert 0.5 * waited <= first <= waited + 0.05
        later(1.0)
        assert t.seconds > first


def test_a_compile_under_way_when_the_timer_starts_counts_its_callees_once() -> None:
    # Review of session 29: a callee the outer compile typed (a nested start and end in its thread) was counted as a
    # window of its own and again inside the outer compile's [enter, end]: 0.54 s for 0.30 s of compiling.
    import threading
    import time

    from core.kinematics.kernel_cache import CompileTimer

    with CompileTimer() as t:
        def outer_under_way() -> None:
            t._listener.on_start(None)
            time.sleep(0.2)
            t._listener.on_end(None)  # the callee
            time.sleep(0.1)
            t._listener.on_end(None)  # the outer compile, begun before the timer

        th = threading.Thread(target=outer_under_way)
        th.start()
        th.join()
        assert 0.28 <= t.seconds <= 0.45
        t._listener.on_start(None)  # this thread's own compile afterwards: its own window, added
        time.sleep(0.05)
        t._listener.on_end(None)
        assert 0.33 <= t.seconds <= 0.5


def test_a_compile_under_way_is_counted_while_it_runs_not_only_at_its_end() -> None:
    # Review of session 30: seconds grew only when a compile ended, so the studio's "compiling the numeric kernels,
    # N s so far" could not appear during the one long compile a first run waits for.
    import threading
    import time

    import numba
    import numpy as np

    from core.kinematics.kernel_cache import CompileTimer

    src = "def g(x):\n    s = 0.0\n" + "".join(f"    s += np.sin(x * {i}) * np.cos(x - {i})\n" for i in range(90))
    ns = {"np": np}
    exec(src + "    return s\n", ns)
    slow = numba.njit(cache=False)(ns["g"])
    with CompileTimer() as t:
        th = threading.Thread(target=lambda: slow(0.5))
        th.start()
        polls = []
        while th.is_alive():
            polls.append(t.seconds)
            time.sleep(0.02)
        th.join()
        final = t.seconds
    during = [p for p in polls[:-1] if p > 0.0]
    assert len(polls) > 5 and during, polls  # counted before the compile ended
    assert all(b >= a for a, b in zip(polls, polls[1:], strict=False)) and final >= max(polls)


def test_a_locator_that_cannot_be_installed_falls_back_to_the_version_directory_without_breaking_numba(
        tmp_path: Path) -> None:
    # Review of session 31: _install runs inside `import numba`; if numba's internals moved (or
    # NUMBA_CACHE_LOCATOR_CLASSES replaces the locator list) it must neither fail the import nor leave core's kernels
    # in the unversioned cache.
    import os
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent("""
        import core.kinematics.kernel_cache as kc
        kc._add_locator = lambda caching, where: (_ for _ in ()).throw(AttributeError("moved"))
        import numba
        from numba.core import config
        from core.kinematics.kernel_cache import cache_dir, kernel_fingerprint
        assert config.CACHE_DIR == cache_dir(kernel_fingerprint()), config.CACHE_DIR
        print("ok")
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
    code2 = "import core, numba\nfrom numba.core import config\nprint(config.CACHE_DIR)\n"
    env2 = dict(env, NUMBA_CACHE_LOCATOR_CLASSES="UserProvidedCacheLocator")
    out = subprocess.run([sys.executable, "-c", code2], env=env2, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert Path(out.stdout.strip()).parent == tmp_path and Path(out.stdout.strip()).name == kernel_fingerprint()
