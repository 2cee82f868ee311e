"""psi(a, b) from exact intervals equals a Monte-Carlo estimate with real geometry.

The estimate drops an a x b obstacle at random positions over one stride under the robot's
world-frame foot paths (``core.analysis.gait.world_paths``: trunk from the stance leg, every foot at its
own phase, several strides) and tests every foot segment against the rectangle with the
Liang-Barsky clip. Points below the ground count as inside (the rectangle extends downwards).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.analysis.features import feature_points
from core.analysis.gait import BIPED, Layout, quadruped, walking_trajectory, world_paths
from core.analysis.metrics import psi
from core.analysis.targets import compound_cycloid
from core.kinematics.model import OutputStage
from core.kinematics.presets import get

N_DROPS = 20_000  # standard error <= 0.35 %: a 1 % tolerance is ~3 sigma
N_STRIDES = 5


def segments_hit(seg0: np.ndarray, seg1: np.ndarray, x0: np.ndarray, a: float, ytop: float) -> np.ndarray:
    """``(k,)`` True where any segment (s, 2) meets ``[x0, x0 + a] x [-inf, ytop]`` (k drops)."""
    lo_y = -1e9
    px, py = seg0[None, :, 0], seg0[None, :, 1]
    dx, dy = (seg1 - seg0)[None, :, 0], (seg1 - seg0)[None, :, 1]
    xmin, xmax = x0[:, None], x0[:, None] + a
    t0 = np.zeros((len(x0), len(seg0)))
    t1 = np.ones_like(t0)
    ok = np.ones_like(t0, dtype=bool)
    for p, q in ((-dx, px - xmin), (dx, xmax - px), (-dy, py - lo_y), (dy, ytop - py)):
        p, q = np.broadcast_to(p, t0.shape), np.broadcast_to(q, t0.shape)
        zero = p == 0.0
        ok &= ~(zero & (q < 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(zero, 0.0, q / p)
        t0 = np.where(~zero & (p < 0.0), np.maximum(t0, r), t0)
        t1 = np.where(~zero & (p > 0.0), np.minimum(t1, r), t1)
    return (ok & (t0 <= t1)).any(1)


def monte_carlo_psi(path: np.ndarray, dpath: np.ndarray, layout: Layout, a: float, b: float, seed: int) -> float:
    fp = feature_points(path, dpath)
    w = world_paths(path, dpath, fp, layout, n_strides=N_STRIDES)
    feet = w.feet[0]  # (n_legs, m, 2)
    ytop = w.ground[0] + b
    stride = 2.0 * abs(fp.point("t1")[0, 0] - fp.point("t2")[0, 0])
    # a window that every leg's path covers with more than a stride to spare on both sides
    lo = feet[..., 0].min(1).max()
    hi = feet[..., 0].max(1).min()
    assert hi - lo > 3 * stride + a
    x0 = np.random.default_rng(seed).uniform(0.0, stride, N_DROPS) + 0.5 * (lo + hi - stride - a)
    s0 = feet[:, :-1].reshape(-1, 2)
    s1 = feet[:, 1:].reshape(-1, 2)
    low = np.minimum(s0[:, 1], s1[:, 1]) <= ytop  # only these can reach the obstacle
    # a standing foot repeats one point: keep each distinct segment once
    seg = np.unique(np.round(np.concatenate([s0[low], s1[low]], 1), 7), axis=0)
    hit = np.zeros(N_DROPS, bool)
    for chunk in np.array_split(np.arange(N_DROPS), 10):
        hit[chunk] = segments_hit(seg[:, :2], seg[:, 2:], x0[chunk], a, ytop)
    return 1.0 - hit.mean()


def paper_leg(name: str) -> tuple[np.ndarray, np.ndarray]:
    sol = get(name).design().solve(360, joints=False, backend="numpy")
    return sol.leg[0], sol.dleg[0]


def cycloid_leg() -> tuple[np.ndarray, np.ndarray]:
    p, d = compound_cycloid(360)
    stage = OutputStage(k=-1.0, ox=150.0, oy=0.0)
    return stage.apply(p), stage.apply_derivative(d)


CASES = [
    ("stephenson1/X3", BIPED, 25.0, 25.0),
    ("stephenson1/X3", quadruped(), 25.0, 25.0),
    ("stephenson1/X0", BIPED, 60.0, 10.0),
    ("stephenson1/X1", quadruped(300.0), 10.0, 60.0),
    ("cycloid", BIPED, 40.0, 40.0),
    ("cycloid", quadruped(), 25.0, 20.0),
]


@pytest.mark.parametrize(("name", "layout", "a", "b"), CASES)
def test_exact_psi_equals_monte_carlo(name: str, layout: Layout, a: float, b: float) -> None:
    path, dpath = cycloid_leg() if name == "cycloid" else paper_leg(name)
    fp = feature_points(path, dpath)
    exact = psi(walking_trajectory(path, dpath, fp), layout, a, b)[0]
    mc = monte_carlo_psi(path, dpath, layout, a, b, seed=len(name) + int(a))
    assert 0.0 < exact < 1.0  # a case that says something
    assert exact == pytest.approx(mc, abs=0.01)


@pytest.mark.parametrize("name", ["stephenson1/X0", "stephenson1/X3", "cycloid"])
def test_a_point_obstacle_is_always_crossed(name: str) -> None:
    path, dpath = cycloid_leg() if name == "cycloid" else paper_leg(name)
    fp = feature_points(path, dpath)
    wt = walking_trajectory(path, dpath, fp)
    for layout in (BIPED, quadruped()):
        assert psi(wt, layout, 0.0, 0.0)[0] == pytest.approx(1.0, abs=1e-12)
