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
    from numba.core import config

    where = cache_dir(kernel_fingerprint())
    if where is None:
        pytest.skip("neither NUMBA_CACHE_DIR nor a writable virtual environment: numba's default cache")
    assert config.CACHE_DIR == where and Path(where).name == kernel_fingerprint()
