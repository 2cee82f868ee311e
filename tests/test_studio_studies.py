"""The Studies panel's reading of finished studies (issue 12, item 6): found under a folder, read without
writing, box plots per case and metric, and a run's picked design loaded into the editor."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from study_files import tiny_study

from core.formats.study import load_study
from core.optimize.pipeline import Pipeline
from core.study.runner import run_study
from studio.panels.studies import box_figure
from studio.studies import StudyRun, find_studies, finished_runs, picked_design, study_rows

TINY = tiny_study("nsga2", "cmoes").replace('name = "cmoes"\n', 'name = "cmoes"\nlabel = "CMOES (2024)"\n')


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("runs")
    (root / "tiny.toml").write_text(TINY)
    run_study(load_study(root / "tiny.toml"), str(root / "tiny_dir"), workers=1, stream=None)
    (root / "not-a-study").mkdir()
    return root


def test_studies_are_found_and_read_without_writing(studies):
    dirs = find_studies(studies)
    assert [d.name for d in dirs] == ["tiny_dir"]
    before = sorted((p.name, p.stat().st_mtime_ns) for p in (studies / "tiny_dir").iterdir())
    name, rows = study_rows(dirs[0])
    assert name == "tiny"  # the study's name, not its folder's
    assert len(rows) == 4 and {r["status"] for r in rows} == {"done"}
    assert sorted((p.name, p.stat().st_mtime_ns) for p in (studies / "tiny_dir").iterdir()) == before
    runs = finished_runs(rows)
    assert {r.algorithm for r in runs} == {"nsga2", "cmoes"} and all("mse" in r.metrics for r in runs)
    fig = box_figure(runs, "subtask2", "mse")
    # Named as the study file labels them, as its report does (a rehearsal read "nsga2" where it said "NSGA-II").
    # In the study file's order, its reference marked (rehearsal 6: alphabetical, the reference unsaid).
    assert [t.name for t in fig.data] == ["nsga2 (reference)", "CMOES (2024)"] and all(len(t.y) == 2 for t in fig.data)
    assert {r.label.split(" · ")[1] for r in runs} == {"CMOES (2024)", "nsga2 (reference)"}
    assert fig.layout.yaxis.title.text == "MSE (mm)" and fig.layout.title.text == "subtask2: MSE (mm)"
    with pytest.raises(ValueError, match="not a folder"):
        find_studies(studies / "missing")
    # A relative folder (the panel's default "runs") is named by its full path, and where it is read from.
    with pytest.raises(ValueError, match=f"^{re.escape(str(Path.cwd() / 'no-such-runs'))} is not a folder "
                                         r"\(a relative folder is read from where the studio was started\)$"):
        find_studies(Path("no-such-runs"))
    with pytest.raises(ValueError, match="holds no study.sqlite"):
        study_rows(studies / "not-a-study")


def test_each_run_carries_the_reports_hv_and_igd_plus_and_the_dropdown_names_metrics_as_the_report(studies):
    """Rehearsal 3: the Metric dropdown offered `n_eval`, `wall_time` and no HV or IGD+, the report's first rows."""
    from core.study.report import LABELS
    from core.study.stats import run_values
    from studio.panels.studies import metric_name

    _, rows = study_rows(studies / "tiny_dir")
    runs = finished_runs(rows)
    want = {(r["algorithm"], int(r["seed"])): v for r, v in run_values([r for r in rows if r["case"] == "subtask2"])}
    for run in runs:
        v = want[(run.algorithm, run.seed)]
        assert run.metrics["hv"] == pytest.approx(v["hv"]) and run.metrics["igd_plus"] == pytest.approx(v["igd_plus"])
    assert all(0.0 <= r.metrics["hv"] for r in runs) and max(r.metrics["hv"] for r in runs) > 0
    assert metric_name("wall_time") == "time (s)" == LABELS["wall_time"] and metric_name("hv") == "HV"
    assert box_figure(runs, "subtask2", "igd_plus").layout.yaxis.title.text == "IGD+"


def test_an_older_study_is_read_without_migrating_it_and_a_broken_one_is_refused(tmp_path):
    import sqlite3

    old = tmp_path / "old"
    old.mkdir()
    db = sqlite3.connect(old / "study.sqlite")  # the schema before cells kept their settings
    db.executescript("CREATE TABLE runs (key TEXT PRIMARY KEY, case_name TEXT NOT NULL, algorithm TEXT NOT NULL, "
                     "seed INTEGER NOT NULL, status TEXT NOT NULL, error TEXT, metrics TEXT, result_path TEXT, "
                     "task_time REAL, attempts INTEGER NOT NULL DEFAULT 1);"
                     "CREATE TABLE meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);"
                     "INSERT INTO meta VALUES ('study', '{\"name\": \"old one\"}');"
                     "INSERT INTO runs VALUES ('k', 'c', 'nsga2', 1, 'done', NULL, '{\"mse\": 4.1}', 'runs/k.json', "
                     "1.0, 1);")
    db.commit()
    db.close()
    name, rows = study_rows(old)
    assert name == "old one" and rows[0]["settings"] is None and rows[0]["metrics"] == {"mse": 4.1}
    columns = [r[1] for r in sqlite3.connect(old / "study.sqlite").execute("PRAGMA table_info(runs)")]
    assert "settings" not in columns  # read, not migrated
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "study.sqlite").write_bytes(b"not a database, but a file by that name" * 100)
    with pytest.raises(ValueError, match="not a readable study"):
        study_rows(broken)


