"""The Pareto chart's title, markers and the `clm-charts` loop, on hand-built results (a mutation audit of
studio/charts.py found the feasible count, the target suffix, the knee / best / passed-on roles and the
stage loop unchecked)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import plotly.graph_objects as go
import pytest

import studio.charts as charts
from core.cli import main as clm
from core.optimize.problem import make_problem

CONFIG = """
name = "charts"
mechanism = "stephenson1"
seed = 1
n_samples = 36
preset = "stephenson1/X2"
[algorithm]
name = "nsga2"
pop_size = 8
[[stages]]
name = "subtask2"
n_gen = 1
[[stages]]
name = "subtask3"
n_gen = 1
"""


def result(**kw: object) -> SimpleNamespace:
    """Enough of a StageResult for the chart: 5 members, members 0, 2 and 3 feasible, a front of 0 and 2."""
    feasible = np.array([True, False, True, True, False])
    r = SimpleNamespace(
        mechanism=SimpleNamespace(name="six", title="Six-bar"), name="subtask2", status="complete", generation=3,
        n_gen=3,
        pop=5, feasible=feasible, cv=np.where(feasible, 0.0, 1.0), front=(0, 2), objectives=("a", "b"),
        F=np.array([[1.0, 4.0], [2.0, 2.0], [3.0, 1.0], [3.5, 3.5], [4.0, 0.5]]),
        shortlist=SimpleNamespace(knees=(2,), best=(0, 2)), picked=3)
    vars(r).update(kw)
    return r


def test_the_title_counts_feasible_members_and_the_front_and_names_the_target_only_when_there_is_one():
    r = result()
    assert charts.chart_title(r, "complete") == "Six-bar · subtask2 · complete · 3 feasible of 5 · front 2"
    assert charts.chart_title(r, "complete", "cycloid L=1") == (
        "Six-bar · subtask2 · complete · 3 feasible of 5 · front 2 · target cycloid L=1")
    none = result(feasible=np.zeros(5, dtype=bool))
    assert " 0 feasible of 5 " in charts.chart_title(none, "x")
    # The RTCLM's stages measure both modes: "RTCLM, primary mode (...)" read wrong over the auxiliary-mode stage.
    rt = result(mechanism=SimpleNamespace(name="rtclm_primary", title="RTCLM, primary mode (x)"), name="rtclm2")
    assert charts.chart_title(rt, "complete").startswith("RTCLM · rtclm2 · complete")


def traces(fig: go.Figure) -> dict[str, list[int]]:
    return {t.name: list(t.customdata) for t in fig.data}


def test_the_stage_chart_marks_its_knees_its_best_members_and_the_member_passed_on():
    fig = charts.result_figure(result(), {"a": "alpha (mm)"}, "cycloid L=1")
    got = traces(fig)
    assert got["knees"] == [2]  # K1
    assert got["best"] == [0]  # best a; best b is the knee already
    assert got["passed on"] == [3]
    assert got["Pareto front"] == [0, 2] and got["infeasible"] == [1, 4]
    assert fig.layout.xaxis.title.text == "alpha (mm)" and fig.layout.yaxis.title.text == "b"
    assert fig.layout.title.text.endswith("· 3 feasible of 5 · front 2 · target cycloid L=1")


def test_a_three_objective_stage_with_flat_objectives_is_drawn_on_their_projection():
    """Rehearsal 3: clm-charts drew subtask 1 (f2 = f3 = 0 for every member) as one clipped diamond in an empty 3-D
    box, where the studio opens the projection; the PNG now draws f1 against f2 and says which are flat."""
    F = np.array([[4.1, 0.0, 0.0], [3.9, 0.0, 0.0], [4.4, 0.0, 0.0], [4.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    fig = charts.result_figure(result(F=F, objectives=("f1", "f2", "f3"), shortlist=SimpleNamespace(knees=(1,),
                                                                                                     best=(1, 0, 0))))
    assert not any(t.type == "scatter3d" for t in fig.data) and fig.layout.yaxis.title.text == "f2"
    assert fig.layout.title.text.endswith(" · f2 = 0 and f3 = 0 for every member")
    F[:, 1] = np.arange(5.0)
    fig = charts.result_figure(result(F=F, objectives=("f1", "f2", "f3"), shortlist=SimpleNamespace(knees=(1,),
                                                                                                     best=(1, 0, 0))))
    assert fig.layout.title.text.endswith("f3 = 0 for every member") and fig.layout.yaxis.title.text == "f2"
    F[:, 2] = -np.arange(5.0)
    fig = charts.result_figure(result(F=F, objectives=("f1", "f2", "f3"), shortlist=SimpleNamespace(knees=(1,),
                                                                                                     best=(1, 0, 0))))
    assert any(t.type == "scatter3d" for t in fig.data)  # all three vary: the 3-D cloud


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("charts") / "run"
    cfg = out.parent / "c.toml"
    cfg.write_text(CONFIG)
    assert clm(["design", str(cfg), "--out", str(out), "--quiet"]) == 0
    return out


def drawn(monkeypatch: pytest.MonkeyPatch) -> list[go.Figure]:
    """Capture the figures clm-charts would draw (no kaleido: the PNG is the figure's job, not the loop's)."""
    figs: list[go.Figure] = []

    def fake_png(fig: go.Figure, width: int = 0, height: int = 0) -> bytes:
        figs.append(fig)
        return b"png"

    monkeypatch.setattr(charts, "png", fake_png)
    return figs


def test_clm_charts_titles_each_chart_with_its_stage_target_and_axis_labels(run_dir, monkeypatch, capsys):
    figs = drawn(monkeypatch)
    written = charts.run_charts(run_dir)
    assert [p.name for p in written] == ["pareto-0_subtask2.png", "pareto-1_subtask3.png"]
    for fig, stage in zip(figs, ("subtask2", "subtask3"), strict=True):
        spec = make_problem(stage)
        assert fig.layout.xaxis.title.text == spec.labels[spec.objectives[0]] != spec.objectives[0]
        assert fig.layout.yaxis.title.text == spec.labels[spec.objectives[1]]
        assert f" · {stage} · " in fig.layout.title.text
        assert fig.layout.title.text.endswith(" · target cycloid L=300 mm, H=100 mm, T=2 s")
        # Each title line fits the 1000 px PNG (a long one, as an RTCLM stage's unmet constraints, ran off it).
        assert all(len(line) <= charts.TITLE_CHARS for line in fig.layout.title.text.split("<br>"))


def test_clm_charts_skips_a_stage_without_a_result_and_draws_the_ones_after_it(run_dir, monkeypatch, tmp_path):
    data = json.loads((run_dir / "result.json").read_text())
    data["pipeline"]["results"][0] = None  # the first stage never ran (or its result was lost)
    run = tmp_path / "run"
    run.mkdir()
    (run / "result.json").write_text(json.dumps(data))
    figs = drawn(monkeypatch)
    assert [p.name for p in charts.run_charts(run)] == ["pareto-1_subtask3.png"]
    assert (run / "pareto-1_subtask3.png").read_bytes() == b"png" and len(figs) == 1


def test_a_runs_final_pick_is_a_design_for_evaluate_simulate_and_export(run_dir, tmp_path, capsys):
    # A designer's next step after clm design: "unknown design key 'format'" and a design JSON written by hand.
    from core.optimize.pipeline import Pipeline

    data = json.loads((run_dir / "result.json").read_text())
    last = [r for r in Pipeline.from_dict(data["pipeline"]).lineage if r.picked is not None][-1]
    assert clm(["evaluate", "--design", str(run_dir / "result.json"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)
    assert clm(["simulate", "--design", str(run_dir), "--json"]) == 0  # the run's folder works too
    sim = json.loads(capsys.readouterr().out)
    assert sim["mechanism"] == last.mechanism.name
    np.testing.assert_allclose([sim["params"][n] for n in last.mechanism.param_names], last.X[last.picked])
    assert clm(["export", "--design", str(run_dir), "--svg", str(tmp_path / "pick.svg")]) == 0
    assert (tmp_path / "pick.svg").read_text().startswith("<svg")
    # A folder that holds no run: one line, exit 2.
    assert clm(["evaluate", "--design", str(tmp_path)]) == 2
    assert "result.json" in capsys.readouterr().err


def test_the_studio_keeps_one_png_browser_and_stops_it_on_close():
    # Each PNG started its own chromium (7-8 s for the studio's chart here); the studio keeps one between them.
    fig = go.Figure(go.Scatter(x=[1.0, 2.0, 3.0], y=[3.0, 1.0, 2.0]))
    try:
        first = charts.png(fig, 300, 200, keep=True)
        assert charts._kaleido_kept
        again = charts.png(fig, 300, 200, keep=True)
        assert first[:8] == again[:8] == b"\x89PNG\r\n\x1a\n"
    finally:
        charts.stop_png_browser()
    assert not charts._kaleido_kept
    assert charts.png(fig, 300, 200)[:4] == b"\x89PNG"  # and without it, as clm-charts draws
    # kaleido's channel logs a traceback for a message it ignores: not on the user's stderr (its critical ones are)
    import logging

    import choreographer.channels.pipe as channel

    pipe = channel._logger
    said = logging.LogRecord("choreographer.channels.pipe", logging.ERROR, "", 0, "JSONError decoding message. "
                             "Ignoring", None, None)
    assert not pipe.filter(said) and pipe.filter(logging.LogRecord("x", logging.CRITICAL, "", 0, "other", None, None))


def test_clm_charts_stops_quietly_when_its_reader_goes_and_words_a_refused_file(run_dir, monkeypatch, capsys):
    # QA (session 36): 'clm-charts run | head' ended in a BrokenPipeError traceback and exit 1, and a read-only run
    # folder in "[Errno 13] Permission denied: '...'".
    drawn(monkeypatch)

    class Gone:
        def write(self, text: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self) -> None:
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self) -> int:
            return fd

    import os
    import sys

    fd = os.dup(1)
    try:
        monkeypatch.setattr(sys, "stdout", Gone())
        assert charts.main([str(run_dir)]) == 141
    finally:
        os.close(fd)
    assert (run_dir / "pareto-0_subtask2.png").read_bytes() == b"png"  # the charts are written all the same

    def refused(path, data):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(charts, "atomic_write", refused)
    monkeypatch.setattr(sys, "stdout", sys.__stdout__)
    assert charts.main([str(run_dir)]) == 2
    assert capsys.readouterr().err == f"clm-charts: error: Permission denied: {run_dir / 'pareto-0_subtask2.png'}\n"
