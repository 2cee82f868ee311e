"""Designs near a dead point are said so (rehearsal 4: a predesign pick at a worst transmission angle of 0.3 deg
read "meets predesign's constraints" in green with every row black), and a run can keep off them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core.kinematics.solver import MU_DEAD, MU_USUAL
from core.optimize.problem import make_problem
from studio.chains import RunSettings, build_problem
from studio.metrics import metrics_html, motion_warnings
from studio.state import Session
from studio.tables import dead_point_html
from studio.target import TargetSpec


def test_motion_warnings_by_hand():
    assert motion_warnings(60.0, 5.0, 5.0, 300.0) == {}
    assert motion_warnings(21.4, 3.24, 16.3, 300.0)["mu_min"][1] is False  # the paper's X3: weak, no dead point
    assert set(motion_warnings(0.3, 0.0, 0.0, 120.0)) == {"mu_min", "crank_margin", "dyad_margin"}
    assert motion_warnings(0.3, 0.0, 0.0, 120.0)["mu_min"][1] is True
    assert motion_warnings(MU_DEAD, 2.0, 2.0, 100.0)["mu_min"][1] is False  # on the line: not under it
    assert "mu_min" not in motion_warnings(MU_USUAL, 2.0, 2.0, 100.0)
    assert motion_warnings(float("nan"), float("nan"), float("nan"), float("nan")) == {}  # does not assemble


def test_the_metrics_table_marks_a_weak_angle_amber_and_a_dead_point_red_with_a_line_above():
    rows = Session.default().view.rows  # the paper's X3: mu 21.4 deg
    html = metrics_html(rows)
    assert 'data-key="mu_min" data-warn="weak"' in html and "clm-dead-point" not in html
    assert html.count("data-warn=") == 1  # its margins are 1 % of the stride and more
    dead = tuple(dataclasses.replace(r, value=0.3, warn="close to a dead point", severe=True) if r.key == "mu_min"
                 else r for r in rows)
    html = metrics_html(dead)
    assert html.startswith('<div class="clm-dead-point"') and "Min transmission angle μ 0.3 deg" in html
    assert 'data-key="mu_min" data-warn="severe" style="color:#b91c1c"' in html


def _result(angle: float):
    from tests.test_optimize_results_json import small_result

    r = small_result()
    return dataclasses.replace(r, metrics={**r.metrics, "transmission": np.full(r.pop, angle)})


def test_the_pick_panel_says_a_member_passes_close_to_a_dead_point():
    assert "passes close to a dead point: worst transmission angle 0.3 deg" in dead_point_html(_result(0.3), 0)
    assert dead_point_html(_result(21.4), 0) == ""
    assert dead_point_html(_result(float("nan")), 0) == ""


def test_the_predesign_takes_a_transmission_limit_and_the_studio_passes_it_on():
    p = make_problem("predesign", transmission_min=40.0)
    assert any(c.metric == "transmission" and c.lower == 40.0 for c in p.constraints)
    assert not any(c.metric == "transmission" for c in make_problem("predesign").constraints)  # the paper's
    built = build_problem("subtask2", TargetSpec(), 35)
    assert any(c.metric == "transmission" and c.lower == 35.0 for c in built.constraints)
    with pytest.raises(ValueError, match="takes no limit on the transmission angle"):
        build_problem("dp", TargetSpec(), 30)
    with pytest.raises(ValueError, match="min transmission angle"):
        RunSettings("predesign", transmission_min=90)
    s = RunSettings("predesign", transmission_min=40)
    assert RunSettings.from_dict(s.to_dict()) == s
    assert "transmission_min" not in RunSettings("predesign").to_dict()  # sessions saved before read the same


def test_a_run_with_a_limit_keeps_every_feasible_member_off_dead_points():
    import threading

    from studio.chains import chain_for, find
    from studio.runner import Runner

    session = Session.default()
    session.study.settings["subtask1"] = RunSettings("subtask1", pop_size=16, n_gen=3, seed=2, transmission_min=30)
    chain = chain_for(session.view.design.mechanism)
    done = threading.Event()
    runner = Runner(session.lock, lambda: session.study, lambda p: None, done.set)
    stage, view = find(chain, "subtask1"), session.view
    runner.start(lambda st: st.plan(stage, st.settings_for(stage), view.design, view.target, False, chain))
    assert done.wait(60)
    runner.join(10)
    r = session.study.result("subtask1")
    assert r is not None and r.feasible.any()
    assert (r.metrics["transmission"][r.feasible] >= 30.0).all()
    assert (r.metrics["transmission"] < 30.0).any()  # the limit did exclude members
    # A restored branch sets the Stages panel from its results: the limit comes back with them (rehearsal 5: it
    # came back 0, and Run went on without it).
    from studio.study import ran_with

    assert ran_with(r) == RunSettings("subtask1", "nsga2", 16, 3, 2, 30)


def test_a_design_that_does_not_assemble_has_no_transmission_angle_to_show():
    """rtclm/case3 does not assemble: its angle read 0.0 deg, unmarked, beside a red 24.5 elsewhere (rehearsal 5)."""
    view = Session.default().load_preset("rtclm/case3")
    row = next(r for r in view.rows if r.key == "mu_min")
    assert row.text() == "-" and not row.warn and row.undefined  # "-" and why, not "NaN" (QA, session 38)
