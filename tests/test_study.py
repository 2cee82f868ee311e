"""Studies on Dask: a tiny grid runs, resumes after a killed client, records failures, and is the same for any
number of workers or a real scheduler; malformed study files are refused with one line."""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core.cli import main
from core.formats.study import load_study, parse_seeds
from core.study.report import write_report
from core.study.runner import run_study
from core.study.store import Store

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "assets" / "configs" / "stephenson1_cycloid.toml"

TINY = f"""
name = "tiny"
seeds = "1..3"
[[algorithms]]
name = "nsga2"
pop_size = 20
[[algorithms]]
name = "spea2"
pop_size = 20
[[cases]]
name = "subtask2"
config = "{CONFIG}"
stages = ["subtask2"]
start = "stephenson1/X1"
budget = 100
"""


def write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def comparable(rows: list[dict]) -> dict[str, dict]:
    """Each row's metrics without what depends on the machine's speed."""
    out = {}
    for r in rows:
        m = dict(r["metrics"] or {})
        m.pop("wall_time", None)
        m.pop("compile_time", None)
        out[r["key"]] = {"status": r["status"], **m}
    return out


def report_without_times(directory: Path) -> list[str]:
    """The report but its time row and the study file's path (two runs of one study from two copies of its file)."""
    return [ln for ln in (directory / "report.md").read_text().splitlines()
            if not ln.startswith(("| time", "Study file `"))]


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny study, uninterrupted, on a LocalCluster with two workers."""
    d = tmp_path_factory.mktemp("study")
    study = load_study(write(d, TINY))
    summary = run_study(study, str(d / "out"), workers=2, stream=None)
    assert (summary.total, summary.ran, summary.failed) == (6, 6, 0)
    write_report(d / "out")
    return d / "out"


def test_a_tiny_study_keeps_one_row_and_one_result_file_per_cell(reference_run: Path):
    rows = Store(reference_run).rows()
    assert sorted(r["key"] for r in rows) == sorted(f"subtask2/{a}/{s}" for a in ("nsga2", "spea2") for s in (1, 2, 3))
    for r in rows:
        assert r["status"] == "done"
        result = json.loads((reference_run / r["result_path"]).read_text())
        assert result["format"] == "clm-design"
        assert result["config"]["seed"] == r["seed"]
        m = r["metrics"]
        assert m["objectives"] == ["h_s", "I"] and 0.0 <= m["feasible_ratio"] <= 1.0
        assert m["n_eval"] >= 100  # the budget is spent, by whole generations
        # The time row leaves out what the cell spent compiling kernels (recorded apart).
        assert m["compile_time"] >= 0.0 and m["wall_time"] >= 0.0
        assert m["wall_time"] + m["compile_time"] <= r["task_time"] + 1e-6
    text = (reference_run / "report.md").read_text()
    assert "## subtask2" in text and "| HV |" in text and "Best picked design" in text
    assert "Plotly.newPlot" in (reference_run / "report.html").read_text()
    assert not (reference_run / ".lock").exists()  # held while it ran, gone with it (QA, session 37)


def test_results_do_not_depend_on_the_number_of_workers(reference_run: Path, tmp_path: Path):
    study = load_study(write(tmp_path, TINY))
    run_study(study, str(tmp_path / "one"), workers=1, stream=None)
    assert comparable(Store(tmp_path / "one").rows()) == comparable(Store(reference_run).rows())


def test_a_rerun_skips_finished_cells(reference_run: Path, tmp_path: Path):
    study = load_study(write(tmp_path, TINY))
    summary = run_study(study, str(reference_run), workers=1, stream=None)
    assert (summary.skipped, summary.ran) == (6, 0)
    assert len(Store(reference_run).rows()) == 6


def spea2_fails(cell: dict) -> dict:  # type: ignore[type-arg]
    """run_cell, with an option spea2 refuses slipped into its cells past the study's checks."""
    from core.study.cell import run_cell

    if cell["algorithm"]["name"] == "spea2":
        cell = dict(cell, algorithm=dict(cell["algorithm"], options={"no_such_option": 1}))
    return run_cell(cell)


