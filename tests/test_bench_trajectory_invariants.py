"""Properties of feature points, metrics and the walking trajectory on random smooth leg paths.

A path is a counter-clockwise ellipse (stance at the bottom, moving +x) with random small
harmonics and a random start phase, sampled with its exact derivative.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis import metrics as M
from core.analysis.evaluate import evaluate_paths
from core.analysis.features import feature_points
from core.analysis.gait import BIPED, quadruped, walking_trajectory

SETTINGS = settings(max_examples=40, deadline=None)


def smooth_path(
    rx: float, ry: float, coef: np.ndarray, phase: float, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 2)`` ellipse + harmonics k = 2, 3 (coef (2, 2, 2): k, cos/sin, x/y) and d/dtheta."""
    th = phase + 2.0 * np.pi * np.arange(n) / n
    p = np.stack([rx * np.cos(th), ry * np.sin(th)], -1)
    d = np.stack([-rx * np.sin(th), ry * np.cos(th)], -1)
    for j, k in enumerate((2, 3)):
        c, s = np.cos(k * th)[:, None], np.sin(k * th)[:, None]
        p = p + c * coef[j, 0] + s * coef[j, 1]
        d = d - k * s * coef[j, 0] + k * c * coef[j, 1]
    return p, d


@st.composite
def paths(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    rx = draw(st.floats(60.0, 250.0))
    ry = draw(st.floats(15.0, 90.0))
    coef = np.array(draw(st.lists(st.floats(-0.12, 0.12), min_size=8, max_size=8))).reshape(2, 2, 2)
    coef *= np.array([rx, ry])  # relative to the radii, so the path stays a simple oval
    phase = draw(st.floats(0.0, 2.0 * np.pi))
    n = draw(st.sampled_from([48, 90, 120, 360, 361]))
    return smooth_path(rx, ry, coef, phase, n)


def all_metrics(path: np.ndarray, dpath: np.ndarray) -> dict[str, np.ndarray]:
    ev = evaluate_paths(path, path, dpath)
    return {k: getattr(ev, k) for k in ("l_s", "h_s", "S", "I", "theta1", "theta2", "h_m", "h_bar", "psi2", "psi4")} | {
        "times": ev.times
    }


@SETTINGS
@given(paths())
def test_landing_pair_is_a_root_half_a_period_apart(pd: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = pd
    fp = feature_points(path, dpath, period=2.0)
    assert fp.valid[0] and fp.n_roots[0] == 2 and fp.turning[0] == 1
    t1, t2 = fp.time("t1")[0], fp.time("t2")[0]
    assert (t2 - t1) % 2.0 == pytest.approx(1.0, abs=1e-12)
    # even N: y(t + T/2) is a sample, so the root is exact on the interpolant; odd N: it is itself
    # interpolated, which leaves the Hermite error (~ r h^4 / 384)
    tol = 1e-9 if len(path) % 2 == 0 else 1e-5
    assert fp.point("t1")[0, 1] == pytest.approx(fp.point("t2")[0, 1], abs=tol)
    # the stance half is the lower one and moves +x (counter-clockwise path)
    assert fp.point("t1")[0, 0] < fp.point("t2")[0, 0]
    assert fp.point("t3")[0, 1] <= min(fp.point("t1")[0, 1], fp.point("t2")[0, 1]) + 1e-9
    assert np.all((fp.times >= 0.0) & (fp.times < 2.0))
    th = M.tangent_angles(fp)
    assert np.all((th >= 0.0) & (th <= np.pi / 2))


@SETTINGS
@given(paths())
def test_walking_trajectory_starts_at_take_off_and_steps_two_stances(pd: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = pd
    fp = feature_points(path, dpath)
    wt = walking_trajectory(path, dpath, fp)
    l_s = M.stance_length(fp)
    np.testing.assert_allclose(wt.points[0, 0], fp.point("t2")[0], atol=1e-9)
    np.testing.assert_allclose(wt.points[0, -1], 2 * fp.point("t1")[0] - fp.point("t2")[0], atol=1e-9)
    assert wt.step[0] == pytest.approx(2.0 * l_s[0], rel=1e-6)
    # the arc's interior follows C_b(t) - C_b(t - T/2) + C_b(t1): ground height at both ends
    assert wt.heights[0, 0] == 0.0 and wt.heights[0, -1] == 0.0
    assert M.crossing_height(wt)[0] > 0.0


@SETTINGS
@given(paths(), st.floats(-500.0, 500.0), st.floats(-500.0, 500.0))
def test_metrics_do_not_depend_on_where_the_path_is(pd: tuple[np.ndarray, np.ndarray], dx: float, dy: float) -> None:
    path, dpath = pd
    a = all_metrics(path, dpath)
    b = all_metrics(path + np.array([dx, dy]), dpath)
    b["times"] = a["times"] + ((b["times"] - a["times"] + 1.0) % 2.0 - 1.0)  # times are modulo T = 2 s
    for k in a:
        np.testing.assert_allclose(b[k], a[k], rtol=1e-6, atol=1e-6, err_msg=k)


@SETTINGS
@given(paths(), st.floats(0.2, 5.0))
def test_straightness_does_not_depend_on_size(pd: tuple[np.ndarray, np.ndarray], s: float) -> None:
    path, dpath = pd
    a = all_metrics(path, dpath)
    b = all_metrics(s * path, s * dpath)
    np.testing.assert_allclose(b["S"], a["S"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(b["h_s"], s * a["h_s"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(b["l_s"], s * a["l_s"], rtol=1e-9)


def test_batch_equals_loop_over_designs() -> None:
    rng = np.random.default_rng(7)
    items = [
        smooth_path(rng.uniform(60, 250), rng.uniform(15, 90), rng.uniform(-10, 10, (2, 2, 2)), rng.uniform(0, 6), 120)
        for _ in range(6)
    ]
    P = np.stack([p for p, _ in items])
    D = np.stack([d for _, d in items])
    P[2] = np.nan  # an unassemblable member must not disturb the others
    batch = evaluate_paths(P, P, D)
    for i in range(len(items)):
        one = evaluate_paths(P[i : i + 1], P[i : i + 1], D[i : i + 1])
        for k in ("l_s", "h_s", "S", "I", "h_m", "h_bar", "psi2", "psi4", "violation", "times", "constraints"):
            np.testing.assert_array_equal(getattr(batch, k)[i], getattr(one, k)[0], err_msg=k)


def test_psi_of_a_larger_obstacle_is_smaller() -> None:
    p, d = smooth_path(150.0, 50.0, np.zeros((2, 2, 2)), 0.3, 360)
    fp = feature_points(p, d)
    wt = walking_trajectory(p, d, fp)
    for layout in (BIPED, quadruped()):
        grid = np.array([[M.psi(wt, layout, a, b)[0] for b in (0, 5, 20, 45, 60)] for a in (0, 5, 20, 60, 200)])
        assert grid[0, 0] == pytest.approx(1.0)
        assert np.all(np.diff(grid, axis=0) <= 1e-12) and np.all(np.diff(grid, axis=1) <= 1e-12)
        assert grid[-1, -1] == 0.0  # a 200 mm long, 60 mm high obstacle is never crossed cleanly


@pytest.mark.parametrize("n", [48, 90, 360])
def test_a_tie_between_two_left_most_points_goes_the_same_way_wherever_the_path_is(n: int) -> None:
    # x(theta) = x(-theta): two left-most points of equal x, in separate places of the cycle. Which one t4 is
    # used to depend on the last bit of x, so a translation moved it (0.93 s against 1.07 s, a fresh CI run).
    th = 2.0 * np.pi * np.arange(n) / n
    path = np.stack([100.0 * np.cos(th) + 40.0 * np.cos(2 * th), 40.0 * np.sin(th)], -1)
    dpath = np.stack([-100.0 * np.sin(th) - 80.0 * np.sin(2 * th), 40.0 * np.cos(th)], -1)
    t4 = feature_points(path, dpath, period=2.0).time("t4")[0]
    moved = [feature_points(path + np.array([dx, dy]), dpath, period=2.0).time("t4")[0]
             for dx in np.linspace(-500.0, 500.0, 41) for dy in (-181.0, 0.0, 181.0)]
    assert np.allclose(moved, t4, rtol=0, atol=1e-9)
    assert t4 < 1.0  # the first of the two in sample order (theta from 0): the one near theta = 0.72 pi