def test_a_runs_picked_design_comes_back_exactly(studies):
    _, rows = study_rows(studies / "tiny_dir")
    run = finished_runs(rows)[0]
    design = picked_design(studies / "tiny_dir", run)
    data = json.loads((studies / "tiny_dir" / run.result_path).read_text())
    last = Pipeline.from_dict(data["pipeline"]).results[-1]
    assert np.array_equal(design.params[0], last.X[last.picked])
    assert run.metrics["mse"] == pytest.approx(float(last.metrics["mse"][last.picked]))


def test_a_run_says_which_target_it_ran_against_and_targets_compare_by_value(studies):
    from studio.studies import picked, same_target, target_words

    _, rows = study_rows(studies / "tiny_dir")
    design, ran = picked(studies / "tiny_dir", finished_runs(rows)[0])
    assert ran is not None and same_target(ran, "cycloid") and target_words(ran).startswith("compound cycloid L = 300")
    assert same_target("cycloid:L=300.0,H=100.0,T=2.0", "cycloid:T=2,L=300,H=100")
    assert not same_target("cycloid:L=300.0,H=100.0,T=2.0", "cycloid:L=300,H=100,T=2.5")
    assert not same_target("cycloid", "/tmp/x/ellipse.csv") and same_target("/a/ellipse.csv", "/b/ellipse.csv")
    assert target_words("/tmp/x/ellipse.csv") == "curve ellipse.csv"


def test_loading_a_study_design_under_another_target_says_so(studies):
    # The notification said "mse 5.04" (the run's, against the cycloid) while the Metrics panel said MSE 50.67 mm
    # (against an uploaded ellipse), and nothing said why.
    from types import SimpleNamespace

    from studio.app import Studio
    from studio.state import Session
    from studio.target import Curve

    notes: list[tuple[str, str, str]] = []
    client = SimpleNamespace(client_id=1, add_notification=lambda title, body, color="", **_: notes.append(
        (title, body, color)))
    s = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        s.animator.stop()
        panel = s.studies
        panel.path.value = str(studies)
        for cb in list(panel.scan._impl.update_cb):
            cb(SimpleNamespace(client=client, target=panel.scan))
        assert panel.run.options and panel.run.options[0] != "(none)"

        def load():
            for cb in list(panel.load._impl.update_cb):
                cb(SimpleNamespace(client=client, target=panel.load))
            return notes[-1]

        title, body, color = load()  # the paper's cycloid in the editor: the study's own target
        assert (title, color) == ("Design loaded", "green")
        s.session.set_curve(Curve("ellipse.csv", ((0.0, 0.0), (200.0, 0.0), (200.0, 60.0), (0.0, 60.0)), None, 2.0))
        title, body, color = load()
        assert title == "Design loaded: its study ran against another target" and color == "yellow"
        assert "compound cycloid L = 300 mm" in body and "curve ellipse.csv" in body
    finally:
        s.close()


def test_a_run_file_outside_the_study_is_refused(studies):
    bad = StudyRun("subtask2", "nsga2", 1, {}, "../tiny.toml")
    with pytest.raises(ValueError, match="outside the study directory"):
        picked_design(studies / "tiny_dir", bad)


def test_an_rtclm_run_is_listed_with_its_deviations() -> None:
    run = StudyRun("rtclm_case1", "imtcmo", 4, {"dh6": 0.2681, "dh4": 0.1984, "h6": 50.27}, "runs/x.json", "IMTCMO")
    assert run.label == "rtclm_case1 · IMTCMO · seed 4 · dh6 0.268 · dh4 0.198"


def test_runs_are_listed_case_by_case_in_the_study_files_algorithm_order(tmp_path) -> None:
    # Review of session 30: ordering by algorithm alone scattered each case's runs over the algorithms' blocks.
    from core.study.store import Store

    store = Store(tmp_path)
    store.set_meta("study", {"name": "two", "algorithms": ["nsga2", "cmoes"], "labels": {}, "reference": "nsga2",
                             "cases": ["c1", "c2"], "seeds": [1, 2]})
    for case in ("c1", "c2"):
        for alg in ("cmoes", "nsga2"):
            for seed in (2, 1):
                store.save({"key": f"{case}/{alg}/{seed}", "case": case, "algorithm": alg, "seed": seed,
                            "status": "done", "result": "{}", "metrics": {}})
    store.close()
    _, rows = study_rows(tmp_path)
    assert [(r["case"], r["algorithm"], r["seed"]) for r in rows] == [
        ("c1", "nsga2", 1), ("c1", "nsga2", 2), ("c1", "cmoes", 1), ("c1", "cmoes", 2),
        ("c2", "nsga2", 1), ("c2", "nsga2", 2), ("c2", "cmoes", 1), ("c2", "cmoes", 2)]
