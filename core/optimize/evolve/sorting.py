"""Non-dominated sorting under constraint domination (CDP), and crowding distance.

Sorting is moocore's ``pareto_rank`` (0.05 ms at n = 400 and 3 objectives on this machine, against 0.1 ms for
pymoo's and 1.1 ms for a plain O(m n^2) numba kernel); crowding is a numba kernel.
"""

from __future__ import annotations

import moocore
import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


def nd_ranks(F: F64) -> I64:
    """``(n,)`` Pareto front index of each member (0 = non-dominated); NaN objectives count as +inf."""
    F = np.asarray(F, dtype=np.float64)
    if F.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    return np.asarray(moocore.pareto_rank(np.where(np.isnan(F), np.inf, F)), dtype=np.int64)


def cdp_ranks(F: F64, cv: F64) -> I64:
    """``(n,)`` front index under constraint domination: feasible members (cv <= 0) by Pareto fronts, then the
    infeasible ones after the last feasible front, one front per distinct violation, smaller first."""
    F = np.asarray(F, dtype=np.float64)
    cv = np.asarray(cv, dtype=np.float64)
    rank = np.zeros(F.shape[0], dtype=np.int64)
    feas = cv <= 0.0
    if feas.any():
        rank[feas] = nd_ranks(F[feas])
    if (~feas).any():
        start = int(rank[feas].max()) + 1 if feas.any() else 0
        _, dense = np.unique(np.where(np.isnan(cv[~feas]), np.inf, cv[~feas]), return_inverse=True)
        rank[~feas] = start + dense
    return rank


@numba.njit(cache=True)
def _crowding(F: F64, rank: I64) -> F64:  # pragma: no cover - compiled
    n, m = F.shape
    cd = np.zeros(n)
    if n == 0:
        return cd
    order = np.argsort(rank, kind="mergesort")
    start = 0
    while start < n:
        r = rank[order[start]]
        stop = start
        while stop < n and rank[order[stop]] == r:
            stop += 1
        idx = order[start:stop]
        k = stop - start
        if k <= 2:
            for a in range(k):
                cd[idx[a]] = np.inf
        else:
            for j in range(m):
                vals = F[idx, j]
                o = np.argsort(vals, kind="mergesort")
                lo = vals[o[0]]
                hi = vals[o[k - 1]]
                cd[idx[o[0]]] = np.inf
                cd[idx[o[k - 1]]] = np.inf
                span = hi - lo
                if span > 0.0 and np.isfinite(span):
                    for a in range(1, k - 1):
                        cd[idx[o[a]]] += (vals[o[a + 1]] - vals[o[a - 1]]) / span
        start = stop
    return cd


def crowding(F: F64, rank: I64) -> F64:
    """``(n,)`` crowding distance of each member within its own front (normalised by the front's range per
    objective; the extremes of a front, and fronts of one or two members, get +inf)."""
    F = np.asarray(F, dtype=np.float64)
    return _crowding(np.ascontiguousarray(np.where(np.isnan(F), np.inf, F)), np.asarray(rank, dtype=np.int64))


def cdp_better(F: F64, cv: F64, a: I64, b: I64) -> NDArray[np.bool_]:
    """``(k,)`` whether member a[i] constraint-dominates member b[i]: smaller violation, or equal violation
    and Pareto dominance (spec §1.2 ``cdp``)."""
    Fa, Fb = F[a], F[b]
    pareto = (Fa <= Fb).all(axis=1) & (Fa < Fb).any(axis=1)
    return (cv[a] < cv[b]) | ((cv[a] == cv[b]) & pareto)


def epsilon_cv(cv: F64, eps: float) -> F64:
    """Violations under an ε level: what is within ε counts as feasible (0) for ε-CDP comparisons."""
    cv = np.asarray(cv, dtype=np.float64)
    return np.where(cv <= eps, 0.0, cv)
