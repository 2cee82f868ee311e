"""Odd inputs never raise: NaN rows give NaN metrics, odd paths a positive, continuous violation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from core.analysis.evaluate import evaluate, evaluate_paths
from core.analysis.features import NO_ROOT_VIOLATION, feature_points
from core.analysis.metrics import order_violation
from core.kinematics.design import Design
from core.kinematics.presets import get

METRICS = ("l_s", "h_s", "S", "I", "theta1", "theta2", "width", "y_min", "step_length", "h_m", "h_bar", "psi2", "psi4",
           "mse")


def ellipse(n: int = 360, rx: float = 150.0, ry: float = 50.0, e: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Counter-clockwise ``x = rx cos, y = ry (sin + e sin 3 theta)`` and its derivative."""
    th = 2.0 * np.pi * np.arange(n) / n
    p = np.stack([rx * np.cos(th), ry * (np.sin(th) + e * np.sin(3 * th))], -1)
    d = np.stack([-rx * np.sin(th), ry * (np.cos(th) + 3 * e * np.cos(3 * th))], -1)
    return p, d


@pytest.mark.parametrize("kernel", [False, True])
def test_nan_rows_give_nan_metrics_and_a_violation(kernel: bool) -> None:
    p, d = ellipse()
    P = np.stack([p, p, p])
    D = np.stack([d, d, d])
    P[0] = np.nan  # unassemblable everywhere
    P[1, 17] = np.nan  # one unplaced sample
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ev = evaluate_paths(P, P, D, kernel=kernel)
    for k in METRICS:
        assert np.isnan(getattr(ev, k)[:2]).all(), k
        assert np.isfinite(getattr(ev, k)[2]), k
    assert np.all(ev.violation[:2] > 0) and ev.violation[2] == 0.0
    assert not ev.feasible[:2].any() and ev.feasible[2]
    assert np.isnan(ev.times[:2]).all()


def test_an_unassemblable_design_keeps_the_solver_violation() -> None:
    x3 = get("stephenson1/X3").design()
    p = np.repeat(x3.params, 2, axis=0)
    p[1, x3.mechanism.param_names.index("r2")] = 5.0  # link BC far too short to close
    ev = evaluate(Design(x3.mechanism, p, x3.output), backend="numpy")
    sol = Design(x3.mechanism, p[1:], x3.output).solve(360, joints=False, backend="numpy")
    assert ev.feasible[0] and not ev.feasible[1]
    assert ev.violation[1] == sol.violation[0] > 0.0
    assert np.isnan(ev.S[1]) and np.isnan(ev.mse[1])


def test_extra_landing_roots_cost_their_lobe_and_vanish_continuously() -> None:
    """y = ry sin t (1 + 3e - 4e sin^2 t): for e < -1/3 the landing equation has extra roots
    whose lobes shrink to nothing as e -> -1/3 (spec: odd path -> positive violation)."""
    viol = []
    for e in (-0.30, -1 / 3 + 1e-3, -0.34, -0.36, -0.40):
        p, d = ellipse(e=e)
        fp = feature_points(p, d)
        viol.append(fp.root_violation[0])
        assert fp.n_roots[0] == (2 if e > -1 / 3 else 6)
    assert viol[0] == 0.0 and viol[1] == 0.0
    assert 0.0 < viol[2] < viol[3] < viol[4]
    assert viol[2] < 0.5  # 0.007 past the threshold: a small defect, a small value


def dwell(n: int = 360, frac: float = 0.6, noise: float = 0.0) -> np.ndarray:
    """A foot flat on the ground for ``frac`` of the cycle (longer than T/2: f = 0 over an interval), then a
    cycloidal arch 60 mm high back; ``noise`` (mm) on its heights."""
    t = np.arange(n) / n
    s = np.clip((t - frac) / (1.0 - frac), 0.0, 1.0)
    x = np.where(t < frac, 300.0 * t / frac, 300.0 * (1.0 - s + np.sin(2.0 * np.pi * s) / (2.0 * np.pi)))
    y = np.where(t < frac, 0.0, 30.0 * (1.0 - np.cos(2.0 * np.pi * s)))
    y = y + noise * np.random.default_rng(1).standard_normal(n)
    return np.stack([x, y], -1)[None]


