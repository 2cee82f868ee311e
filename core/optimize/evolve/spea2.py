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
def _push(heap: F64, r: int, v: float) -> None:  # pragma: no cover - compiled
    # Replace the largest value of row r's max-heap (heap[r, 0]) with a smaller v and sift it down. (A row
    # index, not a row view: a view costs a reference count each call.)
    k = heap.shape[1]
    p = 0
    while True:
        c = 2 * p + 1
        if c >= k:
            break
        if c + 1 < k and heap[r, c + 1] > heap[r, c]:
            c += 1
        if heap[r, c] <= v:
            break
        heap[r, p] = heap[r, c]
        p = c
    heap[r, p] = v


@numba.njit(cache=True)
def _fitness(F: F64, c: F64, constrained: bool, k: int) -> F64:  # pragma: no cover - compiled
    # One pass over the pairs i < j: who dominates whom (branch-free counts; 1: i over j, 2: j over i, kept
    # row-wise), S(i) = how many i dominates, and each row's k smallest squared distances in a max-heap (its
    # root is the k-th); then R(j) = sum of S over j's dominators. No (n, n) distance matrix is built
    # (np.partition over one was the largest cost of a CMOES generation, whose pools reach 800 members).
    # The caller sorts the members by the first objective; i runs down and j up, so every row meets its
    # members nearest in that order first, and its heap holds small distances early: ~35 % fewer pushes.
    n, m = F.shape
    who = np.zeros((n, n), dtype=np.int8)
    S = np.zeros(n)
    near = np.full((n, k), np.inf)
    for i in range(n - 1, -1, -1):
        for j in range(i + 1, n):
            if constrained and c[i] != c[j]:
                ij, ji = c[i] < c[j], c[j] < c[i]
            else:
                lt, gt = 0, 0
                for q in range(m):
                    lt += F[i, q] < F[j, q]
                    gt += F[i, q] > F[j, q]
                ij, ji = gt == 0 and lt > 0, lt == 0 and gt > 0
            who[i, j] = 1 if ij else (2 if ji else 0)
            S[i] += ij
            S[j] += ji
            s = 0.0  # squared distance; sqrt is monotone, so it is taken of the k-th only
            for q in range(m):
                d = F[i, q] - F[j, q]
                s += d * d
            if np.isnan(s):  # inf - inf (penalised members)
                s = np.inf
            if s < near[i, 0]:
                _push(near, i, s)
            if s < near[j, 0]:
                _push(near, j, s)
    R = np.zeros(n)
    for i in range(n):
        for j in range(i + 1, n):
            if who[i, j] == 1:
                R[j] += S[i]
            elif who[i, j] == 2:
                R[i] += S[j]
    out = np.empty(n)
    for i in range(n):
        out[i] = R[i] + 1.0 / (np.sqrt(near[i, 0]) + 2.0)
    return out


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
    if n == 1:
        return np.full(1, 0.5)
    k = int(math.floor(math.sqrt(n)))
    order = np.argsort(Fa[:, 0], kind="stable")  # the kernel's visiting order (same values in any order)
    out = np.empty(n)
    out[order] = _fitness(np.ascontiguousarray(Fa[order]), np.ascontiguousarray(c[order]), cv is not None,
                          min(k, n - 1))
    return out


@numba.njit(cache=True)
def _next_value(D: F64, alive: B, row: int, after: float) -> tuple[float, int]:  # pragma: no cover - compiled
    # The smallest distance of ``row`` to an alive member that is > ``after``, and how many alive members are at it.
    v, count = np.inf, 0
    for j in range(D.shape[0]):
        if alive[j]:
            d = D[row, j]
            if d > after:
                if d < v:
                    v, count = d, 1
                elif d == v:
                    count += 1
    return v, count


@numba.njit(cache=True)
def _sorted_less(D: F64, order: NDArray[np.int64], sorted_: B, alive: B, a: int,
                 b: int) -> bool:  # pragma: no cover - compiled
    # Are a's ascending distances to the alive members lexicographically smaller than b's? Each row is sorted
    # once, on first need, and read with its dead members skipped.
    for k in (a, b):
        if not sorted_[k]:
            order[k] = np.argsort(D[k], kind="mergesort")
            sorted_[k] = True
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
        if va != vb:
            return va < vb
        pa += 1
        pb += 1


