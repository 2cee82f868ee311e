"""``clm design`` writes result.json and one CSV per stage; ``clm compare`` prints the comparison table."""

from __future__ import annotations

import csv
import json
import re
import signal
from pathlib import Path

import numpy as np
import pytest

from core.cli import main
from core.optimize.pipeline import Pipeline

ROOT = Path(__file__).resolve().parents[1]

TINY = """
name = "tiny"
preset = "stephenson1/X0"
seed = 4
n_samples = 72

[algorithm]
pop_size = 12

[[stages]]
name = "subtask1"
box = "subtask1"
n_gen = 3
pick = "best:f1"

[[stages]]
name = "subtask2"
box = "subtask2"
n_gen = 2
pick = "knee"
[stages.options]
f1_max = "start+1.0"
"""

BASELINE = """
name = "dp"
method = "dp_ga"
mechanism = "stephenson1"
seed = 1
n_samples = 72
[baseline]
n_points = 12
pop_size = 12
n_gen = 3
"""


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:
    root = tmp_path_factory.mktemp("design")
    (root / "tiny.toml").write_text(TINY)
    (root / "dp.toml").write_text(BASELINE)
    assert main(["design", str(root / "tiny.toml"), "--out", str(root / "h"), "--quiet"]) == 0
    assert main(["design", str(root / "dp.toml"), "--out", str(root / "b"), "--quiet"]) == 0
    return root / "h", root / "b", ""


def test_design_writes_result_json_and_a_csv_per_stage(outputs: tuple[Path, Path, str]) -> None:
    h, _, _ = outputs
    assert sorted(p.name for p in h.iterdir()) == ["0_subtask1.csv", "1_subtask2.csv", "result.json"]
    data = json.loads((h / "result.json").read_text())
    assert data["status"] == "complete" and data["config"]["name"] == "tiny"
    pipe = Pipeline.from_dict(data["pipeline"])
    with (h / "1_subtask2.csv").open() as f:
        rows = list(csv.DictReader(f))
    res = pipe.results[1]
    assert res is not None and len(rows) == res.pop
    assert [int(r["picked"]) for r in rows].index(1) == res.picked
    np.testing.assert_array_equal([float(r["h_s"]) for r in rows], res.F[:, 0])
    np.testing.assert_array_equal([float(r["r1"]) for r in rows], res.X[:, 4])
    assert sum(int(r["front"]) for r in rows) == len(res.front)
    # Constraint columns are not "g[...]" beside the crank phase g (rehearsal 3 read them as one family).
    assert [k for k in rows[0] if k.startswith("constraint[")] == [f"constraint[{c}]" for c in res.constraints]
    assert not any(k.startswith("g[") for k in rows[0])


def test_design_prints_a_summary_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "t.toml").write_text(TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1"))
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "o")]) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    assert lines[1].split()[:4] == ["stage", "status", "gen", "time"]
    assert "MSE (mm)" in lines[1] and "S (%)" in lines[1] and "I (mm/s)" in lines[1]  # metrics with units
    assert lines[2].split()[:3] == ["subtask1", "complete", "1"]
    assert "[1/2 subtask1]" in cap.err and "[2/2 subtask2]" in cap.err  # progress on stderr


def test_a_scheduler_a_config_without_a_multi_start_does_not_use_is_said(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "t.toml").write_text(TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1"))
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "o"), "--quiet", "--scheduler",
                 "tcp://127.0.0.1:9"]) == 0
    assert capsys.readouterr().err == (f"clm: note: --scheduler is not used: {tmp_path / 't.toml'} has no multi-start "
                                       "block (only a block's chains run on Dask)\n")