@pytest.mark.parametrize("kernel", [False, True])
def test_a_dwell_is_judged_on_its_shape_not_on_round_off(kernel: bool) -> None:
    # A flat stance longer than half the cycle changes sign on noise alone: 1e-13 mm of it made the path infeasible
    # (30 "landings"). Round-off lobes are not landings; a real bump still costs its size.
    exact = evaluate_paths(dwell(), dwell(), kernel=kernel)
    for noise, feasible in ((1e-13, True), (1e-11, True), (1e-6, False)):
        p = dwell(noise=noise)
        ev = evaluate_paths(p, p, kernel=kernel)
        assert bool(ev.feasible[0]) == feasible, noise
        if feasible:  # where the landing sits on the flat is a matter of noise: within a micrometre
            assert ev.l_s[0] == pytest.approx(exact.l_s[0], abs=1e-3) and ev.h_m[0] == pytest.approx(exact.h_m[0])
    assert exact.feasible[0] and exact.l_s[0] == pytest.approx(250.0, rel=1e-5)


def test_a_figure_eight_is_infeasible() -> None:
    th = 2.0 * np.pi * np.arange(360) / 360
    p = np.stack([150 * np.sin(th), 60 * np.sin(2 * th) + 20 * np.sin(th)], -1)
    ev = evaluate_paths(p, p)
    fp = feature_points(p)
    assert fp.turning[0] == 0
    assert ev.path_violation[0] >= 1.0 and not ev.feasible[0]


def test_a_path_folded_on_itself_has_no_landing_root() -> None:
    th = 2.0 * np.pi * np.arange(360) / 360
    p = np.stack([150 * np.cos(th), np.zeros_like(th)], -1)  # y(t) = y(t + T/2) everywhere
    fp = feature_points(p)
    assert fp.n_roots[0] == 0 and fp.root_violation[0] == NO_ROOT_VIOLATION
    assert not evaluate_paths(p, p).feasible[0]


def test_a_clockwise_path_breaks_the_eq30_order() -> None:
    p, d = ellipse()
    fp_ccw = feature_points(p, d)
    fp_cw = feature_points(p[::-1].copy(), -d[::-1].copy())
    assert order_violation(fp_ccw)[0] == pytest.approx(0.0, abs=1e-9)
    assert order_violation(fp_cw)[0] > 1.0  # rad: the extremes sit in the wrong halves


def test_order_violation_grows_continuously_with_a_backward_landing() -> None:
    """Tilting the path moves the left-most point t4 into the stance a little: a small value."""
    values = []
    for tilt in (0.0, 0.05, 0.1, 0.2):
        p, d = ellipse()
        rot = np.array([[1.0, 0.0], [tilt, 1.0]])  # shear: y += tilt x
        fp = feature_points(p @ rot.T, d @ rot.T)
        values.append(order_violation(fp)[0])
    assert values[0] == pytest.approx(0.0, abs=1e-9)
    assert 0.0 < values[1] < values[2] < values[3] < 1.0


@pytest.mark.parametrize("n", [7, 9, 101, 361])
def test_odd_sample_counts_work(n: int) -> None:
    p, d = ellipse(n)
    fp = feature_points(p, d)
    assert fp.n_roots[0] == 2
    # the ellipse lands at its left end (theta = pi) and takes off at its right end, up to the
    # cubic Hermite interpolation error ~ r h^4 / 384 (h = 2 pi / n)
    tol = 150.0 * (2 * np.pi / n) ** 4 / 100
    assert fp.point("t1")[0] == pytest.approx([-150.0, 0.0], abs=tol)
    assert fp.point("t2")[0] == pytest.approx([150.0, 0.0], abs=tol)
