"""The shipped DAS-CMOP1-9 reference fronts (difficulty 8, scripts/make_dascmop_fronts.py): every point is
reached feasibly by pymoo's own problem, and no feasible point pymoo evaluates beats them or lies off them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from core.optimize.decision import pareto_front
from core.optimize.moea import FRONTS, problem_by_name, reference_front, run

KS = range(1, 10)
D, E = 0.5, 0.5 - np.log(0.5)  # zeta = 0.5: feasible iff D <= g <= E
FEAS_TOL = 1e-9  # pymoo's G <= this counts as feasible (the files carry 12 significant digits)
BEAT_TOL = 1e-6  # how far a sampled feasible point may dominate a front point (rounding, grid error)
COVER_TOL = {2: 0.005, 3: 0.025}  # how far from the front a sampled feasible point may stick out (thinning)


def snap(x: np.ndarray, feasible, edges: np.ndarray) -> np.ndarray:
    """x moved onto the nearest edge of its diversity interval where the file's rounding put it just outside."""
    x = np.clip(x, 0.0, 1.0)
    near = edges[np.abs(x[:, None] - edges[None, :]).argmin(axis=1)]
    return np.where(~feasible(x) & (np.abs(x - near) < 1e-6), near, x)


def x1_ok(x):
    return np.sin(20 * np.pi * x) >= -FEAS_TOL  # eta = 0.5: the diversity constraint sin(20 pi x1) >= 0


def x2_ok(x):
    return np.cos(20 * np.pi * x) >= -FEAS_TOL


EDGES1, EDGES2 = np.arange(21) / 20, np.arange(41) / 40