def test_a_scheduler_that_does_not_answer_is_one_line_exit_2_before_anything_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # Rehearsal 8: the address was first tried inside the multi-start stage, so clm design exited 1 and left a
    # failed result.json in --out (a retry then needed --overwrite); clm study and the docs say exit 2.
    import core.optimize.workers as workers

    patient = workers.connect
    monkeypatch.setattr(workers, "connect", lambda address: patient(address, timeout="1s"))  # not 20 s in a test
    starts = 'pick = "best:f1"\nstarts = {n = 2, until = "subtask1", select = "best:f1"}'
    (tmp_path / "m.toml").write_text(TINY.replace('pick = "best:f1"', starts, 1))
    out = tmp_path / "o"
    assert main(["design", str(tmp_path / "m.toml"), "--out", str(out), "--quiet", "--scheduler",
                 "tcp://127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("clm: error: no Dask scheduler answers at tcp://127.0.0.1:1 ")
    assert not (out / "result.json").exists()


def test_the_seed_given_on_the_command_line_is_the_one_recorded_and_compared(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Rehearsal 8: --seed 2 ran seed 2 but result.json kept the file's seed 1, and clm compare labelled it "seed 1".
    (tmp_path / "t.toml").write_text(TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1"))
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "s2"), "--seed", "2", "--quiet"]) == 0
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "s3"), "--seed", "3", "--quiet"]) == 0
    data = json.loads((tmp_path / "s2" / "result.json").read_text())
    assert data["config"]["seed"] == 2
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "s2"), str(tmp_path / "s3")]) == 0
    out = capsys.readouterr().out
    assert "(nsga2, seed 2)" in out and "(nsga2, seed 3)" in out and "seed 4" not in out
    # One run named twice (its folder and its result.json) is listed once, with a word (lab rehearsal).
    assert main(["compare", str(tmp_path / "s2"), str(tmp_path / "s2" / "result.json")]) == 0
    cap = capsys.readouterr()
    assert cap.out.count("tiny: ") == 1 and cap.err == f"clm: note: {tmp_path / 's2' / 'result.json'} is given more " \
        "than once; listed once\n"


