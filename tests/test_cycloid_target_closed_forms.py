"""The compound-cycloid target, analysed as a leg-frame path, has closed-form metrics.

Leg frame = the paper's pantograph k = -1 about (150, 0): x' = 2*150 - x, y' = -y. For a step L
the pivot is at L/2 so that the stance runs over [0, L]. In the leg frame the return line lies
on y = 0 (moving +x) and the arch rises above it: y'(s) = H (1 - cos 2 pi s) / 2 >= 0.

- f(t) = y(t) - y(t + T/2) = arch(t) >= 0 on the first half, <= 0 on the second: one root pair,
  at t = 0 and T/2; the lower half-cycle is the line, so t1 = T/2 and t2 = T (= 0).
- l_s = |x(t2) - x(t1)| = |L - 0| = L; the stance is flat: h_s = 0, S = 0.
- y'(t1) = 0 on the line, so I = |y'| sin(theta1) = 0.
- step = 2 l_s = 2 L.
- swing heights y(t) - y(t - T/2) = arch(t) - 0: h_m = H (at s = 1/2), and the time mean of
  H (1 - cos 2 pi s) / 2 over s in [0, 1] is H / 2 (also exactly on N/2 + 1 uniform samples with
  the trapezoid rule: the cosine sums to zero over a full period).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.analysis.evaluate import evaluate_paths
from core.analysis.features import feature_points
from core.analysis.gait import walking_trajectory
from core.analysis.metrics import (
    crossing_height,
    impact,
    mean_crossing_height,
    stance_fluctuation,
    stance_length,
    straightness,
)
from core.analysis.targets import compound_cycloid, cycloid_target
from core.kinematics.model import OutputStage

CASES = [(300.0, 100.0, 360), (300.0, 100.0, 64), (150.0, 40.0, 200), (420.0, 75.0, 1000)]


def leg_path(L: float, H: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p, d = compound_cycloid(n, L, H)
    stage = OutputStage(k=-1.0, ox=L / 2.0, oy=0.0)
    return p, stage.apply(p), stage.apply_derivative(d)


@pytest.mark.parametrize(("L", "H", "n"), CASES)
def test_target_feature_points_are_the_half_periods(L: float, H: float, n: int) -> None:
    _, leg, dleg = leg_path(L, H, n)
    fp = feature_points(leg, dleg, period=2.0)
    assert fp.n_roots[0] == 2 and fp.root_violation[0] == 0.0 and fp.turning[0] == 1
    assert fp.time("t1")[0] == pytest.approx(1.0, abs=1e-12)
    assert fp.time("t2")[0] % 2.0 == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(fp.point("t1")[0], [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(fp.point("t2")[0], [L, 0.0], atol=1e-9)


@pytest.mark.parametrize(("L", "H", "n"), CASES)
def test_target_metrics_closed_forms(L: float, H: float, n: int) -> None:
    _, leg, dleg = leg_path(L, H, n)
    fp = feature_points(leg, dleg, period=2.0)
    h_s = stance_fluctuation(leg[None], fp)
    l_s = stance_length(fp)
    wt = walking_trajectory(leg, dleg, fp)
    assert h_s[0] == pytest.approx(0.0, abs=1e-9)
    assert l_s[0] == pytest.approx(L, rel=1e-12)
    assert straightness(h_s, l_s)[0] == pytest.approx(0.0, abs=1e-9)
    assert impact(fp)[0] == pytest.approx(0.0, abs=1e-9)
    assert wt.step[0] == pytest.approx(2.0 * L, rel=1e-12)
    if (n // 2) % 2 == 0:  # the arch apex s = 1/2 is a sample
        assert crossing_height(wt)[0] == pytest.approx(H, rel=1e-12)
    else:
        assert crossing_height(wt)[0] == pytest.approx(H, rel=1e-3)
    assert mean_crossing_height(wt)[0] == pytest.approx(H / 2.0, rel=1e-12)


@pytest.mark.parametrize("kernel", [False, True])
def test_target_through_the_whole_stack(kernel: bool) -> None:
    """evaluate_paths on the target itself: the same closed forms, MSE 0, width L, y_min -H."""
    L, H, n = 300.0, 100.0, 360
    point, leg, dleg = leg_path(L, H, n)
    ev = evaluate_paths(point, leg, dleg, target=cycloid_target(L, H), kernel=kernel)
    assert ev.feasible[0]
    assert ev.S[0] == pytest.approx(0.0, abs=1e-9)
    assert ev.I[0] == pytest.approx(0.0, abs=1e-9)
    assert ev.l_s[0] == pytest.approx(L)
    assert ev.step_length[0] == pytest.approx(2 * L)
    assert ev.h_m[0] == pytest.approx(H)
    assert ev.h_bar[0] == pytest.approx(H / 2)
    assert ev.mse[0] == pytest.approx(0.0, abs=1e-12)
    assert ev.width[0] == pytest.approx(L)
    assert ev.y_min[0] == pytest.approx(-H)
    # Eq. 30: the stance starts at the left-most point and ends at the right-most one.
    assert ev.constraints[0, 0] == pytest.approx(0.0, abs=1e-9)