def position_and_g(k: int, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (x1[, x2]) and g with pymoo's s(x) + g = F, from the objectives alone."""
    if k <= 6:
        delta = F[:, 1] - F[:, 0]  # = phi(x1) - x1
        if k in (1, 4):  # 1 - x^2 - x = delta
            x = (-1 + np.sqrt(1 + 4 * (1 - delta))) / 2
        elif k in (2, 5):  # 1 - u - u^2 = delta, u = sqrt(x)
            x = ((-1 + np.sqrt(1 + 4 * (1 - delta))) / 2) ** 2
        else:  # 1 - sqrt(x) + |sin(5 pi x)| / 2 - x = delta: not monotone, take a root that fits
            x = np.array([_root_dascmop3(f0, dl) for f0, dl in zip(F[:, 0], delta, strict=True)])
        x = snap(x, x1_ok, EDGES1)
        return x[:, None], F[:, 0] - x
    if k == 7:  # f = (x1 x2, x2 (1 - x1), 1 - x2) + g
        x2 = np.clip((F[:, 0] + F[:, 1] - 2 * F[:, 2] + 2) / 3, 0.0, 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            x1 = np.where(x2 > 1e-9, ((F[:, 0] - F[:, 1]) / x2 + 1) / 2, 0.0)
        x1, x2 = snap(x1, x1_ok, EDGES1), snap(x2, x2_ok, EDGES2)
        return np.column_stack([x1, x2]), F[:, 2] - 1 + x2
    # k = 8, 9: f = (cos a cos b, cos a sin b, sin a) + g on the unit sphere: |F - g| = 1, the smaller root
    s1, s2 = F.sum(axis=1), (F**2).sum(axis=1)
    g = (s1 - np.sqrt(s1**2 - 3 * (s2 - 1))) / 3
    S = F - g[:, None]
    r = np.hypot(S[:, 0], S[:, 1])
    x1 = np.arctan2(S[:, 2], r) / (0.5 * np.pi)
    x2 = np.where(r > 1e-9, np.arctan2(S[:, 1], S[:, 0]) / (0.5 * np.pi), 0.0)
    return np.column_stack([snap(x1, x1_ok, EDGES1), snap(x2, x2_ok, EDGES2)]), g


def _root_dascmop3(f0: float, delta: float) -> float:
    def r(x):
        return 1 - np.sqrt(x) + 0.5 * np.abs(np.sin(5 * np.pi * x)) - x - delta

    grid = np.linspace(0.0, 1.0, 20001)
    v = r(grid)
    cands = list(grid[np.abs(v) < 1e-9])
    cands += [brentq(r, grid[i], grid[i + 1], xtol=1e-15) for i in np.flatnonzero(v[:-1] * v[1:] < 0)]
    fits = [x for x in cands if x1_ok(snap(np.array([x]), x1_ok, EDGES1))[0] and D - 1e-9 <= f0 - x <= E + 1e-9]
    return fits[0] if fits else (cands[0] if cands else 0.5)


def decision_vectors(k: int, P: np.ndarray, g: np.ndarray) -> np.ndarray:
    """30-variable X with positions P whose distance function (pymoo's g1, g2 or g3) equals g."""
    n_dist = 30 - P.shape[1]
    if 4 <= k <= 8:  # g2 = 1 + z^2 - cos(20 pi z) with z = x_j - 0.5 on one variable, z = 0 on the rest
        lo, hi = np.zeros_like(g), np.full_like(g, 0.05)  # increasing from 0 to 2.0025 on [0, 0.05]
        for _ in range(60):
            mid = (lo + hi) / 2
            low = 1 + mid**2 - np.cos(20 * np.pi * mid) < g
            lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
        Dv = np.full((len(P), n_dist), 0.5)
        Dv[:, 0] += (lo + hi) / 2
        return np.hstack([P, Dv])
    if k <= 3:  # g1 = sum (x_j - sin(pi x1 / 2))^2
        target = np.repeat(np.sin(0.5 * np.pi * P[:, :1]), n_dist, axis=1)
    else:  # g3 = sum (x_j - cos(pi j (x1 + x2) / 120))^2, j = 3..30
        j = np.arange(3, 31)
        target = np.cos(0.25 * j / 30 * np.pi * (P[:, 0:1] + P[:, 1:2]))
    step = np.sqrt(g / n_dist)[:, None]  # every variable off its target by the same step, inside [0, 1]
    return np.hstack([P, np.where(target + step <= 1, target + step, target - step)])


def evaluate(k: int, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    out = problem_by_name(f"dascmop{k}").evaluate(X, return_as_dictionary=True)
    return np.asarray(out["F"], dtype=np.float64), np.asarray(out["G"], dtype=np.float64)


def dominated_by_margin(A: np.ndarray, B: np.ndarray, tol: float) -> np.ndarray:
    """(len(B),) True where some row a of A has a <= b - tol in every objective."""
    out = np.zeros(len(B), dtype=bool)
    for start in range(0, len(B), 500):
        b = B[start : start + 500]
        out[start : start + 500] = np.all(A[None, :, :] <= b[:, None, :] - tol, axis=2).any(axis=1)
    return out


@pytest.mark.parametrize("k", KS)
def test_reference_front_is_the_file_and_non_dominated(k):
    pf = reference_front(f"dascmop{k}")
    assert pf is not None
    assert np.array_equal(pf, np.loadtxt(FRONTS / f"dascmop{k}.pf", ndmin=2))
    assert pf.shape[1] == problem_by_name(f"dascmop{k}").n_obj and len(pf) >= 500
    assert len(np.unique(pf, axis=0)) == len(pf)
    assert np.array_equal(pareto_front(pf), np.arange(len(pf)))


@pytest.mark.parametrize("k", KS)
def test_every_front_point_is_reached_feasibly_by_pymoo(k):
    pf = reference_front(f"dascmop{k}")
    assert pf is not None
    P, g = position_and_g(k, pf)
    F, G = evaluate(k, decision_vectors(k, P, g))
    np.testing.assert_allclose(F, pf, rtol=1e-9, atol=1e-12)
    worst = G.max(axis=1)
    assert worst.max() <= FEAS_TOL, f"infeasible front points: {pf[worst > FEAS_TOL][:5]}"


def samples(k: int, n_obj: int, rng: np.random.Generator) -> np.ndarray:
    """4000 random X, and 16000 with random positions (a fifth on diversity-interval edges) and g in [D, E],
    a third of them at g = D."""
    n = 16_000
    P = rng.random((n, n_obj - 1))
    edge = rng.random(n) < 0.2
    P[edge, 0] = rng.choice(EDGES1, edge.sum())
    if n_obj == 3:
        P[edge, 1] = rng.choice(EDGES2, edge.sum())
    g = np.where(rng.random(n) < 1 / 3, D, D + (E - D) * rng.random(n) ** 2)
    return np.vstack([rng.random((4000, 30)), decision_vectors(k, P, g)])


@pytest.mark.parametrize("k", KS)
def test_no_feasible_point_beats_the_front_or_lies_off_it(k):
    pf = reference_front(f"dascmop{k}")
    assert pf is not None
    F, G = evaluate(k, samples(k, pf.shape[1], np.random.default_rng(k)))
    Q = F[G.max(axis=1) <= FEAS_TOL]
    assert len(Q) > 3000
    beaten = dominated_by_margin(Q, pf, BEAT_TOL)  # front too pessimistic (or missing a better piece)
    assert not beaten.any(), f"{beaten.sum()} front points dominated, e.g. {pf[beaten][:3]}"
    off = ~dominated_by_margin(pf, Q, -COVER_TOL[pf.shape[1]])  # feasible points the front does not cover
    assert not off.any(), f"{off.sum()} feasible points not covered, e.g. {Q[off][:3]}"


def test_a_short_run_reads_the_front():
    res = run("dascmop1", "nsga2", 40, 2000, 1)
    assert res["reference_points"] > 0
    assert np.isfinite(res["hv"])
    assert np.isnan(res["igd"]) or np.isfinite(res["igd"])
