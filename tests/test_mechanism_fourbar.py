"""Four-bar: hand-computed coupler points, Grashof full rotation, assembly violation, exact derivatives."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from core.kinematics.mechanisms.fourbar import FOURBAR
from core.kinematics.solver import solve

# b, g, x_a, y_a, r1 (crank), r2 (coupler), r3 (rocker), r4 (ground), r5, r6 (coupler point)
NAMES = FOURBAR.param_names


def design(**kw: float) -> np.ndarray:
    base = dict(b=0.0, g=0.0, x_a=0.0, y_a=0.0, r1=50.0, r2=120.0, r3=90.0, r4=200.0, r5=60.0, r6=30.0)
    base.update(kw)
    return np.array([[base[n] for n in NAMES]])


def test_right_angle_coupler_point_by_hand() -> None:
    # Crank at phi = 0: B = (50, 0), D = (200, 0), |BD| = 150 = 5 * 30, coupler 120 = 4 * 30 and
    # rocker 90 = 3 * 30, so the angle at C is right and cos(CBD) = 120 / 150 = 0.8 (C above BD).
    sol = solve(FOURBAR, design(), 4, backend="numpy")
    b, c, p = (sol.joints[0, 0, FOURBAR.joint_names.index(n)] for n in "BCP")
    np.testing.assert_allclose(b, [50.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(c, [50.0 + 120.0 * 0.8, 120.0 * 0.6], atol=1e-12)
    # e = (0.8, 0.6), rot90(e) = (-0.6, 0.8): P = B + 60 e + 30 rot90(e).
    np.testing.assert_allclose(p, [50.0 + 48.0 - 18.0, 36.0 + 24.0], atol=1e-12)
    np.testing.assert_allclose(sol.point[0, 0], [80.0, 60.0], atol=1e-12)


def test_rotated_and_translated_frame_by_hand() -> None:
    # The same triangle with the ground link turned by b = pi/2 about A = (10, 20) and the crank
    # phase turned with it: every point rotates by 90 degrees, (x, y) -> (-y, x), then shifts.
    sol = solve(FOURBAR, design(b=np.pi / 2, g=np.pi / 2, x_a=10.0, y_a=20.0), 4, backend="numpy")
    np.testing.assert_allclose(sol.point[0, 0], [10.0 - 60.0, 20.0 + 80.0], atol=1e-12)
    np.testing.assert_allclose(sol.joints[0, 0, FOURBAR.joint_names.index("D")], [10.0, 220.0], atol=1e-12)


def test_rectangle_at_quarter_turn_by_hand() -> None:
    # Parallelogram lengths (crank = rocker = 90, coupler = ground = 120) at phi = pi/2: B = (0, 90),
    # D = (120, 0), |BD| = 150, and the left solution is the rectangle corner C = (120, 90).
    x = design(r1=90.0, r2=120.0, r3=90.0, r4=120.0, r5=40.0, r6=-10.0)
    sol = solve(FOURBAR, x, 4, backend="numpy")  # sample 1 is theta = pi/2
    np.testing.assert_allclose(sol.joints[0, 1, FOURBAR.joint_names.index("C")], [120.0, 90.0], atol=1e-12)
    np.testing.assert_allclose(sol.point[0, 1], [40.0, 80.0], atol=1e-12)


@pytest.mark.parametrize(
    ("r1", "r2", "r3", "r4", "grashof"),
    [
        (50, 120, 90, 200, False),  # ground longest: 50 + 200 > 120 + 90
        (50, 150, 110, 200, True),  # ground longest: 250 < 260
        (40, 200, 100, 120, False),  # coupler longest: 240 > 220
        (40, 200, 130, 120, True),  # coupler longest: 240 < 250
        (40, 100, 210, 120, False),  # rocker longest: 250 > 220
        (40, 100, 170, 120, True),  # rocker longest: 210 < 220
    ],
)
def test_crank_margin_is_positive_iff_grashof_with_crank_shortest(r1, r2, r3, r4, grashof) -> None:
    sol = solve(FOURBAR, design(r1=r1, r2=r2, r3=r3, r4=r4), 720, backend="numpy")
    assert (sol.crank_margin[0] > 0) == grashof
    assert (sol.violation[0] == 0) == grashof


@settings(max_examples=200, deadline=None)
@given(st.floats(30.0, 100.0), st.lists(st.floats(0.0, 300.0), min_size=3, max_size=3))
def test_crank_margin_sign_matches_grashof(r1, extra) -> None:
    r2, r3, r4 = (r1 + e for e in extra)  # the crank is the shortest link
    s, p, q, ln = sorted([r1, r2, r3, r4])
    assume(abs(s + ln - p - q) > 1e-6)
    sol = solve(FOURBAR, design(r1=r1, r2=r2, r3=r3, r4=r4), 8, backend="numpy")
    assert (sol.crank_margin[0] > 0) == (s + ln < p + q)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_crank_that_stops_between_two_samples_is_not_feasible(backend: str) -> None:
    # Crank 50 about A, D at 100: |BD| reaches 150 at phi = pi, which a coupler + rocker of 149.999 cannot span.
    # With the phase g = 0.5 deg no sample of 360 falls at phi = pi, so every sample closes: the exact crank margin
    # (-0.001 mm) is the violation, small and continuous, where it read 0 (feasible).
    g = np.deg2rad(0.5)
    for short, viol in ((0.0, 0.0), (1e-3, 1e-3), (1e-4, 1e-4)):
        sol = solve(FOURBAR, design(g=g, r1=50.0, r2=75.0, r3=75.0 - short, r4=100.0), 360, backend=backend)
        assert sol.valid.all()
        assert sol.violation[0] == pytest.approx(viol, rel=1e-6, abs=1e-12)
        assert sol.violation[0] == pytest.approx(max(0.0, -sol.crank_margin[0]), abs=1e-12)
    # Further short, a sample fails too: the violation keeps growing (it fell ~1000x to that sample's shortfall
    # when only the samples counted once one of them failed).
    shorts = np.linspace(1e-4, 5e-2, 400)
    P = np.concatenate([design(g=g, r1=50.0, r2=75.0, r3=75.0 - x, r4=100.0) for x in shorts])
    sol = solve(FOURBAR, P, 360, backend=backend)
    assert (~sol.valid).any()  # the range crosses the point where samples fail
    assert np.all(np.diff(sol.violation) > 0) and np.all(sol.violation >= shorts * (1 - 1e-9))


@settings(max_examples=100, deadline=None)
@given(st.floats(30.0, 100.0), st.lists(st.floats(0.0, 300.0), min_size=3, max_size=3), st.floats(0.0, 6.28))
def test_a_feasible_four_bar_turns_fully_at_any_phase(r1, extra, g) -> None:
    r2, r3, r4 = (r1 + e for e in extra)
    sol = solve(FOURBAR, design(g=g, r1=r1, r2=r2, r3=r3, r4=r4), 36, backend="numpy")
    if sol.violation[0] == 0.0:
        assert sol.crank_margin[0] >= 0.0


def test_unassemblable_is_nan_with_violation_equal_to_the_shortfall() -> None:
    # With b = g = 0 the sample theta = pi stretches B-D to r1 + r4 = 250; a coupler + rocker of
    # 250 - t leaves a shortfall of exactly t there.
    ts = np.array([20.0, 10.0, 5.0, 1.0, 0.1, -1.0])
    x = np.repeat(design(r1=50.0, r2=120.0, r4=200.0), len(ts), axis=0)
    x[:, NAMES.index("r3")] = 130.0 - ts
    sol = solve(FOURBAR, x, 360, backend="numpy")
    np.testing.assert_allclose(sol.violation, np.maximum(ts, 0.0), atol=1e-9)
    assert np.all(np.diff(sol.violation) <= 0)
    for i, t in enumerate(ts):
        assert np.isnan(sol.point[i, 180]).all() == (t > 0)
        assert np.isfinite(sol.point[i, 0]).all()
    assert sol.valid[ts <= 0].all()


@settings(max_examples=30, deadline=None)
@given(
    st.floats(-np.pi, np.pi),
    st.floats(-np.pi, np.pi),
    st.floats(0.85, 1.15),
    st.floats(0.85, 1.15),
    st.floats(-200.0, 200.0),
    st.floats(-200.0, 200.0),
)
def test_rigid_distances_and_exact_derivatives(b, g, f2, f3, r5, r6) -> None:
    x = design(b=b, g=g, r1=50.0, r2=170.0 * f2, r3=130.0 * f3, r4=200.0, r5=r5, r6=r6)
    sol = solve(FOURBAR, x, 90, backend="numpy")
    assume(sol.violation[0] == 0.0)
    assert_rigid(FOURBAR, sol.joints[0])
    assert_derivatives_match(FOURBAR, x, "g", 90)


def assert_rigid(mechanism, joints: np.ndarray) -> None:
    """Every pairwise distance inside every rigid body is constant over the cycle (1e-9 mm)."""
    idx = {n: i for i, n in enumerate(mechanism.joint_names)}
    for body in mechanism.bodies():
        for i, p in enumerate(body):
            for q in body[i + 1 :]:
                d = np.linalg.norm(joints[:, idx[p]] - joints[:, idx[q]], axis=-1)
                assert np.ptp(d) < 1e-9, (body, p, q, np.ptp(d))


def assert_derivatives_match(mechanism, x: np.ndarray, phase: str, n: int, h: float = 1e-5) -> None:
    """Exact d/dtheta == central difference in the crank phase, to 1e-5 relative."""
    k = mechanism.param_names.index(phase)
    xp, xm = x.copy(), x.copy()
    xp[:, k] += h
    xm[:, k] -= h
    sol, sp, sm = (solve(mechanism, v, n, backend="numpy") for v in (x, xp, xm))
    fd = (sp.joints - sm.joints) / (2 * h)
    scale = np.abs(sol.djoints).max()
    np.testing.assert_allclose(sol.djoints, fd, rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(sol.dpoint, (sp.point - sm.point) / (2 * h), rtol=0, atol=1e-5 * scale)


def test_batch_equals_loop_over_designs() -> None:
    x = np.concatenate(
        [design(), design(r2=150.0, r3=110.0), design(b=1.0, g=-2.0, r2=140.0, r3=120.0, r5=-80.0), design(r3=10.0)]
    )
    before = x.copy()
    batch = solve(FOURBAR, x, 120, backend="numpy")
    np.testing.assert_array_equal(x, before)
    for i in range(len(x)):
        one = solve(FOURBAR, x[i], 120, backend="numpy")
        np.testing.assert_allclose(batch.joints[i], one.joints[0], rtol=0, atol=1e-12, equal_nan=True)
        np.testing.assert_allclose(batch.dpoint[i], one.dpoint[0], rtol=0, atol=1e-12, equal_nan=True)
        assert batch.violation[i] == one.violation[0]
        assert batch.crank_margin[i] == one.crank_margin[0]
