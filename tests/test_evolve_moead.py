"""MOEA/D's compiled one-child replacement equals the numpy rule it replaced (CMOEMT's task 2), with ties,
penalised (+inf) and undefined (NaN) objectives, and stamps exactly the members it replaced."""

from __future__ import annotations

import numpy as np
import pytest
from cmoea_common import logistic, replace_ok
from hypothesis import given, settings
from hypothesis import strategies as st

from core.optimize.evolve.moead import tchebycheff_replace
from core.optimize.evolve.weights import tchebycheff

VALUES = [0.0, 0.5, 1.0, 2.0, 3.0, np.inf, np.nan]


def by_numpy(X, F, G, cv, W, pool, yX, yF, yG, ycv, z, eps, pull, nr):
    X, F, G, cv = X.copy(), F.copy(), G.copy(), cv.copy()
    with np.errstate(invalid="ignore"):
        g_old = tchebycheff(F[pool], W[pool], z)
        g_new = tchebycheff(np.broadcast_to(yF[0], (len(pool), yF.shape[1])), W[pool], z)
    idx = pool[replace_ok(g_old, g_new, cv[pool], ycv, eps, pull)][:nr]
    X[idx], F[idx], G[idx], cv[idx] = yX[0], yF[0], yG[0], ycv
    return X, F, G, cv, len(idx), idx


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 12), st.integers(1, 3), st.integers(0, 2**32 - 1), st.booleans(), st.integers(1, 3))
def test_the_compiled_replacement_equals_the_numpy_rule(n, m, seed, pull, nr):
    rng = np.random.default_rng(seed)
    F = rng.choice(VALUES, size=(n, m))
    cv = rng.choice([0.0, 0.0, 0.5, 1.0, np.inf], size=n)
    X, G = rng.random((n, 4)), rng.random((n, 2))
    W = rng.choice([1e-6, 0.25, 0.5, 1.0], size=(n, m))
    pool = rng.permutation(n)[: rng.integers(1, n + 1)].astype(np.int64)
    yF = rng.choice(VALUES, size=(1, m))
    yX, yG = rng.random((1, 4)), rng.random((1, 2))
    ycv = float(rng.choice([0.0, 0.5, 1.0, np.inf]))
    with np.errstate(invalid="ignore"):
        z = np.fmin(np.nanmin(np.where(np.isnan(F), np.inf, F), axis=0), yF[0])
    eps = float(rng.choice([0.0, 0.5, 1.0]))
    want = by_numpy(X, F, G, cv, W, pool, yX, yF, yG, ycv, z, eps, pull, nr)
    got = [a.copy() for a in (X, F, G, cv)]
    stamp = np.zeros(n, dtype=np.int64)
    replaced = tchebycheff_replace(*got, W, pool, yX, yF, yG, ycv, z, eps, pull, nr, stamp, 7)
    for a, b in zip(got, want[:4], strict=True):
        np.testing.assert_array_equal(a, b)
    assert replaced == want[4]
    np.testing.assert_array_equal(np.flatnonzero(stamp == 7), np.sort(want[5]))
    assert set(stamp) <= {0, 7}


def cmt_by_numpy(P, W, pool, y, z1, cmin, cmax, s_cv, nr=2, s_obj=0.3):
    """MOEA/D-CMT's task-1 rule as the numpy code it replaced wrote it."""

    X, F, G, cv = (a.copy() for a in P)
    yX, yF, yG, ycv = y
    Wp = W[pool]
    with np.errstate(invalid="ignore", divide="ignore"):
        g_old = (np.abs(F[pool] - z1) / Wp).max(axis=1)
        g_new = (np.abs(yF[0] - z1) / Wp).max(axis=1)
        cv_old, cv_new = cv[pool].copy(), np.full(len(pool), ycv)
        if cmax > cmin:
            cv_old = np.where(cv_old > 0, (cv_old - cmin) / (cmax - cmin), cv_old)
            cv_new = np.where(cv_new > 0, (cv_new - cmin) / (cmax - cmin), cv_new)
        a = logistic(g_old - g_new, s_obj) * np.fmax(logistic(cv_old - cv_new, s_cv), 1e-4)
        b = logistic(g_new - g_old, s_obj) * np.fmax(logistic(cv_new - cv_old, s_cv), 1e-4)
    idx = pool[a >= b][:nr]
    X[idx], F[idx], G[idx], cv[idx] = yX[0], yF[0], yG[0], ycv
    return X, F, G, cv, len(idx), idx


