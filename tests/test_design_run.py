"""Running a design: spec §6 boxes around each pick, constraints of the picks, determinism, JSON, cancel."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from core.formats.config import parse_config
from core.optimize import Pipeline, search_box
from core.optimize.lineage import choose, next_feasible
from core.optimize.objectives import shape_metrics
from core.optimize.result import StageResult, dumps
from core.optimize.run import DesignRun, run_design

CONFIG = {
    "name": "tiny",
    "preset": "stephenson1/X0",
    "seed": 3,
    "n_samples": 72,
    "algorithm": {"name": "nsga2", "pop_size": 16},
    "stages": [
        {"name": "subtask1", "box": "subtask1", "n_gen": 6, "pick": "best:f1"},
        {"name": "subtask2", "box": "subtask2", "n_gen": 3, "pick": "knee",
         "options": {"f1_max": "start+1.0", "place": "extent"}},
        {"name": "subtask3", "box": "subtask3", "n_gen": 3, "pick": "best:I",
         "options": {"f1_max": "start+0.2", "h_s_max": "start*1.05", "I_max": "start+5"}},
    ],
}


@pytest.fixture(scope="module")
def run() -> DesignRun:
    return run_design(parse_config(CONFIG))


def test_each_stage_searches_the_spec_box_around_the_previous_pick(run: DesignRun) -> None:
    res = run.results
    assert [r.status for r in res] == ["complete"] * 3
    start = run.config.start.params[0]
    expect = search_box(run.config.mechanism, start, 0.2, 20.0)
    np.testing.assert_array_equal(res[0].box.lower, expect.lower)
    for k, (s, d) in ((1, (0.1, 10.0)), (2, (0.05, 5.0))):
        prev = res[k - 1]
        assert res[k].parent_pick == prev.picked
        box = search_box(run.config.mechanism, prev.X[prev.picked], s, d)
        np.testing.assert_array_equal(res[k].box.lower, box.lower)
        np.testing.assert_array_equal(res[k].box.upper, box.upper)
        assert res[k].box.contains(res[k].X).all()


def test_relative_limits_are_resolved_against_the_stage_start(run: DesignRun) -> None:
    s1, s2, s3 = run.results
    f1_start = s1.metrics["f1"][s1.picked]
    opts2 = s2.settings["problem"]["options"]
    assert opts2["f1_max"] == pytest.approx(f1_start + 1.0)
    opts3 = s3.settings["problem"]["options"]
    assert opts3["h_s_max"] == pytest.approx(1.05 * s2.metrics["h_s"][s2.picked])
    assert opts3["I_max"] == pytest.approx(s2.metrics["I"][s2.picked] + 5.0)


def test_picks_satisfy_their_stage_constraints(run: DesignRun) -> None:
    for r in run.results:
        i = r.picked
        assert r.feasible[i], r.name
        assert (r.G[i] <= 0.0).all()


def test_the_pick_prefers_members_feasible_for_the_next_stage(run: DesignRun) -> None:
    s1 = run.results[0]
    nxt = parse_config(CONFIG).stages[1]
    from core.optimize.design_config import placeholder
    from core.optimize.problem import make_problem

    mask = next_feasible(s1, make_problem(nxt.problem, **placeholder(nxt.options)))
    assert mask[s1.picked]
    assert choose(s1, "best:f1", mask) == s1.picked


def test_subtask1_lowers_the_shape_error_from_x0(run: DesignRun) -> None:
    s1 = run.results[0]
    before = shape_metrics(run.config.start, n_samples=72)["f1"][0]
    assert s1.metrics["f1"][s1.picked] < before - 1.0


def test_same_seed_gives_the_same_picks(run: DesignRun) -> None:
    again = run_design(parse_config(CONFIG))
    assert [r.picked for r in again.results] == [r.picked for r in run.results]
    for a, b in zip(again.results, run.results, strict=True):
        np.testing.assert_array_equal(a.X, b.X)


def test_json_round_trip_is_lossless(run: DesignRun) -> None:
    d = json.loads(dumps(run.to_dict()))
    assert d["format"] == "clm-design" and d["rows"][0]["stage"] == "subtask3"
    pipe = Pipeline.from_dict(d["pipeline"])
    for a, b in zip(pipe.results, run.results, strict=True):
        assert a is not None
        for name in ("X", "F", "G", "cv"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert a.picked == b.picked and a.shortlist == b.shortlist and a.settings == b.settings
        for k in b.metrics:
            np.testing.assert_array_equal(a.metrics[k], b.metrics[k])
    assert dumps(pipe.to_dict()["results"]) == dumps(run.pipeline.to_dict()["results"])  # type: ignore[union-attr]


def test_cancellation_mid_stage_leaves_a_loadable_partial_result() -> None:
    cancel = threading.Event()

    def cb(p) -> None:  # type: ignore[no-untyped-def]
        if p.stage == "subtask2" and p.generation == 2:
            cancel.set()

    out = run_design(parse_config(CONFIG), callback=cb, cancel=cancel)
    assert out.status == "cancelled"
    res = out.results
    assert [r.status for r in res] == ["complete", "cancelled"] and res[1].generation == 2
    back = json.loads(dumps(out.to_dict()))
    loaded = StageResult.from_dict(back["pipeline"]["results"][1])
    np.testing.assert_array_equal(loaded.X, res[1].X)
    assert back["pipeline"]["results"][2] is None
    # The partial stage can still hand a pick to a rerun.
    assert loaded.choose("knee") >= 0
    # It has its rule's pick, as the studio's Stop gives one (lab rehearsal: nothing could evaluate or export a run
    # stopped with Ctrl-C), and the run ended there all the same.
    assert res[1].picked is not None and loaded.picked == res[1].picked
    assert out.final() is not None and out.final()[0] is res[1]


def test_single_level_reports_the_three_extremes() -> None:
    cfg = {"name": "sl", "method": "single_level", "preset": "stephenson1/X0", "n_samples": 72, "seed": 2,
           "algorithm": {"pop_size": 12},
           "stages": [{"name": "single_level", "problem": "single_level", "n_gen": 3, "pick": "best:f1"}]}
    out = run_design(parse_config(cfg))
    rows = out.rows()
    r = out.results[0]
    assert r.feasible.any()  # the seeded start (X0) is feasible
    assert r.objectives == ("f1", "f2", "f3", "h_s", "I")
    assert [row["label"].split("smallest ")[1] for row in rows] == ["f1", "h_s", "I"]
    assert rows[0]["mse"] == pytest.approx(np.min(r.metrics["mse"][r.feasible]))
    assert rows[2]["I"] == pytest.approx(np.min(r.metrics["I"][r.feasible]))


@pytest.mark.parametrize(("seed", "limits"), [(0, [0.2, 0.2]), (1, [5.0, 0.02])])
def test_a_stage_that_stops_early_picks_among_the_members_that_met_its_thresholds(seed: int,
                                                                                   limits: list[float]) -> None:
    # The analytic "bowl" problem: f1 = mean((u - a)^2), f2 = mean((u + a)^2) with u in [-1, 1]. With (5, 0.02) the
    # best f1 meets the loose f1 limit but not the tight f2 one: it must not be the pick.
    cfg = {"name": "bowl", "mechanism": "stephenson1", "seed": seed, "algorithm": {"pop_size": 20},
           "stages": [{"name": "bowl", "problem": "bowl", "n_gen": 30, "pick": "best:f1", "stop_below": limits}]}
    out = run_design(parse_config(cfg))
    r = out.results[0]
    assert r.status == "stopped" and r.generation < 30
    met = r.feasible & (r.F <= np.array(limits)).all(axis=1)
    assert met[r.picked]
    assert r.F[r.picked, 0] == np.min(r.F[met, 0])