LEVELS = 3  # distinct smallest distances each row keeps during truncation


@numba.njit(cache=True)
def _fill(D: F64, alive: B, row: int, near: F64, start: int) -> None:  # pragma: no cover - compiled
    # near[row, 2j], near[row, 2j + 1] for j >= start: the next distinct smallest distances of ``row`` to alive
    # members after level start - 1's value, and how many alive members are at each (+inf, 0: none).
    after = -np.inf if start == 0 else near[row, 2 * start - 2]
    for j in range(start, near.shape[1] // 2):
        v, c = _next_value(D, alive, row, after) if after < np.inf else (np.inf, 0)
        near[row, 2 * j], near[row, 2 * j + 1] = v, c
        after = v


@numba.njit(cache=True)
def _same_point(F: F64, a: int, b: int) -> bool:  # pragma: no cover - compiled
    for q in range(F.shape[1]):
        if F[a, q] != F[b, q]:
            return False
    return True


@numba.njit(cache=True)
def _less(D: F64, F: F64, order: NDArray[np.int64], sorted_: B, alive: B, near: F64, a: int,
          b: int) -> bool:  # pragma: no cover - compiled
    # Is a's row lexicographically smaller than b's? Their first distinct values and counts decide nearly
    # always (more copies of an equal value = smaller); two copies of one point have equal rows (their
    # distances to every other member are the same numbers); anything else is compared on rows sorted once.
    for j in range(near.shape[1] // 2):
        va, vb = near[a, 2 * j], near[b, 2 * j]
        if va != vb:
            return va < vb
        if va == np.inf:  # the rest of both rows is +inf
            return False
        if near[a, 2 * j + 1] != near[b, 2 * j + 1]:
            return near[a, 2 * j + 1] > near[b, 2 * j + 1]
    if _same_point(F, a, b):
        return False
    return _sorted_less(D, order, sorted_, alive, a, b)


@numba.njit(cache=True)
def _truncate(D: F64, F: F64, keep: int) -> B:  # pragma: no cover - compiled
    # Each alive row keeps its LEVELS smallest distinct distances to alive members and their counts; a removal
    # updates the rows it touches (a count drops; a level whose count reaches zero is dropped and the last
    # level found again by one scan). Only rows with the smallest first value are candidates, compared by
    # :func:`_less`: O(r^2) in all, where comparing whole rows made exact duplicates (CMOES's unions) and
    # mutual nearest neighbours cost a sort per row.
    r = D.shape[0]
    alive = np.ones(r, dtype=np.bool_)
    order = np.empty((r, r), dtype=np.int64)  # rows sorted on demand (_sorted_less)
    sorted_ = np.zeros(r, dtype=np.bool_)
    near = np.empty((r, 2 * LEVELS))
    for i in range(r):
        _fill(D, alive, i, near, 0)
    for _ in range(r - keep):
        m = np.inf
        for i in range(r):
            if alive[i] and near[i, 0] < m:
                m = near[i, 0]
        best = -1
        for i in range(r):
            if alive[i] and near[i, 0] == m and (best < 0 or _less(D, F, order, sorted_, alive, near, i, best)):
                best = i
        alive[best] = False
        for i in range(r):
            if not alive[i]:
                continue
            d = D[best, i]  # D is symmetric: the row is contiguous, the column is not
            for j in range(LEVELS):
                if d == near[i, 2 * j]:
                    near[i, 2 * j + 1] -= 1
                    if near[i, 2 * j + 1] == 0:
                        for q in range(2 * j, 2 * LEVELS - 2):
                            near[i, q] = near[i, q + 2]
                        _fill(D, alive, i, near, LEVELS - 1)
                    break
                if d < near[i, 2 * j]:
                    break
    return alive


def truncate(F: F64, keep: int) -> B:
    """``(n,)`` mask of the members kept when cutting n down to ``keep``: repeatedly drop the member whose
    ascending distances to the other remaining members are lexicographically smallest (ties: lowest index)."""
    n = len(F)
    if keep >= n:
        return np.ones(n, dtype=bool)
    F = np.ascontiguousarray(F, dtype=np.float64).reshape(n, -1)
    return _truncate(np.ascontiguousarray(distances(F)), F, int(keep))


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
