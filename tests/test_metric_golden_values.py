"""Golden values from closed forms for what the cycloid's zeros cannot tell apart: the landing impact on a path
that lands at a slant, the derivative of a sampled path, and each dyad's transmission-angle range against the
angles measured on the solved joints. Both backends share these functions, so comparing them cannot catch a
wrong formula (a mutation audit found each one unguarded)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.analysis.features import feature_points, periodic_derivative
from core.analysis.metrics import impact, landing_speed, tangent_angles
from core.kinematics.model import Dyad
from core.kinematics.presets import PRESETS
from core.kinematics.solver import solve


def sheared_ellipse(n: int, a: float, b: float, e: float) -> tuple[np.ndarray, np.ndarray]:
    """``x = 150 + a cos t + e sin t, y = b sin t``: counter-clockwise, y(t) - y(t + pi) = 2 b sin t, so it lands
    at t = pi at (150 - a, 0) with d/dt = (-e, -b)."""
    t = 2.0 * np.pi * np.arange(n) / n
    p = np.stack([150.0 + a * np.cos(t) + e * np.sin(t), b * np.sin(t)], -1)
    d = np.stack([-a * np.sin(t) + e * np.cos(t), b * np.cos(t)], -1)
    return p[None], d[None]


@pytest.mark.parametrize(("b", "e", "period"), [(40.0, 30.0, 2.0), (40.0, 90.0, 1.0), (10.0, 5.0, 4.0)])
def test_the_impact_of_a_slanted_landing_is_its_vertical_speed_times_the_sine_of_its_angle(b, e, period) -> None:
    p, d = sheared_ellipse(360, 150.0, b, e)
    fp = feature_points(p, d, period=period)
    assert fp.time("t1")[0] == pytest.approx(period / 2.0, abs=1e-9)
    np.testing.assert_allclose(fp.point("t1")[0], [0.0, 0.0], atol=1e-9)
    omega = 2.0 * np.pi / period
    assert landing_speed(fp)[0] == pytest.approx(-b * omega, rel=1e-9)
    assert tangent_angles(fp)[0, 0] == pytest.approx(math.atan2(b, e), rel=1e-9)
    assert impact(fp)[0] == pytest.approx(b * omega * b / math.hypot(b, e), rel=1e-9)  # sin(atan2(b, e))


@pytest.mark.parametrize("n", [64, 360, 1000])
def test_the_derivative_of_a_sampled_path_is_the_analytic_one_to_fourth_order(n: int) -> None:
    p, d = sheared_ellipse(n, 150.0, 60.0, 20.0)
    err = np.abs(periodic_derivative(p) - d).max()
    h = 2.0 * np.pi / n
    assert err <= 160.0 * h**4 / 30.0 * 1.5  # the stencil's error term: |f^(5)| h^4 / 30, |f^(5)| <= 160


@pytest.mark.parametrize("name", ["stephenson1/X3", "stephenson3/paper", "watt1/paper", "fourbar/chebyshev", "jansen"])
def test_transmission_angle_ranges_are_the_extremes_of_the_angles_at_the_dyads_joints(name: str) -> None:
    pr = PRESETS[name]
    design = pr.design()
    mech = design.mechanism
    sol = solve(mech, design.params, 3600, output=design.output)
    names = mech.joint_names
    dyads = [s for s in mech.steps if isinstance(s, Dyad)]
    assert sol.mu_min.shape == (1, len(dyads))
    for k, s in enumerate(dyads):
        j, p, q = (sol.joints[0, :, names.index(x)] for x in (s.name, s.p, s.q))
        u, v = p - j, q - j
        cos = np.sum(u * v, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
        mu = np.arccos(np.clip(cos, -1.0, 1.0))
        # the solver takes the exact extremes (at the extreme |PQ|), the samples come within 1e-3 rad of them
        assert sol.mu_min[0, k] <= mu.min() + 1e-9 and sol.mu_min[0, k] == pytest.approx(mu.min(), abs=2e-3), s
        assert sol.mu_max[0, k] >= mu.max() - 1e-9 and sol.mu_max[0, k] == pytest.approx(mu.max(), abs=2e-3), s


def two_hump_path(n: int = 360) -> np.ndarray:
    """Stance along y = 0 from x = 0 to 300 in the first half-cycle, then a swing back with two humps
    (y = 60 sin(pi s) + 25 sin(3 pi s), 35 mm at its middle)."""
    h = n // 2
    s = np.arange(h) / h
    stance = np.stack([300.0 * s, np.zeros(h)], -1)
    swing = np.stack([300.0 * (1 - s), 60 * np.sin(np.pi * s) + 25 * np.sin(3 * np.pi * s)], -1)
    return np.vstack([stance, swing])[None]


def test_a_flat_topped_swing_peak_is_still_a_peak():
    p = two_hump_path()
    y = p[0, :, 1]
    j = 180 + int(np.argmax(y[180:270]))  # the first hump's top sample
    p[0, j + 1, 1] = y[j]  # two equal top samples
    fp = feature_points(p)
    q7, q8 = fp.index[0, 6], fp.index[0, 7]
    assert abs(q7 - j) < 1.0 and q8 > 270  # t7 on the flat top, t8 on the second hump
    q6 = fp.index[0, 5]
    assert q7 < q6 < q8 and fp.point("t6")[0, 1] < 40.0  # t6 between them, near the 35 mm dip

