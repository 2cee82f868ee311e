"""The worst transmission angle as a metric: closed form on a four-bar, backends and batch agree, picks and
subtasks can require it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from core.analysis.evaluate import evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms.fourbar import FOURBAR
from core.kinematics.presets import get
from core.kinematics.solver import worst_transmission
from core.optimize.objectives import shape_metrics
from core.optimize.problem import Constraint, make_problem

NAMES = FOURBAR.param_names


def fourbar(r1: float, r2: float, r3: float, r4: float) -> Design:
    base = dict(b=0.0, g=0.0, x_a=0.0, y_a=0.0, r1=r1, r2=r2, r3=r3, r4=r4, r5=60.0, r6=30.0)
    return Design(FOURBAR, np.array([[base[n] for n in NAMES]]))


def closed_form(a: float, b: float, c: float, d: float) -> float:
    """Crank a, coupler b, rocker c, ground d: the transmission angle mu at the coupler-rocker joint has
    cos mu = (b^2 + c^2 - BD^2) / (2 b c) with BD from d - a (crank along the ground) to d + a (crank opposite);
    the worst of min(mu, 180 - mu) is at one of those two ends (deg)."""
    ends = [math.degrees(math.acos((b * b + c * c - e * e) / (2 * b * c))) for e in (d - a, d + a)]
    return min(min(mu, 180.0 - mu) for mu in ends)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_crank_rocker_has_the_closed_form_worst_angle(backend: str) -> None:
    # 50 / 150 / 110 / 200: BD runs 150..250 mm, mu 68.49..147.73 deg, so the worst is 180 - 147.73 = 32.27 deg,
    # reached at theta = pi, a sample of every even count.
    ev = evaluate(fourbar(50.0, 150.0, 110.0, 200.0), 360, backend=backend)
    assert ev.transmission[0] == pytest.approx(closed_form(50.0, 150.0, 110.0, 200.0), abs=1e-9)
    assert ev.transmission[0] == pytest.approx(32.27, abs=0.01)


@settings(max_examples=25, deadline=None)
@given(st.floats(20.0, 60.0), st.floats(140.0, 200.0), st.floats(100.0, 160.0), st.floats(150.0, 220.0))
def test_any_grashof_crank_rocker_matches_the_closed_form(a: float, b: float, c: float, d: float) -> None:
    lengths = sorted((a, b, c, d))
    assume(lengths[0] == a and lengths[0] + lengths[3] < lengths[1] + lengths[2] - 1.0)  # a crank that turns fully
    ev = evaluate(fourbar(a, b, c, d), 360, backend="numpy")
    assert ev.transmission[0] == pytest.approx(closed_form(a, b, c, d), abs=1e-7)


def test_a_batch_agrees_with_each_design_alone_and_the_backends_agree() -> None:
    d = get("stephenson1/X3").design()
    P = np.repeat(d.params, 4, axis=0)
    P[1:, d.mechanism.param_names.index("r1")] *= (0.9, 1.05, 3.0)  # 3x: no assembly
    design = Design(d.mechanism, P, d.output)
    batch = evaluate(design, 360, backend="numba").transmission
    alone = [evaluate(Design(d.mechanism, P[i : i + 1], d.output), 360, backend="numpy").transmission[0]
             for i in range(4)]
    np.testing.assert_allclose(batch[:3], alone[:3], rtol=1e-12)
    assert np.isfinite(batch[:3]).all() and 0.0 < batch[:3].min() and batch[:3].max() <= 90.0
    sol = design.solve(360, backend="numpy")
    np.testing.assert_allclose(batch[:3], np.degrees(worst_transmission(sol.mu_min, sol.mu_max))[:3], rtol=1e-12)
    # The design that does not assemble has no angle (its dyad reaches 0 deg at the edge of where it closes, which
    # read as a measured dead point: the review of session 29), on both backends.
    assert sol.violation[3] > 0 and np.isnan(batch[3]) and np.isnan(alone[3])


def test_the_worst_angle_takes_both_ends_and_ignores_dyads_that_never_close() -> None:
    mu_min = np.array([[1.2, np.nan], [0.3, 1.0], [np.nan, np.nan]])
    mu_max = np.array([[2.5, np.nan], [1.6, 2.0], [np.nan, np.nan]])
    out = worst_transmission(mu_min, mu_max)
    assert out[0] == pytest.approx(math.pi - 2.5) and out[1] == 0.3 and np.isnan(out[2])


def test_picks_and_subtasks_can_require_it() -> None:
    from core.formats.config import parse_config

    m = shape_metrics(get("stephenson1/X3").design())
    assert m["transmission"][0] == pytest.approx(21.36, abs=0.01)  # the paper's X3: below the usual 40 deg
    for name in ("subtask1", "subtask2", "subtask3", "single_level"):
        assert "transmission" in make_problem(name).metric_names
        assert Constraint("transmission", lower=40.0) in make_problem(name, transmission_min=40.0).constraints
        assert not any(c.metric == "transmission" for c in make_problem(name).constraints)  # the paper's: none
    with pytest.raises(ValueError, match="transmission_min must be an angle in degrees in \\[0, 90\\)"):
        make_problem("subtask2", transmission_min=0.7 * 180)
    cfg = parse_config({"name": "x", "preset": "stephenson1/X0", "algorithm": {"name": "nsga2", "pop_size": 12},
                        "stages": [{"name": "subtask1", "n_gen": 2, "pick": "best:f1",
                                    "pick_where": {"transmission_min": 40.0},
                                    "options": {"transmission_min": 30.0}}]})
    assert cfg.stages[0].pick_where == (Constraint("transmission", lower=40.0),)
    spec = cfg.stages[0].problem_spec()
    assert Constraint("transmission", lower=30.0) in spec.constraints
    # The constraint's value is limit - angle: X3 (21.4 deg) misses 30 deg by 8.6.
    x3 = get("stephenson1/X3").design()
    assert spec.constraints[-1].value(shape_metrics(x3)["transmission"])[0] == pytest.approx(30.0 - 21.36, abs=0.01)


def test_clm_evaluate_prints_it_for_a_design_and_not_for_a_curve(tmp_path, capsys) -> None:
    from core.cli import main

    assert main(["evaluate", "--preset", "stephenson1/X3"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "worst transmission angle" in x)
    assert line.split()[3:5] == ["21.4", "deg"]
    pts = get("stephenson1/X3").design().solve(72, backend="numpy").point[0]
    (tmp_path / "c.csv").write_text("x,y\n" + "\n".join(f"{float(x)!r},{float(y)!r}" for x, y in pts))
    assert main(["evaluate", "--curve", str(tmp_path / "c.csv")]) == 0
    assert "transmission" not in capsys.readouterr().out
    assert main(["evaluate", "--preset", "stephenson1/X3", "--json"]) == 0
    assert '"transmission":21.35' in capsys.readouterr().out.replace(" ", "")


def test_best_transmission_takes_the_largest_angle_in_picks_and_chains() -> None:
    # Every best:<metric> kept the smallest value: best:transmission chose the design nearest a dead point.
    from core.optimize.multistart import rank_chains
    from core.optimize.result import best_metric

    values = np.array([60.0, 5.0, np.nan, 45.0])
    mask = np.array([True, True, True, True])
    assert best_metric(values, mask, "transmission") == 0 and best_metric(values, mask, "crank_margin") == 0
    assert best_metric(values, mask, "S") == 1  # the others: the smallest
    picks = [{"transmission": 60.0}, {"transmission": 5.0}]
    assert rank_chains(picks, [True, True], "best:transmission") == [0, 1]
    assert rank_chains([{"S": 2.0}, {"S": 1.0}], [True, True], "best:S") == [1, 0]


def test_the_rtclm_measures_each_modes_angle_and_can_require_it() -> None:
    # An RTCLM pick assembled with a 0-degree transmission angle in its auxiliary mode (an exploratory walk).
    from core.kinematics.mechanisms import get as mechanism
    from core.optimize.result import best_metric

    params = get("rtclm/case4").design().params
    m = make_problem("rtclm2").evaluate_metrics(Design(mechanism("rtclm_primary"), params))
    for suffix, mode in (("6", "rtclm_primary"), ("4", "rtclm_auxiliary")):
        want = evaluate(Design(mechanism(mode), params), 360, backend="numpy").transmission[0]
        assert m[f"transmission_{suffix}"][0] == pytest.approx(want, rel=1e-9)
    cons = make_problem("rtclm2", transmission_min=30.0).constraints
    assert Constraint("transmission_6", lower=30.0) in cons and Constraint("transmission_4", lower=30.0) in cons
    held = [c.metric for c in make_problem("rtclm1", transmission_min=30.0).constraints]
    assert "transmission_6" in held and "transmission_4" not in held  # subtask 1 holds the primary mode only
    assert not any(c.metric.startswith("transmission") for c in make_problem("rtclm2").constraints)
    with pytest.raises(ValueError, match="transmission_min must be an angle"):
        make_problem("rtclm1", transmission_min=-1.0)
    assert best_metric(np.array([10.0, 50.0]), np.array([True, True]), "transmission_4") == 1
