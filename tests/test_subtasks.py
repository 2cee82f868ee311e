"""Subtask problems 1-3 (paper §3.2): Eq. 20-23 as objectives and continuous constraints."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis.evaluate import evaluate_paths
from core.analysis.targets import compound_cycloid
from core.kinematics.design import Design
from core.kinematics.presets import PAPER_PANTOGRAPH, get
from core.optimize import make_problem
from core.optimize.objectives import EQ22, EQ23, load_target, metrics_of, shape_metrics, tiered, width_penalty
from core.optimize.subtasks import parse_relative, resolve_limits

N = 120  # samples: enough for the metrics, quick


def test_width_penalty_is_quadratic_in_the_band_and_five_times_steeper_far_outside() -> None:
    w = np.array([300.0, 295.0, 310.0, 290.0, 320.0, 250.0])
    # e^2 inside the +-10 band; e^2 + 4 (|e| - 10)^2 outside.
    np.testing.assert_allclose(width_penalty(w, 300.0), [0.0, 25.0, 100.0, 100.0, 400 + 4 * 100, 2500 + 4 * 1600])
    far = width_penalty(np.array([1300.0]), 300.0)[0]
    assert far == pytest.approx(5.0 * 1000.0**2, rel=0.03)
    assert np.isnan(width_penalty(np.array([np.nan]), 300.0)[0])


@given(st.floats(-200.0, 200.0), st.floats(-200.0, 200.0))
@settings(max_examples=60, deadline=None)
def test_width_penalty_grows_with_the_distance_to_the_nominal_width(a: float, b: float) -> None:
    pa, pb = width_penalty(np.array([300.0 + a, 300.0 + b]), 300.0)
    if abs(a) < abs(b):
        assert pa <= pb
    assert pa >= 0.0


def test_the_target_itself_scores_zero_on_every_subtask_objective() -> None:
    # The compound cycloid as a path: f1 = f2 = f3 = 0, flat stance (h_s = 0) and a tangential landing (I = 0).
    pts, d = compound_cycloid(360)
    leg = PAPER_PANTOGRAPH.apply(pts)
    ev = evaluate_paths(pts, leg, PAPER_PANTOGRAPH.apply_derivative(d))
    m = metrics_of(ev, load_target("cycloid"))
    for k in ("f1", "f2", "f3", "h_s", "I", "violation"):
        assert m[k][0] == pytest.approx(0.0, abs=1e-6), k


def test_a_scaled_cycloid_pays_the_width_and_depth_penalties() -> None:
    pts, d = compound_cycloid(360, L=306.0, H=97.0)
    ev = evaluate_paths(pts, PAPER_PANTOGRAPH.apply(pts), PAPER_PANTOGRAPH.apply_derivative(d))
    m = metrics_of(ev, load_target("cycloid"))
    assert m["f2"][0] == pytest.approx(36.0, rel=1e-6)  # (306 - 300)^2
    assert m["f3"][0] == pytest.approx(9.0, rel=1e-6)  # (-97 + 100)^2


def test_subtask_constraints_are_eq22_and_eq23_limits_on_the_metrics() -> None:
    x2 = get("stephenson1/X2").design()
    s2 = make_problem("subtask2", n_samples=N)
    s3 = make_problem("subtask3", n_samples=N)
    assert s2.objectives == s3.objectives == ("h_s", "I")
    assert [(c.metric, c.upper) for c in s2.constraints] == [("violation", 0.0)] + list(EQ22.items())
    assert [(c.metric, c.upper) for c in s3.constraints] == [("violation", 0.0)] + list(EQ22.items()) + list(
        EQ23.items())
    m = s3.evaluate_metrics(x2)
    F, G = s3.columns(m)
    np.testing.assert_array_equal(F[0], [m["h_s"][0], m["I"][0]])
    np.testing.assert_allclose(G[0, 1:], [m["f1"][0] - 6.0, m["f2"][0] - 5.0, m["f3"][0] - 5.0,
                                          m["h_s"][0] - 6.5, m["I"][0] - 20.0])


def test_eq30_option_adds_order_and_angle_constraints() -> None:
    p = make_problem("subtask1", n_samples=N, eq30=True)
    assert [c.metric for c in p.constraints] == ["violation", "order", "theta1_margin", "theta2_margin"]
    assert all(c.upper == 0.0 and c.lower is None for c in p.constraints)  # each g <= 0 is satisfied
    m = p.evaluate_metrics(get("stephenson1/X3").design())
    assert m["theta1_margin"][0] == pytest.approx(np.deg2rad(15.0) - m["theta1"][0])
    assert m["theta2_margin"][0] == pytest.approx(np.deg2rad(15.0) - m["theta2"][0])
    assert m["theta1"][0] != pytest.approx(m["theta2"][0])  # (so the two margins are told apart)


def test_the_assembly_violation_is_tiered_above_any_constraint_and_unreadable_paths_above_that() -> None:
    v = tiered(np.array([0.0, 1.5, np.nan, np.inf, -0.0]))
    np.testing.assert_array_equal(v, [0.0, 1001.5, 2000.0, 2000.0, 0.0])


def test_unassemblable_members_get_nan_metrics_and_a_positive_violation() -> None:
    x3 = get("stephenson1/X3").design()
    bad = x3.params.copy()
    bad[0, 4] = 400.0  # crank r1 far too long for the loop
    m = shape_metrics(Design(x3.mechanism, np.vstack([x3.params, bad]), x3.output), n_samples=N)
    assert m["violation"][0] == 0.0 and m["violation"][1] > 0.0
    assert np.isfinite(m["f1"][0]) and np.isnan(m["f1"][1])


def test_batch_equals_per_design_loop() -> None:
    names = ("stephenson1/X0", "stephenson1/X1", "stephenson1/X3", "stephenson1/DP-SQP")
    designs = [get(n).design() for n in names]
    batch = shape_metrics(Design(designs[0].mechanism, np.vstack([d.params for d in designs]), designs[0].output),
                          n_samples=N)
    for i, d in enumerate(designs):
        one = shape_metrics(d, n_samples=N)
        for k, v in one.items():
            np.testing.assert_allclose(batch[k][i], v[0], rtol=1e-12, atol=1e-12, err_msg=k)


def test_relative_limits_resolve_against_the_start() -> None:
    start = {"f1": np.array([3.0]), "h_s": np.array([6.0]), "I": np.array([10.0])}
    out = resolve_limits({"f1_max": "start+0.5", "h_s_max": "start*1.1", "I_max": 20.0, "n_samples": 72}, start)
    assert out == {"f1_max": 3.5, "h_s_max": pytest.approx(6.6), "I_max": 20.0, "n_samples": 72}
    assert parse_relative(" start * 1.05 ") == ("*", 1.05)
    for bad in ("start-1", "start*0.9", "start+", "begin+1", "start+nan"):
        with pytest.raises(ValueError, match="relative limit"):
            parse_relative(bad)
    with pytest.raises(ValueError, match="no finite"):
        resolve_limits({"f1_max": "start+1"}, {"f1": np.array([np.nan])})
    # a list of limits: the loosest holds (an absolute floor with a relative allowance)
    assert resolve_limits({"f1_max": [4.0, "start+0.05"]}, {"f1": np.array([5.0])})["f1_max"] == 5.05
    assert resolve_limits({"f1_max": [4.0, "start+0.05"]}, {"f1": np.array([3.0])})["f1_max"] == 4.0


def test_a_csv_target_with_times_gives_the_formula_targets_metrics(tmp_path) -> None:  # type: ignore[no-untyped-def]
    pts, _ = compound_cycloid(360)
    t = np.arange(360) * (2.0 / 360)
    f = tmp_path / "cycloid.csv"
    rows = [f"{float(x)!r},{float(y)!r},{float(tt)!r}" for (x, y), tt in zip(pts, t, strict=True)]
    f.write_text("x,y,t\n" + "\n".join(rows) + f"\n{float(pts[0, 0])!r},{float(pts[0, 1])!r},2.0\n")
    x3 = get("stephenson1/X3").design()
    by_csv = shape_metrics(x3, str(f), n_samples=N)
    by_formula = shape_metrics(x3, "cycloid", n_samples=N)
    for k in ("f1", "f2", "f3", "h_s", "I"):
        assert by_csv[k][0] == pytest.approx(by_formula[k][0], rel=1e-9, abs=1e-9), k


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_crank_margin_is_a_metric_a_pick_can_require(backend: str) -> None:
    # Picks 0.002 mm from a dead point (transmission angles of 179.9 deg) could not be refused: no metric said so.
    from core.formats.config import parse_config

    d = get("stephenson1/X3").design()
    P = np.repeat(d.params, 3, axis=0)
    P[1:, d.mechanism.param_names.index("r1")] *= (1.02, 1.2)  # a longer crank: nearer its dead point, or past it
    design = Design(d.mechanism, P, d.output)
    m = shape_metrics(design, backend=backend)
    want = design.solve(360, joints=False, backend="numpy").crank_margin
    np.testing.assert_allclose(m["crank_margin"], want, rtol=1e-9)
    assert m["crank_margin"][0] > m["crank_margin"][1]
    assert "crank_margin" in make_problem("subtask2").metric_names  # a config may name it
    cfg = parse_config({"name": "x", "preset": "stephenson1/X0", "algorithm": {"name": "nsga2", "pop_size": 12},
                        "stages": [{"name": "subtask1", "n_gen": 2, "pick": "best:f1",
                                    "pick_where": {"crank_margin_min": 1.0}}]})
    assert cfg.stages[0].pick_where[0].metric == "crank_margin" and cfg.stages[0].pick_where[0].lower == 1.0
