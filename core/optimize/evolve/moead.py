"""MOEA/D's sequential replacement, one child at a time, compiled (CMOEMT's task 2, MOEA/D-CMT's tasks).

A child evaluated alone replaces at most ``nr`` of its neighbours before the next child is made (the
published algorithms require it), so this runs once per child: in numpy it was ~10 small array operations,
~40 us of Python each time. Same numbers as the numpy form (IEEE operations only; ``max`` propagates NaN as
``np.max`` does). Each replacement writes the child's ``tick`` into ``stamp`` for the member it replaced, which
tells a child made ahead whether its parents are still the ones it was made from.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@numba.njit(cache=True)
def _put(X: F64, F: F64, G: F64, cv: F64, p: int, yX: F64, yF: F64, yG: F64, ycv: float, stamp: I64,
         tick: int) -> None:  # pragma: no cover - compiled
    # member p becomes the child (stamped with the child's tick)
    stamp[p] = tick
    X[p, :] = yX[0, :]
    F[p, :] = yF[0, :]
    G[p, :] = yG[0, :]
    cv[p] = ycv


@numba.njit(cache=True)
def fmin_into(z: F64, y: F64) -> None:  # pragma: no cover - compiled
    """``z = np.fmin(z, y)`` in place: a NaN on one side gives the other."""
    for k in range(len(z)):
        if np.isnan(z[k]) or y[k] < z[k]:
            z[k] = y[k]


@numba.njit(cache=True)
def _tchebycheff(F: F64, row: int, W: F64, w: int, z: F64) -> float:  # pragma: no cover - compiled
    # max_k W[w, k] |F[row, k] - z_k|, NaN if any term is (as np.max)
    m = -np.inf
    for k in range(F.shape[1]):
        v = W[w, k] * abs(F[row, k] - z[k])
        if np.isnan(v):
            return np.nan
        if v > m:
            m = v
    return m


@numba.njit(cache=True)
def tchebycheff_replace(X: F64, F: F64, G: F64, cv: F64, W: F64, pool: I64, yX: F64, yF: F64, yG: F64,
                        ycv: float, z: F64, eps: float, pull: bool, nr: int,
                        stamp: I64, tick: int) -> int:  # pragma: no cover - compiled
    """Replace, in place, the first ``nr`` members of ``pool`` (in its order) the child (``yX``, ``yF``, ``yG``,
    ``ycv``; rows of shape ``(1, .)``) may replace: push (``pull`` False) when its Tchebycheff value (weights
    ``W[pool]``, ideal point ``z``) is no worse; pull by the improved epsilon rule: no worse and both within
    ``eps`` or equally violating, or less violating. Returns how many it replaced."""
    done = 0
    for p in pool:
        if done >= nr:
            break
        better = _tchebycheff(F, p, W, p, z) >= _tchebycheff(yF, 0, W, p, z)
        if pull:
            ok = (better and ((cv[p] <= eps and ycv <= eps) or cv[p] == ycv)) or ycv < cv[p]
        else:
            ok = better
        if ok:
            _put(X, F, G, cv, p, yX, yF, yG, ycv, stamp, tick)
            done += 1
    return done


@numba.njit(cache=True)
def cmt_differences(F: F64, cv: F64, W: F64, pool: I64, yF: F64, ycv: float, z: F64, cmin: float,
                    cmax: float) -> tuple[F64, F64]:  # pragma: no cover - compiled
    """MOEA/D-CMT's task-1 comparison of a child with each neighbour in ``pool``: ``(g_old - g_new, cv_old -
    cv_new)``, g the Tchebycheff value ``max_k |f_k - z_k| / w_k`` (NaN if any term is), violations normalised
    to [cmin, cmax] where positive (when cmax > cmin)."""
    T, m = len(pool), F.shape[1]
    dg, dc = np.empty(T), np.empty(T)
    scale = cmax > cmin
    for t in range(T):
        p = pool[t]
        g_old, g_new = -np.inf, -np.inf
        for k in range(m):
            v = abs(F[p, k] - z[k]) / W[p, k]
            g_old = np.nan if (np.isnan(v) or np.isnan(g_old)) else max(g_old, v)
            v = abs(yF[0, k] - z[k]) / W[p, k]
            g_new = np.nan if (np.isnan(v) or np.isnan(g_new)) else max(g_new, v)
        dg[t] = g_old - g_new
        c_old, c_new = cv[p], ycv
        if scale:
            if c_old > 0:
                c_old = (c_old - cmin) / (cmax - cmin)
            if c_new > 0:
                c_new = (c_new - cmin) / (cmax - cmin)
        dc[t] = c_old - c_new
    return dg, dc


@numba.njit(cache=True)
def _logistic(x: float, sigma: float) -> float:  # pragma: no cover - compiled
    # 1 / (1 + e^(-x / sigma)); 0.5 at x == 0; a step for sigma <= 0 (NaN stays NaN)
    if sigma <= 0:
        return 1.0 if x > 0 else (0.0 if x < 0 else 0.5)
    return 0.5 if x == 0 else 1.0 / (1.0 + math.exp(-x / sigma))


@numba.njit(cache=True)
def _floor(c: float) -> float:  # pragma: no cover - compiled
    # np.fmax(c, 1e-4): NaN gives the floor
    return 1e-4 if np.isnan(c) or c < 1e-4 else c


@numba.njit(cache=True)
def cmt_replace(X: F64, F: F64, G: F64, cv: F64, pool: I64, yX: F64, yF: F64, yG: F64, ycv: float, dg: F64,
                dc: F64, s_obj: float, s_cv: float, nr: int, stamp: I64,
                tick: int) -> int:  # pragma: no cover - compiled
    """Replace, in place, the first ``nr`` neighbours in ``pool`` the child beats by MOEA/D-CMT's soft rule
    ``L(dg) max(L(dc), 1e-4) >= L(-dg) max(L(-dc), 1e-4)`` (L the logistic of sharpness s_obj, s_cv, with the
    compiled ``exp``: numpy's may differ in the last bit, which decides only between near-equal sides). Returns
    how many it replaced."""
    done = 0
    for t in range(len(pool)):
        if done >= nr:
            break
        a = _logistic(dg[t], s_obj) * _floor(_logistic(dc[t], s_cv))
        b = _logistic(-dg[t], s_obj) * _floor(_logistic(-dc[t], s_cv))
        if a >= b:
            p = pool[t]
            _put(X, F, G, cv, p, yX, yF, yG, ycv, stamp, tick)
            done += 1
    return done


@numba.njit(cache=True)
def _pbi(F: F64, row: int, W: F64, w: int, norm_w: float, z: F64, theta: float,
         degenerate: float) -> float:  # pragma: no cover - compiled
    # d1 + theta |d| sin(angle to w), d = f - z (a point on z has the cosine ``degenerate``)
    ss, dw = 0.0, 0.0
    for k in range(F.shape[1]):
        d = F[row, k] - z[k]
        ss += d * d
        dw += d * W[w, k]
    nd = np.sqrt(ss)
    d1 = dw / norm_w
    cos = d1 / nd if nd > 0 else degenerate
    s2 = 1 - cos * cos
    s2 = np.nan if np.isnan(s2) else max(0.0, s2)
    return d1 + theta * nd * np.sqrt(s2)


@numba.njit(cache=True)
def pbi_replace(X: F64, F: F64, G: F64, cv: F64, W: F64, pool: I64, yX: F64, yF: F64, yG: F64, ycv: float,
                z: F64, theta: float, degenerate: float, stamp: I64, tick: int) -> int:  # pragma: no cover - compiled
    """Replace, in place, every neighbour in ``pool`` whose PBI value (weights ``W[pool]``, ideal point ``z``,
    penalty ``theta``) is no better than the child's (MOEA/D-CMT's unconstrained task 2). Returns how many."""
    done = 0
    for p in pool:
        nw = 0.0
        for k in range(W.shape[1]):
            nw += W[p, k] * W[p, k]
        nw = np.sqrt(nw)
        if _pbi(F, p, W, p, nw, z, theta, degenerate) >= _pbi(yF, 0, W, p, nw, z, theta, degenerate):
            _put(X, F, G, cv, p, yX, yF, yG, ycv, stamp, tick)
            done += 1
    return done