def test_compare_prints_one_row_per_method(outputs: tuple[Path, Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    h, b, _ = outputs
    assert main(["compare", str(h), str(b / "result.json"), "--paper"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["method", "time", "(s)"]
    assert out[1].startswith("tiny: subtask2 pick") and out[2].startswith("dp: DP+GA")
    assert any(line.startswith("paper: DP+SQP (printed)") for line in out)
    data = json.loads((h / "result.json").read_text())
    mse = data["rows"][0]["mse"]
    assert f"{mse:.4g}" in out[1].split()
    # The paper's S is h_s / 300: it sits in a column of its own, beside ours (h_s / l_s), never under it.
    head = out[0].split("  ")
    col = [c.strip() for c in head if c.strip()].index("h_s/300 (%)")
    assert [c.strip() for c in head if c.strip()][col - 1] == "S (%)"
    ours = out[1].split()
    assert f"{100 * data['rows'][0]['h_s'] / 300:.4g}" in ours and f"{data['rows'][0]['S']:.4g}" in ours
    paper = next(line for line in out if line.startswith("paper: hierarchical")).split()
    assert paper[-4:] == ["3.97", "-", "0.95", "0.9"]  # MSE, S (not the paper's), h_s/300, I
    assert any("copy error" in line for line in out)


def test_compare_names_the_run_of_rows_alike_and_stars_an_infeasible_one(outputs: tuple[Path, Path, str],
                                                                        tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    h, _, _ = outputs
    data = json.loads((h / "result.json").read_text())
    files = []
    for seed, feasible in ((1, True), (2, False)):  # two cells of a study: one config, two seeds
        data["config"]["seed"], data["rows"][0]["feasible"] = seed, feasible
        files.append(tmp_path / f"{seed}.json")
        files[-1].write_text(json.dumps(data))
    assert main(["compare", *map(str, files)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("tiny: subtask2 pick (nsga2, seed 1) ") and "*" not in out[1]
    assert out[2].startswith("tiny: subtask2 pick (nsga2, seed 2) *")
    assert out[3].startswith("* infeasible: the pick misses its stage's constraints")
    assert main(["compare", str(files[0])]) == 0  # a row alone keeps its label
    assert capsys.readouterr().out.splitlines()[1].startswith("tiny: subtask2 pick  ")


def test_compare_names_the_folder_of_rows_still_alike(outputs: tuple[Path, Path, str], tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    # Copies of one config with other targets (an RTCLM case file with h4 = 300) gave rows no one could tell apart.
    h, _, _ = outputs
    data = (h / "result.json").read_text()
    for d in ("h4_220", "h4_300"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "result.json").write_text(data)
    assert main(["compare", str(tmp_path / "h4_220"), str(tmp_path / "h4_300")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith(f"tiny: subtask2 pick (nsga2, seed 4) in {tmp_path / 'h4_220'}")
    assert out[2].startswith(f"tiny: subtask2 pick (nsga2, seed 4) in {tmp_path / 'h4_300'}")


def tiny_rtclm_run(out: Path) -> None:
    """RTCLM case 1's config, 12 members and 3 generations a stage, designed into ``out``."""
    text = (ROOT / "assets" / "configs" / "rtclm_case1.toml").read_text()
    config = out.parent / "rtclm_tiny.toml"
    config.write_text(text.replace("n_gen = 1500", "n_gen = 3").replace("n_gen = 200", "n_gen = 3")
                      .replace("pop_size = 100", "pop_size = 12"))
    assert main(["design", str(config), "--out", str(out), "--quiet"]) == 0


def test_compare_paper_appends_the_rtclm_cases_for_rtclm_runs(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    # It appended the Stephenson-I baselines of Appendix B-5, which have no h6 or h4 to compare with.
    tiny_rtclm_run(tmp_path / "o")
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "o"), "--paper"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[-4:] == ["h6", "(mm)", "h4", "(mm)"] and "h_s/300" not in out[0]
    assert out[2].startswith("paper: RTCLM case 1 (printed)")
    assert out[2].split()[-7:] == ["798", "-", "-", "-", "-", "50.1", "220.1"]  # no evaluations printed
    # The run's own row counts its evaluations, every stage's (lab rehearsal: CMOES spent 2-3x NSGA-II's at the
    # same population and generations, and nothing said so).
    data = json.loads((tmp_path / "o" / "result.json").read_text())
    spent = sum(r["n_evals"] for r in data["pipeline"]["results"] if r is not None)
    assert spent > 0 and data["rows"][0]["evals"] == spent
    assert out[0].split()[3] == "evaluations" and out[1].split()[-6] == str(spent)
    assert len([x for x in out if x.startswith("paper: ")]) == 5 and not any("DP+SQP" in x for x in out)


def test_compare_refuses_a_directory_without_a_result(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("clm: error: ")


def test_design_lists_every_chain_and_tags_their_progress(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    starts = 'pick = "best:f1"\nstarts = {n = 3, until = "subtask1", select = "best:f1"}'
    (tmp_path / "m.toml").write_text(TINY.replace('pick = "best:f1"', starts, 1))
    assert main(["design", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), "--workers", "2"]) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    assert "2 worker processes" in lines[0]
    i = next(k for k, line in enumerate(lines) if line.startswith("multi-start subtask1..subtask1: 3 chains"))
    assert lines[i + 1].split()[:7] == ["chain", "status", "time", "(s)", "pick", "at", "feasible"]
    rows = lines[i + 2 : i + 5]
    assert all(" subtask1 " in r for r in rows)
    data = json.loads((tmp_path / "o" / "result.json").read_text())
    chosen = data["multistart"][0]["chosen"]
    assert [r.split()[0] for r in rows].count("*") == 1
    assert rows[chosen].startswith("* ") and data["workers"] == 2
    assert all(f"chain {j}]" in cap.err for j in range(3))
    assert main(["design", str(tmp_path / "m.toml"), "--out", str(tmp_path / "p"), "--workers", "0"]) == 2


def test_design_says_what_a_screen_kept_and_where_each_chain_stopped(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    starts = ('pick = "best:f1"\nstarts = {n = 3, until = "subtask2", select = "best:S", '
              'screen = {after = "subtask1", keep = 1, by = "best:f1", where = {f2_max = 1e6}}}')
    (tmp_path / "m.toml").write_text(TINY.replace('pick = "best:f1"', starts, 1))
    assert main(["design", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), "--workers", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("multi-start subtask1..subtask2: 3 chains"))
    assert lines[i].endswith("; after subtask1 the 1 best by best:f1, f2_max 1e+06 went on")
    rows = [r.split() for r in lines[i + 2 : i + 5]]
    kept = [r for r in rows if "complete" in r]
    dropped = [r for r in rows if "dropped" in r]
    assert len(kept) == 1 and len(dropped) == 2
    # A dropped chain's row is its subtask-1 pick, and says nothing of subtask 2's constraints.
    assert all(r[r.index("dropped") + 2 : r.index("dropped") + 4] == ["subtask1", "-"] for r in dropped)
    k = kept[0]
    assert k[k.index("complete") + 2] == "subtask2" and k[k.index("complete") + 3] in ("yes", "no")


def test_design_notes_a_stop_not_reached_and_an_infeasible_pick(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    # An impossible target (an RTCLM h4 of 5000 mm) ended "complete", and nothing but compare's star said so.
    text = TINY.replace('pick = "best:f1"', 'pick = "best:f1"\nstop_below = [0.0, 0.0, 0.0]', 1)
    (tmp_path / "m.toml").write_text(text.replace('f1_max = "start+1.0"', "f1_max = 0.001"))
    assert main(["design", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert ("note: subtask1 spent its budget (3 generations, 36 evaluations) without reaching its stop_below "
            "[0, 0, 0] (its pick: f1 ") in out
    assert re.search(r"note: subtask2's pick #\d+ misses the stage's constraints \(0 of 12 members meet them\)", out)
    (tmp_path / "n.toml").write_text(TINY)
    assert main(["design", str(tmp_path / "n.toml"), "--out", str(tmp_path / "p"), "--quiet"]) == 0
    assert "note:" not in capsys.readouterr().out


def test_an_earlier_run_in_out_is_kept_unless_overwrite_replaces_it_whole(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "t.toml").write_text(TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1"))
    (tmp_path / "dp.toml").write_text(BASELINE.replace("n_gen = 3", "n_gen = 1"))
    out = tmp_path / "o"
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(out), "--quiet"]) == 0
    (out / "pareto-0_subtask1.png").write_bytes(b"png")  # clm-charts on that run
    for mine in ("notes.txt", "2024_measurements.csv", "pareto-from-paper.png"):  # the designer's own files
        (out / mine).write_text("mine")
    before = (out / "result.json").read_text()
    capsys.readouterr()
    # A second run into the same folder would have overwritten result.json and left the other CSVs beside it.
    assert main(["design", str(tmp_path / "dp.toml"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("clm: error: --out") and "--overwrite" in err and "\n" not in err
    assert (out / "result.json").read_text() == before
    assert main(["design", str(tmp_path / "dp.toml"), "--out", str(out), "--quiet", "--overwrite"]) == 0
    assert "removed 3 file(s) of the earlier run" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["2024_measurements.csv", "dp_ga.csv", "notes.txt",
                                                     "pareto-from-paper.png", "result.json"]


def test_a_folder_without_an_earlier_run_keeps_every_file_and_a_foreign_result_is_never_replaced(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "dp.toml").write_text(BASELINE.replace("n_gen = 3", "n_gen = 1"))
    out = tmp_path / "o"
    out.mkdir()
    for mine in ("0_subtask1.csv", "pareto-0_subtask1.png", "dp_sqp.csv"):  # named like outputs, made by hand
        (out / mine).write_text("mine")
    assert main(["design", str(tmp_path / "dp.toml"), "--out", str(out), "--quiet"]) == 0
    assert "removed" not in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["0_subtask1.csv", "dp_ga.csv", "dp_sqp.csv",
                                                     "pareto-0_subtask1.png", "result.json"]
    # A result.json edited to name a file outside --out: nothing outside is touched.
    data = json.loads((out / "result.json").read_text())
    data["method"] = "hierarchical"
    data["pipeline"] = {"stages": [{"name": "x/../../outside"}]}  # 0_x/../../outside.csv
    (out / "result.json").write_text(json.dumps(data))
    (out / "0_x").mkdir()
    (tmp_path / "outside.csv").write_text("mine")
    assert main(["design", str(tmp_path / "dp.toml"), "--out", str(out), "--quiet", "--overwrite"]) == 0
    assert (tmp_path / "outside.csv").read_text() == "mine"
    other = tmp_path / "other"
    other.mkdir()
    (other / "result.json").write_text('{"format": "something else"}')
    assert main(["design", str(tmp_path / "dp.toml"), "--out", str(other), "--quiet", "--overwrite"]) == 2
    assert "is not a 'clm design' result; not replacing it" in capsys.readouterr().err
    assert (other / "result.json").read_text() == '{"format": "something else"}'


@pytest.mark.parametrize(("signum", "code", "said"), [(2, 130, "stopping after this generation"),
                                                     (15, 143, "terminated; stopping after this generation")],
                         ids=["ctrl-c", "sigterm"])
def test_ctrl_c_or_sigterm_stop_clm_design_between_generations_and_write_the_partial_result(
        tmp_path: Path, signum: int, code: int, said: str, capsys: pytest.CaptureFixture[str]) -> None:
    # SIGTERM (kill, timeout, a batch scheduler's end of job) used to end the run with nothing written.
    import subprocess
    import sys

    from ctrl_c import sigint_as_in_a_terminal

    cfg = tmp_path / "long.toml"
    cfg.write_text(TINY.replace("n_gen = 3", "n_gen = 100000"))
    out = tmp_path / "out"
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-m", "core.cli", "design", str(cfg), "--out", str(out)], cwd=root,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_as_in_a_terminal)
    try:
        assert proc.stderr is not None and proc.stderr.read(1)  # the progress bar: generations are running
        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == code, stderr
    assert said in stderr and "Traceback" not in stderr
    result = json.loads((out / "result.json").read_text())
    stages = result["pipeline"]["results"]
    assert stages[0]["status"] == "cancelled" and stages[0]["generation"] < 100000, stages[0]["status"]
    # The stopped run's pick is there to evaluate (lab rehearsal: "the run picked no design (status cancelled)").
    assert stages[0]["picked"] is not None
    assert main(["evaluate", "--design", str(out)]) == 0
    assert "the run was stopped during" in capsys.readouterr().err


def test_a_stage_that_fails_keeps_the_stages_finished_before_it(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    # A stage that raised (a ZeroDivisionError in mutation once, after an hour of earlier stages) lost every
    # finished stage: the result was written only after the whole run returned.
    import core.optimize.run as run_module

    real = run_module.run_stage

    def second_fails(config, pipe, k, *args, **kwargs):  # type: ignore[no-untyped-def]
        if k == 1:
            raise ZeroDivisionError("float division by zero")
        return real(config, pipe, k, *args, **kwargs)

    monkeypatch.setattr(run_module, "run_stage", second_fails)
    (tmp_path / "t.toml").write_text(TINY)
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 1
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "clm: error: stage 'subtask2' failed: ZeroDivisionError: float division by zero; the 1 stage(s) finished "
        f"before it are in {tmp_path / 'o' / 'result.json'}")
    assert "Traceback" not in cap.err
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["0_subtask1.csv", "result.json"]
    data = json.loads((tmp_path / "o" / "result.json").read_text())
    assert data["status"] == "failed" and data["error"].startswith("stage 'subtask2': ZeroDivisionError")
    assert "Traceback" in data["error"] and "second_fails" in data["error"]
    lineage = Pipeline.from_dict(data["pipeline"]).lineage
    assert [r.name for r in lineage] == ["subtask1"] and lineage[0].picked is not None
    assert data["rows"][0]["label"] == "tiny: subtask1 pick" and data["rows"][0]["status"] == "failed"
    # clm compare reads it and marks it.
    assert main(["compare", str(tmp_path / "o")]) == 0
    assert "tiny: subtask1 pick [failed]" in capsys.readouterr().out


def test_an_rtclm_runs_auxiliary_mode_can_be_evaluated_simulated_and_drawn(tmp_path: Path,
                                                                           capsys: pytest.CaptureFixture[str]) -> None:
    # Its h4 needed a hand-edited design JSON: --design RUN took the primary mode only.
    tiny_rtclm_run(tmp_path / "o")
    h4 = json.loads((tmp_path / "o" / "result.json").read_text())["rows"][-1]["h4"]
    capsys.readouterr()
    assert main(["evaluate", "--design", str(tmp_path / "o"), "--mode", "auxiliary", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["mechanism"] == "rtclm_auxiliary" and data["h_m"] == pytest.approx(h4, abs=1e-5)
    assert main(["simulate", "--design", str(tmp_path / "o"), "--mode", "auxiliary", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mechanism"] == "rtclm_auxiliary"
    assert main(["evaluate", "--preset", "rtclm/case4/auxiliary", "--mode", "primary", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mechanism"] == "rtclm_primary"
    assert main(["simulate", "--preset", "stephenson1/X3", "--mode", "auxiliary"]) == 2
    assert capsys.readouterr().err.strip() == ("clm: error: --mode auxiliary: stephenson1 has no modes; only the RTCLM "
                                               "(rtclm_primary, rtclm_auxiliary) has")


def test_compare_given_a_study_directory_points_to_its_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Rehearsal 6: it said only "expected a 'clm design --out' directory".
    (tmp_path / "study.sqlite").write_bytes(b"")
    assert main(["compare", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path} is a study directory: compare its runs' files ({tmp_path}/runs/<case>/<algorithm>/" in err


def test_compile_time_is_recorded_said_in_the_summary_and_by_compare(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    # Rehearsal 8: a first run on a machine reported 16 s of stage time for a run that takes 0.17 s once the numba
    # kernels are cached, with no word; clm study and the studio already said it apart.
    from core.cli.design import summary

    (tmp_path / "t.toml").write_text(TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1"))
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "b"), "--quiet", "--seed", "9"]) == 0
    data = json.loads((tmp_path / "a" / "result.json").read_text())
    assert isinstance(data["compile_time"], float) and 0.0 <= data["compile_time"] <= data["wall_time"]
    data["compile_time"] = 12.3  # as a first run on a fresh machine records it
    (tmp_path / "a" / "result.json").write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert ("The time includes compiling numba kernels (a first run of this code, in this checkout; later runs load "
            f"them from the cache) in {tmp_path / 'a'} (12.3 s of it)." in out)
    assert str(tmp_path / "b") + " (" not in out
    from core.formats.config import load_config
    from core.optimize.run import DesignRun

    run = DesignRun(load_config(tmp_path / "t.toml"), wall_time=14.0, compile_time=12.3)
    assert ("wall 14.0 s (12.3 s of it compiling numba kernels, which later runs of this code load from its cache"
            in summary(run))
    assert "compiling" not in summary(DesignRun(load_config(tmp_path / "t.toml"), wall_time=1.0, compile_time=0.1))


def test_evaluating_a_runs_pick_names_the_target_the_run_was_made_against(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    # Rehearsal 8: clm evaluate --design RUN measured a run made against another target against the default cycloid
    # without a word; a CI gate then compared MSE against the wrong curve.
    text = TINY.replace("n_gen = 3", "n_gen = 1").replace("n_gen = 2", "n_gen = 1")
    (tmp_path / "t.toml").write_text(text.replace("[algorithm]", "[target]\nL = 250.0\n\n[algorithm]"))
    (tmp_path / "d.toml").write_text(text)
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert main(["design", str(tmp_path / "d.toml"), "--out", str(tmp_path / "p"), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["evaluate", "--design", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"clm: note: {tmp_path / 'o'} was made against target cycloid:L=250") and "--target" in err
    assert main(["evaluate", "--design", str(tmp_path / "p")]) == 0  # the default cycloid's run: nothing to say
    assert capsys.readouterr().err == ""


def test_a_second_design_into_a_folder_another_one_is_writing_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Lab rehearsal: two clm design runs into one --out both passed the "holds an earlier run" check (the first had
    # not written yet), and the second's files silently replaced the first's. The lock is the real one a running
    # clm design holds: taken here by another process, as a second terminal would.
    import subprocess
    import sys
    import time

    (tmp_path / "t.toml").write_text(TINY)
    out = tmp_path / "o"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from core.formats.files import dir_lock\n"
        f"with dir_lock({str(out)!r}, 'clm design', remove=True):\n"
        "    print('held', flush=True); time.sleep(30)\n")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        assert main(["design", str(tmp_path / "t.toml"), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err == (f"clm: error: {out}: another clm design is writing into it (process {holder.pid}); wait for it "
                       "to end, or choose another --out\n")
        assert sorted(p.name for p in out.iterdir()) == [".lock"]  # nothing of a run was written
    finally:
        holder.kill()
        holder.wait()
    # When the lock's holder is gone, the folder is free; the run leaves its outputs only (no .lock).
    time.sleep(0.1)
    assert main(["design", str(tmp_path / "t.toml"), "--out", str(out), "--quiet"]) == 0
    assert ".lock" not in {p.name for p in out.iterdir()} and (out / "result.json").is_file()


def test_a_design_run_piped_into_a_reader_that_goes_away_runs_on(tmp_path: Path) -> None:
    # Lab rehearsal: 'clm design ... 2>&1 | head' failed its stage on the progress bar's BrokenPipeError, and the
    # folder then refused a rerun. A real pipe whose reader has closed.
    import subprocess
    import sys

    (tmp_path / "t.toml").write_text(TINY)
    out = tmp_path / "o"
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-m", "core.cli", "design", str(tmp_path / "t.toml"), "--out", str(out)],
                            cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    proc.stderr.read(1)  # the first progress line has begun
    proc.stderr.close()
    assert proc.wait(timeout=300) in (0, 1)
    data = json.loads((out / "result.json").read_text())
    assert data["status"] == "complete", data.get("error")


def test_ctrl_c_of_a_piped_clm_design_whose_reader_went_away_still_keeps_the_pick(tmp_path: Path) -> None:
    # Review of session 32: `clm design ... 2>&1 | head`, then Ctrl-C: the handler's message raised BrokenPipeError
    # inside the running stage, which ended "failed" with nothing picked.
    import subprocess
    import sys

    from ctrl_c import sigint_as_in_a_terminal

    cfg = tmp_path / "long.toml"
    cfg.write_text(TINY.replace("n_gen = 3", "n_gen = 100000"))
    out = tmp_path / "out"
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-m", "core.cli", "design", str(cfg), "--out", str(out)], cwd=root,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=sigint_as_in_a_terminal)
    try:
        assert proc.stderr is not None and proc.stderr.read(1)  # generations are running
        proc.stderr.close()  # `head` has read its lines and gone
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
    finally:
        proc.kill()
    stages = json.loads((out / "result.json").read_text())["pipeline"]["results"]
    assert stages[0]["status"] == "cancelled" and stages[0]["picked"] is not None


def test_a_lock_file_that_cannot_be_made_is_refused_not_retried_forever(tmp_path: Path) -> None:
    # dir_lock makes the folder again when its lock file's folder vanished (a refused study's cleanup); a .lock
    # that can never be opened (a link into a missing folder) must end in a message, not a loop
    from core.formats.files import dir_lock

    out = tmp_path / "o"
    out.mkdir()
    (out / ".lock").symlink_to(tmp_path / "gone" / "lock")
    taken = r"its lock file \.lock could not be taken in 100 tries \(removed or held open by another program\?\)"
    with pytest.raises(ValueError, match=taken), dir_lock(out, "clm design"):
        pass


def test_a_run_stopped_under_overwrite_goes_beside_the_finished_run_it_would_have_replaced(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # QA (session 36): Ctrl-C during 'clm design --overwrite' replaced a finished run (its CSVs and charts) with a
    # cancelled one; a user who changed their mind lost the old results for nothing.
    import threading

    import core.cli.design as design_cli

    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY)
    out = tmp_path / "out"
    assert main(["design", str(cfg), "--out", str(out), "--quiet"]) == 0
    (out / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.name != ".lock"}
    real = design_cli.run_design

    def stopped(config, callback, cancel):  # Ctrl-C after the first generation
        ev = threading.Event()

        def cb(p) -> None:  # type: ignore[no-untyped-def]
            if p.generation >= 1:
                ev.set()

        return real(config, cb, ev)

    monkeypatch.setattr(design_cli, "run_design", stopped)
    capsys.readouterr()
    for beside in (tmp_path / "out-stopped", tmp_path / "out-stopped-2"):
        assert main(["design", str(cfg), "--out", str(out), "--quiet", "--overwrite"]) == 130
        err = capsys.readouterr().err
        assert f"the earlier run in {out} is kept as it was" in err and f"this one is in {beside}" in err
        assert {p.name: p.read_bytes() for p in out.iterdir() if p.name != ".lock"} == before
        assert json.loads((beside / "result.json").read_text())["status"] == "cancelled"
    # '--out .' goes beside the folder too, not into './-stopped' (review of session 36).
    monkeypatch.chdir(out)
    assert main(["design", str(cfg), "--out", ".", "--quiet", "--overwrite"]) == 130
    assert "this one is in " + str(tmp_path / "out-stopped-3") in capsys.readouterr().err
    assert not (out / "-stopped").exists() and {p.name for p in out.iterdir() if p.name != ".lock"} == set(before)
    monkeypatch.chdir(tmp_path)
    # A stage that fails before any result: its error is said, and the earlier run kept.
    from dataclasses import replace

    from core.optimize.run import StageFailed

    def failing(config, callback, cancel):
        ev = threading.Event()
        ev.set()
        run = real(config, None, ev)
        raise StageFailed(replace(run, status="failed", error="kaput trace"), "subtask1", RuntimeError("kaput"))

    monkeypatch.setattr(design_cli, "run_design", failing)
    assert main(["design", str(cfg), "--out", str(out), "--quiet", "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert "clm: error: stage 'subtask1' failed: RuntimeError: kaput" in err and "is kept as it was" in err
    assert json.loads((tmp_path / "out-stopped-4" / "result.json").read_text())["error"] == "kaput trace"
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.name != ".lock"} == before
    # A finished rerun replaces it, as --overwrite says.
    monkeypatch.setattr(design_cli, "run_design", real)
    assert main(["design", str(cfg), "--out", str(out), "--quiet", "--overwrite"]) == 0
    assert json.loads((out / "result.json").read_text())["status"] == "complete"
    assert (out / "notes.txt").read_text() == "mine"


def test_the_progress_line_names_each_objectives_best_on_its_own() -> None:
    # QA (session 37): "best h_s=17.12 I=47.66" read as one member's values; the member with h_s 17.12 had I 88.
    import io

    from core.cli.design import ProgressBar
    from core.optimize.stage import Progress

    F = np.array([[17.12, 88.0], [17.17, 47.66], [20.0, 10.0]])
    feasible = np.array([True, True, False])  # an infeasible member's I is not the best
    out = io.StringIO()
    ProgressBar(out, 2)(Progress("subtask2", 1, 10, 10, 1.0, 30, np.zeros((3, 2)), F, np.zeros((3, 1)),
                                 np.array([0.0, 0.0, 1.0]), feasible, ("h_s", "I")))
    assert out.getvalue().rstrip().endswith("gen 10/10  1.0 s  best h_s=17.12, best I=47.66")