def test_a_failing_task_is_recorded_and_the_study_goes_on(tmp_path: Path):
    study = load_study(write(tmp_path, TINY))
    summary = run_study(study, str(tmp_path / "out"), workers=2, stream=None, task=spea2_fails)
    assert (summary.ran, summary.failed) == (6, 3)
    rows = Store(tmp_path / "out").rows()
    failed = [r for r in rows if r["status"] == "failed"]
    assert {r["algorithm"] for r in failed} == {"spea2"}
    assert all("no_such_option" in r["error"] for r in failed)
    assert sum(r["status"] == "done" for r in rows) == 3
    # A rerun tries the failed cells again and counts the attempt.
    summary = run_study(study, str(tmp_path / "out"), workers=1, stream=None, task=spea2_fails)
    assert (summary.skipped, summary.ran, summary.failed) == (3, 3, 3)
    assert {r["attempts"] for r in Store(tmp_path / "out").rows() if r["status"] == "failed"} == {2}


def test_cells_that_could_only_fail_are_refused_before_any_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    # An option the algorithm refuses, a start preset of another mechanism, an odd population for IMTCMO: every
    # cell of the pair failed at run time, after the study had started (clm design refuses them at load).
    bad = {
        "options = {no_such_option = 1}": "cases[0] ('subtask2') with algorithm 'spea2': "
                                          "algorithm.options.no_such_option: unknown key",
        'start = "watt1/paper"': "cases[0] ('subtask2') with algorithm 'nsga2': preset: preset is a watt1 design",
    }
    for change, message in bad.items():
        text = (TINY.replace('name = "spea2"\npop_size = 20', 'name = "spea2"\npop_size = 20\n' + change)
                if "options" in change else TINY.replace('start = "stephenson1/X1"', change))
        assert main(["study", str(write(tmp_path, text)), "--out", str(tmp_path / "out"), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("clm: error: " + message) and len(err.splitlines()) == 1, err
        assert not (tmp_path / "out" / "study.sqlite").exists()
    odd = TINY.replace('name = "spea2"\npop_size = 20', 'name = "imtcmo"\npop_size = 13')
    assert main(["study", str(write(tmp_path, odd)), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "with algorithm 'imtcmo': algorithm: imtcmo needs an even population" in capsys.readouterr().err
    best = TINY.replace("budget = 100", 'budget = 100\nbest = "zzz"')
    with pytest.raises(ValueError, match=r"cases\[0\].best: unknown pick metric 'zzz'; one of mse, S, I"):
        load_study(write(tmp_path, best))


def test_a_changed_study_is_refused_or_rerun_never_reused(reference_run: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]):
    # Raising the budget and running into the same folder reported "6 already done" with the old runs' numbers
    # under the new settings: a cell's key is its case, algorithm and seed only.
    import shutil

    out = tmp_path / "out"
    shutil.copytree(reference_run, out)
    before = {r["key"]: r["metrics"]["n_eval"] for r in Store(out).rows()}
    raised = TINY.replace("budget = 100", "budget = 160")
    assert main(["study", str(write(tmp_path, raised)), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"clm: error: {out} holds 6 finished cell(s) run with other settings, e.g. "
                          "subtask2/nsga2/1: case.budget 100 -> 160; pass --rerun-changed"), err
    assert {r["key"]: r["metrics"]["n_eval"] for r in Store(out).rows()} == before  # nothing touched
    # A comment or a label changes no result: still resumed.
    same = TINY.replace('name = "spea2"', 'name = "spea2"\nlabel = "SPEA2"') + "# a note\n"
    assert main(["study", str(write(tmp_path, same)), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    assert "6 already done, 0 run now" in capsys.readouterr().out
    # An edit of the case's config file counts (its parsed contents, not its layout).
    config = tmp_path / "case.toml"
    config.write_text(CONFIG.read_text().replace("n_samples = 360", "n_samples = 180"))
    assert "n_samples = 180" in config.read_text()
    moved = TINY.replace(str(CONFIG), str(config))
    assert main(["study", str(write(tmp_path, moved)), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    assert "case.config.n_samples 360 -> 180" in capsys.readouterr().err
    # --rerun-changed runs the six again with the new budget.
    assert main(["study", str(write(tmp_path, raised)), "--out", str(out), "--workers", "1", "--quiet",
                 "--rerun-changed"]) == 0
    assert "0 already done, 6 run now" in capsys.readouterr().out
    after = {r["key"]: r["metrics"]["n_eval"] for r in Store(out).rows()}
    assert all(160 <= after[k] and before[k] < 160 for k in before), (before, after)


def test_a_study_begun_before_cells_kept_their_settings_still_resumes(reference_run: Path, tmp_path: Path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(reference_run, out)
    db = sqlite3.connect(out / "study.sqlite")
    db.execute("ALTER TABLE runs DROP COLUMN settings")
    db.commit()
    db.close()
    summary = run_study(load_study(write(tmp_path, TINY)), str(out), workers=1, stream=None)
    assert (summary.skipped, summary.ran) == (6, 0)


def test_resume_after_killing_the_client_loses_nothing_and_matches_an_uninterrupted_run(reference_run: Path,
                                                                                          tmp_path: Path):
    study_file = write(tmp_path, TINY.replace("budget = 100", "budget = 100\nbest = \"mse\""))
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "core.cli", "study", str(study_file), "--out", str(out), "--workers", "1"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    n = 0
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "study.sqlite").exists():
            with sqlite3.connect(out / "study.sqlite") as db:
                try:
                    n = db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
                except sqlite3.OperationalError:
                    n = 0
            if n >= 2:
                break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the client and its local workers, mid-study
    proc.wait()
    kept = Store(out).rows()
    assert 2 <= len(kept) < 6 and all(r["status"] == "done" for r in kept)
    summary = run_study(load_study(study_file), str(out), workers=2, stream=None)
    assert summary.skipped == len(kept) and summary.ran == 6 - len(kept)
    rows = Store(out).rows()
    assert len(rows) == 6 and len({r["key"] for r in rows}) == 6
    assert comparable(rows) == comparable(Store(reference_run).rows())
    write_report(out)
    assert report_without_times(out) == report_without_times(reference_run)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_same_study_runs_on_a_real_dask_scheduler_and_worker(reference_run: Path, tmp_path: Path):
    port = free_port()
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    procs = [subprocess.Popen([str(bindir / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        procs.append(subprocess.Popen([str(bindir / "dask"), "worker", f"tcp://127.0.0.1:{port}", "--nthreads", "1",
                                       "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1"], cwd=ROOT, env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        out = tmp_path / "out"
        code = main([
            "study", str(write(tmp_path, TINY)), "--out", str(out), "--scheduler", f"tcp://127.0.0.1:{port}", "--quiet",
        ])
        assert code == 0
        assert comparable(Store(out).rows()) == comparable(Store(reference_run).rows())
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.parametrize(("edit", "message"), [
    (('name = "spea2"', 'name = "nope"'), "algorithms[1].name: unknown algorithm 'nope'"),
    (('seeds = "1..3"', 'seeds = "3..1"'), "seeds: empty seed range"),
    (('seeds = "1..3"', 'seeds = []'), "seeds: no seeds"),
    (('seeds = "1..3"', 'seeds = "1..99999999999"'), "seeds: seeds must be <="),
    (('stages = ["subtask2"]', 'stages = ["subtask9"]'), "cases[0].stages[0]: no stage 'subtask9'"),
    (("budget = 100", "budget = -5"), "cases[0].budget: must be >= 1, got -5"),
    (("budget = 100", 'budget = "lots"'), "cases[0].budget: expected an integer, got a string"),
    (('start = "stephenson1/X1"', 'start = "stephenson1/X9"'), "cases[0].start: unknown preset"),
    (("pop_size = 20\n[[algorithms]]", "pop_size = 20\ncolour = 1\n[[algorithms]]"),
     "algorithms[0].colour: unknown key"),
    (('name = "tiny"', 'name = "tiny"\nreference = "moead"'), "reference: 'moead' is not one of"),
    ((f'config = "{CONFIG}"', 'config = "missing.toml"'), "cases[0].config: no such config file"),
    (('name = "spea2"', 'name = "nsga2"'), "algorithms[1].name: 'nsga2' is listed twice"),
])
def test_a_malformed_study_file_is_refused_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], edit,
                                                         message):
    text = TINY.replace(*edit)
    assert text != TINY
    code = main(["study", str(write(tmp_path, text)), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("clm: error: ") and message in err, err
    assert not (tmp_path / "out").exists()  # nothing was started


def test_the_run_cap_counts_cases_too(tmp_path: Path):
    # 50 000 seeds x 2 algorithms is the cap itself; a second case doubles it
    text = TINY.replace('seeds = "1..3"', 'seeds = "1..50000"')
    load_study(write(tmp_path, text))
    two = text + TINY[TINY.index("[[cases]]"):].replace('name = "subtask2"', 'name = "again"')
    with pytest.raises(ValueError, match="study: 200000 runs is more than the 100000"):
        load_study(write(tmp_path, two, "two.toml"))


def test_command_line_mistakes_are_one_line_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    study = write(tmp_path, TINY)
    (tmp_path / "file").write_text("x")
    for argv in (["study", str(study)], ["study", str(study), "--out", ""],
                 ["study", str(study), "--out", str(tmp_path / "file")],
                 ["study", str(study), "--out", str(tmp_path / "o"), "--workers", "0"],
                 ["study", "report", str(tmp_path)], ["study", "report"], ["study", str(tmp_path / "none.toml"),
                                                                           "--out", str(tmp_path / "o")],
                 ["study", str(tmp_path / "file"), "--out", str(tmp_path / "o")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("clm: error: "), (argv, err)


def test_seed_ranges():
    assert parse_seeds("1..20") == tuple(range(1, 21))
    assert parse_seeds("7") == (7,)
    assert parse_seeds([3, 1]) == (3, 1)
    with pytest.raises(ValueError, match="listed twice"):
        parse_seeds([1, 1])


@pytest.mark.parametrize("algorithm", ["cmoes", "mccmo"])
def test_every_algorithm_gets_the_budget_in_evaluations(tmp_path: Path, algorithm: str):
    # Converting the budget into generations at a nominal rate gave CMOES half of it on subtask 1 and MCCMO
    # three quarters; now every cell ends within one generation (at most 3N) after the budget.
    from core.study.cell import run_cell

    study = load_study(write(tmp_path, TINY.replace('"spea2"', f'"{algorithm}"').replace("budget = 100",
                                                                                      "budget = 400")))
    cell = next(c for c in study.cells() if c["algorithm"]["name"] == algorithm and c["seed"] == 1)
    record = run_cell(dict(cell, threads=1))
    assert record["status"] == "done", record.get("error")
    assert 400 <= record["metrics"]["n_eval"] < 400 + 3 * 20


def test_a_failing_stage_names_where_it_failed_not_where_the_failure_was_passed_on(tmp_path: Path,
                                                                                  monkeypatch: pytest.MonkeyPatch):
    import core.optimize.run as run_module
    from core.study.cell import run_cell

    def fails(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(run_module, "run_stage", fails)
    study = load_study(write(tmp_path, TINY))
    record = run_cell(dict(study.cells()[0], threads=1))
    assert record["status"] == "failed"
    assert record["error"].startswith("StageFailed: stage ")
    assert record["error"].endswith("failed: ZeroDivisionError: float division by zero (test_study.py:"
                                    f"{fails.__code__.co_firstlineno + 1})")


def test_a_local_cluster_asks_for_no_fixed_dashboard_port() -> None:
    # Rehearsal 6: with another cluster on 8787 every study, --quiet too, printed "Port 8787 is already in use".
    import socket
    import warnings

    from core.study.runner import client_for

    held = socket.socket()
    try:
        held.bind(("127.0.0.1", 8787))
        held.listen()
    except OSError:  # another process has it already: the same situation
        pass
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", UserWarning)
            with client_for(None, 1) as client:
                assert client.dashboard_link.startswith("http://127.0.0.1:")
                assert ":8787/" not in client.dashboard_link
    finally:
        held.close()


def test_ctrl_c_says_what_was_kept_and_that_the_same_command_goes_on(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str], monkeypatch):
    # QA (session 36): clm study ended with 130 and not a word, whether finished cells were kept or not.
    import core.study.runner as runner

    study = write(tmp_path, TINY)

    def interrupted(kept: int):
        def run(study, out, **kw):
            if kept:
                store = Store(out)  # the database as the runner makes it
                store.close()
                db = sqlite3.connect(Path(out) / "study.sqlite")
                cols = [r[1] for r in db.execute("PRAGMA table_info(runs)")]
                for k in range(kept + 1):  # and a failed one, which runs again: not counted as kept
                    status = "done" if k < kept else "failed"
                    db.execute(f"INSERT INTO runs ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})",
                               [f"key{k}" if c == "key" else status if c == "status" else 0 for c in cols])
                db.commit()
                db.close()
            raise KeyboardInterrupt
        return run

    monkeypatch.setattr(runner, "run_study", interrupted(0))
    assert main(["study", str(study), "--out", str(tmp_path / "a")]) == 130
    assert capsys.readouterr().err == "clm: stopped before any run finished; nothing kept\n"
    assert not (tmp_path / "a").exists()
    monkeypatch.setattr(runner, "run_study", interrupted(2))
    assert main(["study", str(study), "--out", str(tmp_path / "b")]) == 130
    assert capsys.readouterr().err == (f"clm: stopped; 2 finished runs kept in {tmp_path / 'b'}: the same command "
                                       "goes on from there\n")
