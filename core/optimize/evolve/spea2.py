"""SPEA2 fitness and environmental selection under a dominance relation (spec §1.2-1.3).

Used by CMOEMT, CMOES, DRLOS-EMCMO, IMTCMO, MCCMO and MOEA/D-CMT's archive. Distances are in raw
(unnormalised) objective space, as PlatEMO's.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
B = NDArray[np.bool_]


def dominance(F: F64, cv: F64 | None = None) -> B:
    """``(n, n)`` matrix D with D[i, j] = i dominates j: plain Pareto dominance (``cv`` None), or constraint
    domination (smaller cv, or equal cv and Pareto dominance)."""
    F = np.where(np.isnan(F), np.inf, np.asarray(F, dtype=np.float64))
    le = (F[:, None, :] <= F[None, :, :]).all(axis=2)
    lt = (F[:, None, :] < F[None, :, :]).any(axis=2)
    D: B = np.asarray(le & lt)
    if cv is not None:
        c = np.where(np.isnan(cv), np.inf, np.asarray(cv, dtype=np.float64))
        D = np.asarray((c[:, None] < c[None, :]) | ((c[:, None] == c[None, :]) & D))
    np.fill_diagonal(D, False)
    return D


@numba.njit(cache=True)
def _distances(F: F64) -> F64:  # pragma: no cover - compiled
    n, m = F.shape
    D = np.empty((n, n))
    for i in range(n):
        D[i, i] = np.inf
        for j in range(i + 1, n):
            s = 0.0
            for k in range(m):
                d = F[i, k] - F[j, k]
                s += d * d
            v = np.sqrt(s)
            if np.isnan(v):  # inf - inf (penalised members)
                v = np.inf
            D[i, j] = v
            D[j, i] = v
    return D


def distances(F: F64) -> F64:
    """``(n, n)`` Euclidean distances between members, +inf on the diagonal (and where undefined)."""
    return _distances(np.ascontiguousarray(F, dtype=np.float64).reshape(len(F), -1))


@numba.njit(cache=True)
def _strength(F: F64, c: F64, constrained: bool) -> F64:  # pragma: no cover - compiled
    # R(i) = sum of S(j) over the members j that dominate i, S(j) = how many j dominates.
    n, m = F.shape
    dom = np.zeros((n, n), dtype=np.bool_)
    S = np.zeros(n)
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            if constrained and c[i] != c[j]:
                d = c[i] < c[j]
            else:
                le, lt = True, False
                for k in range(m):
                    if F[i, k] > F[j, k]:
                        le = False
                        break
                    if F[i, k] < F[j, k]:
                        lt = True
                d = le and lt
            if d:
                dom[i, j] = True
                S[i] += 1.0
    R = np.zeros(n)
    for i in range(n):
        for j in range(n):
            if dom[i, j]:
                R[j] += S[i]
    return R


def fitness(F: F64, cv: F64 | None = None) -> F64:
    """``(n,)`` SPEA2 fitness R(i) + 1 / (σ_i + 2); members with fitness < 1 are the non-dominated ones.

    S(i) counts whom i dominates, R(i) sums S over i's dominators, σ_i is the distance to the k-th nearest
    other member with k = floor(sqrt(n)). Dominance as :func:`dominance` (NaN objectives and violations count
    as +inf).
    """
    n = len(F)
    if n == 0:
        return np.zeros(0)
    Fa = np.where(np.isnan(F), np.inf, np.asarray(F, dtype=np.float64)).reshape(n, -1)
    c = np.zeros(n) if cv is None else np.where(np.isnan(cv), np.inf, np.asarray(cv, dtype=np.float64))
    R = _strength(np.ascontiguousarray(Fa), np.ascontiguousarray(c), cv is not None)
    if n == 1:
        return R + 0.5
    k = int(math.floor(math.sqrt(n)))
    sigma = np.partition(distances(F), min(k, n - 1) - 1, axis=1)[:, min(k, n - 1) - 1]
    with np.errstate(over="ignore"):
        return R + 1.0 / (sigma + 2.0)


@numba.njit(cache=True)
def _row_less(D: F64, order: NDArray[np.int64], alive: B, a: int, b: int) -> bool:  # pragma: no cover - compiled
    # Member a's ascending distances to the alive members, lexicographically smaller than b's?
    n = D.shape[0]
    pa = pb = 0
    while True:
        while pa < n and not alive[order[a, pa]]:
            pa += 1
        while pb < n and not alive[order[b, pb]]:
            pb += 1
        if pa >= n or pb >= n:
            return False
        va, vb = D[a, order[a, pa]], D[b, order[b, pb]]
        if va < vb:
            return True
        if va > vb:
            return False
        pa += 1
        pb += 1


@numba.njit(cache=True)
def _truncate(D: F64, keep: int) -> B:  # pragma: no cover - compiled
    # Each row's neighbours are sorted once; removed members are skipped when rows are read. Only members
    # whose nearest alive distance is the smallest can have the lexicographically smallest row, so only they
    # are compared (from their nearest neighbour on). Same result as re-sorting every row after each removal.
    r = D.shape[0]
    order = np.empty((r, r), dtype=np.int64)
    for i in range(r):
        order[i] = np.argsort(D[i], kind="mergesort")
    alive = np.ones(r, dtype=np.bool_)
    first = np.zeros(r, dtype=np.int64)  # position of each row's nearest alive neighbour in its order
    for _ in range(r - keep):
        m = np.inf
        for i in range(r):
            if alive[i]:
                while first[i] < r and not alive[order[i, first[i]]]:
                    first[i] += 1
                v = D[i, order[i, first[i]]] if first[i] < r else np.inf
                if v < m:
                    m = v
        best = -1
        for i in range(r):
            if not alive[i]:
                continue
            v = D[i, order[i, first[i]]] if first[i] < r else np.inf
            if v != m:
                continue
            if best < 0 or _row_less(D, order, alive, i, best):
                best = i
        alive[best] = False
    return alive


def truncate(F: F64, keep: int) -> B:
    """``(n,)`` mask of the members kept when cutting n down to ``keep``: repeatedly drop the member whose
    ascending distances to the other remaining members are lexicographically smallest (ties: lowest index)."""
    n = len(F)
    if keep >= n:
        return np.ones(n, dtype=bool)
    return _truncate(np.ascontiguousarray(distances(F)), int(keep))


def select(F: F64, n: int, cv: F64 | None = None, fit_F: F64 | None = None) -> tuple[NDArray[np.int64], F64, B]:
    """SPEA2 environmental selection of n members (spec §1.3).

    ``fit_F`` (optional) is the space the fitness is computed in when it differs from the truncation's
    (IMTCMO: fitness on [f, CV], truncation on f).

    Returns:
        order: ``(n,)`` survivor indices sorted by ascending fitness (stable);
        fit: ``(n,)`` their fitness;
        mask: ``(len(F),)`` survivor mask over the input pool.
    """
    fit = fitness(F if fit_F is None else fit_F, cv)
    marked = fit < 1.0
    if marked.sum() < n:
        chosen = np.argsort(fit, kind="stable")[:n]
        mask = np.zeros(len(F), dtype=bool)
        mask[chosen] = True
    elif marked.sum() > n:
        idx = np.flatnonzero(marked)
        mask = np.zeros(len(F), dtype=bool)
        mask[idx[truncate(np.asarray(F)[idx], n)]] = True
    else:
        mask = marked
    surv = np.flatnonzero(mask)
    order = surv[np.argsort(fit[surv], kind="stable")]
    return order, fit[order], mask
