"""Nothing half-written, nothing orphaned, nothing run for an output folder that cannot take the result."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core.cli import main
from core.formats.files import atomic_write

ROOT = Path(__file__).resolve().parents[1]
CONFIG = """
name = "orphans"
mechanism = "stephenson1"
seed = 1
n_samples = 72
workers = 2
[algorithm]
name = "nsga2"
pop_size = 12
[[stages]]
name = "predesign"
box = "global"
n_gen = 100000
pick = "best:f1"
starts = {n = 2, select = "best:f1"}
"""
SMALL = """
name = "small"
mechanism = "stephenson1"
seed = 1
n_samples = 72
[algorithm]
name = "nsga2"
pop_size = 8
[[stages]]
name = "subtask1"
box = "global"
n_gen = 2
"""


def test_a_failed_write_keeps_the_previous_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "result.json"
    atomic_write(target, '{"good": 1}')

    def broken(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", broken)
    with pytest.raises(OSError):
        atomic_write(target, '{"good": 2, "padding": "' + "x" * 100_000 + '"}')
    assert json.loads(target.read_text()) == {"good": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


WRITER = """
import sys
from pathlib import Path
from core.formats.files import atomic_write
path = Path(sys.argv[1])
i = 0
while True:
    i += 1
    atomic_write(path, '{"version": %d, "blob": "%s"}' % (i, "y" * 4_000_000))
"""


def test_kill_9_during_writes_never_leaves_an_unreadable_file(tmp_path):
    target = tmp_path / "result.json"
    atomic_write(target, '{"version": 0, "blob": ""}')
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for delay in (0.05, 0.13, 0.21, 0.37):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target)], env=env)
        time.sleep(delay)
        proc.kill()
        proc.wait()
        assert json.loads(target.read_text())["version"] >= 0  # always one whole version


@pytest.mark.parametrize("case", ["empty", "under a file", "proc", "result.json is a folder", "csv is a folder"])
def test_a_bad_out_folder_is_refused_before_any_work(tmp_path, capsys, case):
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL)
    (tmp_path / "file").write_text("x")
    out = {"empty": "", "under a file": str(tmp_path / "file" / "out"), "proc": "/proc/nope/out"}.get(case)
    if out is None:
        out = str(tmp_path / "out")
        name = "result.json" if case == "result.json is a folder" else "0_subtask1.csv"
        (tmp_path / "out" / name).mkdir(parents=True)
    t = time.perf_counter()
    assert main(["design", str(cfg), "--out", out, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("clm: error: --out") and err.count("\n") == 1, err
    assert time.perf_counter() - t < 5  # refused before the run, not after it
    assert not (tmp_path / "out" / "0_subtask1.csv").is_file()


def test_a_refused_out_folder_leaves_no_folder_it_made_behind(tmp_path, capsys):
    # 'new/a/<a name too long>' was refused after new/a had been made, and new/a stayed.
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL)
    assert main(["design", str(cfg), "--out", str(tmp_path / "new" / "a" / ("x" * 300)), "--quiet"]) == 2
    assert "cannot write there (File name too long)" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def children(pid: int) -> set[int]:
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.add(int(d.name))
    return out


def kill_and_check_no_orphans(proc: subprocess.Popen, missing: str, settle: float) -> None:
    """Wait for two child workers, let them work ``settle`` s, SIGKILL the parent: no child may outlive it 5 s."""
    try:
        deadline = time.monotonic() + 120
        workers: set[int] = set()
        while time.monotonic() < deadline and len(workers) < 2:
            workers = {c for c in children(proc.pid) if alive(c)}
            time.sleep(0.2)
        assert len(workers) >= 2, missing
        time.sleep(settle)
        workers |= {c for c in children(proc.pid) if alive(c)}
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(alive(w) for w in workers):
            time.sleep(0.1)
        assert not any(alive(w) for w in workers), "workers outlived their killed parent"
    finally:
        if proc.poll() is None:
            proc.kill()
        for w in children(proc.pid):
            os.kill(w, signal.SIGKILL)


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc (Linux)")
def test_workers_exit_when_clm_design_is_killed(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text(CONFIG)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "core.cli", "design", str(cfg), "--out", str(tmp_path / "o"),
                             "--quiet"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kill_and_check_no_orphans(proc, "the multi-start block did not start its workers", settle=1.0)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc (Linux)")
def test_study_workers_exit_when_clm_study_is_killed(tmp_path):
    study = tmp_path / "s.toml"
    study.write_text(f"""
name = "orphans"
seeds = "1..4"
[[algorithms]]
name = "nsga2"
[[cases]]
name = "subtask2"
config = "{ROOT / 'assets' / 'configs' / 'stephenson1_cycloid.toml'}"
stages = ["subtask2"]
start = "stephenson1/X1"
budget = 1000000
""")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "core.cli", "study", str(study), "--out", str(tmp_path / "o"),
                             "--workers", "2", "--quiet"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    kill_and_check_no_orphans(proc, "the study did not start its Dask workers", settle=3.0)
