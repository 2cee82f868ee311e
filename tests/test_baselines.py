"""Baselines (paper §3.4.3-3.4.4): DP error, DP+SQP, DP+GA, DP+GA+SQP run and report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from core.analysis.targets import compound_cycloid
from core.kinematics.design import Design
from core.kinematics.mechanisms import get as get_mechanism
from core.kinematics.presets import get
from core.optimize.baselines import (
    BaselineResult,
    BaselineSettings,
    dp_error,
    random_feasible_start,
    run_baseline,
    sqp,
)
from core.optimize.result import dumps

TINY = BaselineSettings(n_points=12, pop_size=16, n_gen=4, maxiter=15, n_samples=72, backend="numpy")


def test_dp_error_is_the_mean_squared_distance_at_the_discrete_points() -> None:
    x3 = get("stephenson1/X3").design()
    err, viol = dp_error(x3, n_points=12, n_samples=72, backend="numpy")
    pts = x3.solve(72, joints=False, backend="numpy").point[0, ::6]
    tgt, _ = compound_cycloid(12)
    assert err[0] == pytest.approx(((pts - tgt) ** 2).sum(-1).mean(), rel=1e-12)
    assert viol[0] == 0.0
    with pytest.raises(ValueError, match="must divide"):
        dp_error(x3, n_points=7, n_samples=72)


def test_unassemblable_designs_have_no_dp_error_and_a_positive_violation() -> None:
    x3 = get("stephenson1/X3").design()
    bad = x3.params.copy()
    bad[0, 4] = 400.0
    err, viol = dp_error(Design(x3.mechanism, bad, x3.output), n_points=12, n_samples=72, backend="numpy")
    assert np.isnan(err[0]) and viol[0] > 0.0


def test_random_start_assembles_and_depends_only_on_the_seed() -> None:
    m, out = get_mechanism("stephenson1"), get("stephenson1/X0").output
    a = random_feasible_start(m, out, np.random.default_rng(4), TINY)
    b = random_feasible_start(m, out, np.random.default_rng(4), TINY)
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(dp_error(Design(m, a, out), n_points=12, n_samples=72)[0][0])
    assert ((a >= m.lower) & (a <= m.upper)).all()


def test_sqp_does_not_worsen_a_feasible_start() -> None:
    x0 = get("stephenson1/X0").design()
    x, info = sqp(x0.mechanism, x0.output, x0.params[0], TINY)
    before = dp_error(x0, n_points=12, n_samples=72)[0][0]
    after, viol = dp_error(Design(x0.mechanism, x, x0.output), n_points=12, n_samples=72)
    assert viol[0] == 0.0
    assert after[0] <= before + 1e-9
    assert info["nit"] >= 1


def test_the_sqp_batch_keeps_the_best_assembling_point_and_its_constraint_holds_only_where_it_assembles() -> None:
    from core.optimize.baselines import _Batch, keeps_best

    x0, x3 = get("stephenson1/X0").design(), get("stephenson1/X3").design()
    b = _Batch(x3.mechanism, x3.output, TINY)
    u = {k: (d.params[0] - b.lo) / b.span for k, d in (("x0", x0), ("x3", x3))}
    bad = x3.params[0].copy()
    bad[4] = 400.0  # r1 too long: does not assemble
    u["bad"] = (bad - b.lo) / b.span
    err = {k: dp_error(d, n_points=12, n_samples=72, backend="numpy")[0][0] for k, d in (("x0", x0), ("x3", x3))}
    assert err["x3"] < err["x0"]
    f, _, c, _ = b(u["x3"])
    assert f == pytest.approx(err["x3"]) and c == 0.0  # SLSQP's "ineq": -violation >= 0 iff it assembles
    assert b(u["bad"])[2] < 0.0
    b(u["x0"])
    assert b.best is not None and b.best[0] == pytest.approx(err["x3"])  # the smallest error seen, not the last
    w = np.zeros(3)
    assert keeps_best((1.0, w), 2.0, 0.0) and not keeps_best((3.0, w), 2.0, 0.0)
    assert keeps_best((3.0, w), 2.0, -0.5) and not keeps_best(None, 2.0, -0.5)  # the final point does not assemble


def test_sqp_from_a_random_start_moves_far_downhill() -> None:
    # A random start's DP error is ~1e5-1e6 mm^2: unscaled, SLSQP stopped on its start after 5 iterations and
    # DP+SQP reported the start itself (MSE ~1 m) as its result.
    x0 = get("stephenson1/X0").design()
    for seed in (1, 4):
        r = run_baseline("dp_sqp", x0.mechanism, x0.output, TINY, seed=seed)
        start = dp_error(Design(x0.mechanism, r.start, x0.output), n_points=12, n_samples=72)[0][0]
        assert start > 1e5 and r.dp < 0.05 * start and r.metrics["violation"] == 0.0


@pytest.mark.parametrize("method", ["dp_sqp", "dp_ga", "dp_ga_sqp"])
def test_each_baseline_runs_reports_and_round_trips(method: str) -> None:
    x0 = get("stephenson1/X0").design()
    r = run_baseline(method, x0.mechanism, x0.output, TINY, seed=2)
    assert r.status == "complete" and r.time > 0.0
    assert set(r.metrics) >= {"mse", "S", "I", "h_s", "violation"}
    assert np.isfinite(r.dp)
    if method != "dp_sqp":
        assert r.details["ga_generations"] == TINY.n_gen
    back = BaselineResult.from_dict(json.loads(dumps(r.to_dict())))
    np.testing.assert_array_equal(back.params, r.params)
    assert back.metrics == r.metrics and back.dp == r.dp and back.details == r.details


def test_same_seed_same_baseline() -> None:
    x0 = get("stephenson1/X0").design()
    a = run_baseline("dp_ga", x0.mechanism, x0.output, TINY, seed=9)
    b = run_baseline("dp_ga", x0.mechanism, x0.output, TINY, seed=9)
    np.testing.assert_array_equal(a.params, b.params)


def test_unknown_method_is_refused() -> None:
    x0 = get("stephenson1/X0").design()
    with pytest.raises(ValueError, match="unknown baseline"):
        run_baseline("dp_pso", x0.mechanism, x0.output, TINY)