def pbi_by_numpy(P, W, pool, y, z, theta=5.0):
    """MOEA/D-CMT's task-2 (PBI) rule as the numpy code it replaced wrote it."""
    X, F, G, cv = (a.copy() for a in P)
    yX, yF, yG, ycv = y
    Wp = W[pool]
    norm_w = np.linalg.norm(Wp, axis=1)
    degenerate = 1.0 if F.shape[1] == 1 else np.nan

    def pbi(Fs):
        d = Fs - z
        nd = np.linalg.norm(d, axis=-1)
        d1 = (d * Wp).sum(axis=-1) / norm_w
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.where(nd > 0, d1 / nd, degenerate)
            return d1 + theta * nd * np.sqrt(np.maximum(0.0, 1 - cos**2))

    with np.errstate(invalid="ignore"):
        idx = pool[pbi(F[pool]) >= pbi(np.broadcast_to(yF[0], (len(pool), yF.shape[1])))]
    X[idx], F[idx], G[idx], cv[idx] = yX[0], yF[0], yG[0], ycv
    return X, F, G, cv, len(idx), idx


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 12), st.integers(1, 3), st.integers(0, 2**32 - 1), st.sampled_from([0.0, 0.02, 0.1, 0.5, 3.0]))
def test_moead_cmt_compiled_replacements_equal_the_numpy_rules(n, m, seed, s_cv):
    from core.optimize.evolve.moead import cmt_differences, cmt_replace, pbi_replace

    rng = np.random.default_rng(seed)
    P = (rng.random((n, 4)), rng.choice(VALUES, size=(n, m)), rng.random((n, 2)),
         rng.choice([0.0, 0.0, 0.5, 1.0, np.inf], size=n))
    y = (rng.random((1, 4)), rng.choice(VALUES, size=(1, m)), rng.random((1, 2)),
         float(rng.choice([0.0, 0.5, 1.0, np.inf])))
    W = rng.choice([1e-6, 0.25, 0.5, 1.0], size=(n, m))
    pool = rng.permutation(n)[: rng.integers(1, n + 1)].astype(np.int64)
    z = rng.choice([0.0, 0.5, np.inf], size=m)
    cmin, cmax = float(rng.choice([0.0, 0.5])), float(max(P[3].max(), y[3]))
    want = cmt_by_numpy(P, W, pool, y, z, cmin, cmax, s_cv)
    got = [a.copy() for a in P]
    dg, dc = cmt_differences(got[1], got[3], W, pool, y[1], y[3], z, cmin, cmax)
    stamp = np.zeros(n, dtype=np.int64)
    replaced = cmt_replace(*got, pool, *y, dg, dc, 0.3, s_cv, 2, stamp, 7)
    for a, b in zip(got, want[:4], strict=True):
        np.testing.assert_array_equal(a, b)
    assert replaced == want[4]
    np.testing.assert_array_equal(np.flatnonzero(stamp == 7), np.sort(want[5]))
    assert set(stamp) <= {0, 7}
    want = pbi_by_numpy(P, W, pool, y, z)
    got = [a.copy() for a in P]
    stamp = np.zeros(n, dtype=np.int64)
    replaced = pbi_replace(*got, W, pool, *y, z, 5.0, 1.0 if m == 1 else np.nan, stamp, 7)
    for a, b in zip(got, want[:4], strict=True):
        np.testing.assert_array_equal(a, b)
    assert replaced == want[4]
    np.testing.assert_array_equal(np.flatnonzero(stamp == 7), np.sort(want[5]))
    assert set(stamp) <= {0, 7}


@pytest.mark.parametrize(("dg", "replaced"), [(2.5, 0), (3.5, 1)])
def test_the_1e_4_floor_lets_a_large_objective_gain_outweigh_a_worse_violation(dg, replaced):
    # The child's violation is worse by 0.5 (normalised) at s_cv 0.02: its L(dc) underflows to the floor 1e-4
    # (spec §7), so it wins iff L(dg / 0.3) 1e-4 >= L(-dg / 0.3): dg >= 0.3 ln(1e4 - 1) = 2.76.
    from core.optimize.evolve.moead import cmt_replace

    X, F, G, cv = np.zeros((1, 2)), np.ones((1, 2)), np.zeros((1, 1)), np.zeros(1)
    y = (np.ones((1, 2)), np.zeros((1, 2)), np.zeros((1, 1)), 0.5)
    stamp = np.zeros(1, dtype=np.int64)
    got = cmt_replace(X, F, G, cv, np.zeros(1, dtype=np.int64), *y, np.array([dg]), np.array([-0.5]), 0.3, 0.02, 2,
                      stamp, 1)
    assert got == replaced and (X[0, 0] == 1.0) == bool(replaced)
