"""SPEA2 fitness and environmental selection under a dominance relation (spec §1.2-1.3).

Used by CMOEMT, CMOES, DRLOS-EMCMO, IMTCMO, MCCMO and MOEA/D-CMT's archive. Distances are in raw
(unnormalised) objective space, as PlatEMO's.
"""

from __future__ import annotations

import math
import threading
from typing import NamedTuple

import moocore
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


@numba.njit(cache=True, inline="always")  # in the callers' loops: a call per block cost 20 %
def _squared_row(FT: F64, i: int, out: F64, j0: int = 0) -> None:  # pragma: no cover - compiled
    # out[j] = squared distance of member i to member j0 + j (FT is (m, n)), summed objective by objective over
    # contiguous columns, so the loops vectorize.
    w = len(out)
    a, col = FT[0, i], FT[0, j0 : j0 + w]
    for j in range(w):
        d = a - col[j]
        out[j] = d * d
    for q in range(1, FT.shape[0]):
        a, col = FT[q, i], FT[q, j0 : j0 + w]
        for j in range(w):
            d = a - col[j]
            out[j] += d * d


BLOCK = 64  # columns of a distance row computed at a time, in a buffer that stays in the L1 cache


@numba.njit(cache=True)
def _distances(FT: F64, D: F64) -> None:  # pragma: no cover - compiled
    # Into D (n, n), row by row: the squared distances of a block of columns are summed in a small buffer, then
    # rooted into the row, so each entry of the large matrix is written once (writing it is what costs; a
    # symmetric fill wrote down columns).
    n = FT.shape[1]
    buf = np.empty(BLOCK)
    for i in range(n):
        row = D[i]
        for j0 in range(0, n, BLOCK):
            w = min(BLOCK, n - j0)
            _squared_row(FT, i, buf[:w], j0)
            for j in range(w):
                v = np.sqrt(buf[j])
                row[j0 + j] = np.inf if np.isnan(v) else v  # inf - inf (penalised members)
        row[i] = np.inf


def distances(F: F64, out: F64 | None = None) -> F64:
    """``(n, n)`` Euclidean distances between members, +inf on the diagonal (and where undefined); into ``out``
    (an ``(n, n)`` C-contiguous float64 array) if given."""
    F = np.asarray(F, dtype=np.float64).reshape(len(F), -1)
    n = len(F)
    D = np.empty((n, n)) if out is None else out
    _distances(np.ascontiguousarray(F.T), D)
    return D


_scratch = threading.local()
SCRATCH_KEPT = 2048 * 2048  # entries (32 MB): a CMOEA's pools at pop 400 and below


def _distance_scratch(n: int) -> F64:
    """An ``(n, n)`` matrix for a truncation's distances, reused by the thread's later truncations: a fresh one each
    call (7 MB at n = 950) cost the kernel's page faults, 1.5-2.5 ms of a 7-9 ms cut (session 34). Matrices larger
    than ``SCRATCH_KEPT`` entries are made fresh and not kept (one cut of 10 000 points would hold 800 MB)."""
    if n * n > SCRATCH_KEPT:
        return np.empty((n, n))
    buf = getattr(_scratch, "D", None)
    if buf is None or buf.size < n * n:
        buf = _scratch.D = np.empty(max(n * n, 1))
    return buf[: n * n].reshape(n, n)


@numba.njit(cache=True)
def _push(heap: F64, r: int, v: float, k: int) -> None:  # pragma: no cover - compiled
    # Replace the largest value of row r's max-heap of k values (heap[r, :k], largest at heap[r, 0]) with a
    # smaller v and sift it down. (A row index, not a row view: a view costs a reference count each call.)
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
def _groups(FT: F64, c: F64) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:  # pragma: no cover
    # Members sorted by the first objective (FT is (m, n)), grouped into exact copies (every objective and the
    # violation equal): each member's group, each group's first member, and its size; groups are numbered in
    # order of first appearance. Copies are looked for among the run of equal first objectives before each
    # member. A member with an infinite objective is its own group: two such copies are at distance inf - inf
    # (NaN, read as +inf), not 0.
    m, n = FT.shape
    gid = np.empty(n, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    size = np.zeros(n, dtype=np.int64)
    u = 0
    for i in range(n):
        g = -1
        finite = True
        for q in range(m):
            finite &= abs(FT[q, i]) < np.inf
        p = i - 1
        while finite and p >= 0 and FT[0, p] == FT[0, i]:
            same = c[p] == c[i]
            for q in range(1, m):
                same &= FT[q, p] == FT[q, i]
            if same:
                g = gid[p]
                break
            p -= 1
        if g < 0:
            g, first[u] = u, i
            u += 1
        gid[i] = g
        size[g] += 1
    return gid, first[:u], size[:u]


@numba.njit(cache=True)
def _raw(FT: F64, c: F64, w: NDArray[np.int64]) -> F64:  # pragma: no cover - compiled
    # R(i) = sum of S over i's dominators, S(i) = how many i dominates (constraint domination on c; equal c:
    # Pareto), over distinct members each standing for w of them. Each pair is compared once, row i against
    # the earlier rows j < i, over the objectives' columns (FT is (m, n)): the counts of objectives where i is
    # better / worse than each j run over contiguous memory and vectorize, and so do the updates of the j's
    # (S, then R) from row i's relations, which are kept for the second pass.
    m, n = FT.shape
    better = np.empty(n, dtype=np.int32)
    worse = np.empty(n, dtype=np.int32)
    rel = np.empty((n, n), dtype=np.int8)  # rel[i, j], j < i: 1 if j dominates i, 2 if i dominates j, else 0
    S = np.zeros(n, dtype=np.int64)
    for i in range(n):
        for j in range(i):
            better[j], worse[j] = 0, 0
        for q in range(m):
            a, col = FT[q, i], FT[q]
            for j in range(i):
                b = col[j]
                better[j] += np.int32(a < b)
                worse[j] += np.int32(a > b)
        ci, wi, s, row = c[i], w[i], np.int64(0), rel[i]
        for j in range(i):
            cj = c[j]
            eq = ci == cj
            i_dom = (ci < cj) | (eq & (worse[j] == 0) & (better[j] > 0))
            j_dom = (cj < ci) | (eq & (better[j] == 0) & (worse[j] > 0))
            s += w[j] * np.int64(i_dom)
            S[j] += wi * np.int64(j_dom)
            row[j] = np.int8(j_dom) + np.int8(2) * np.int8(i_dom)
        S[i] += s
    wS = w * S
    R = np.zeros(n, dtype=np.int64)
    for i in range(n):
        r, wSi, row = np.int64(0), wS[i], rel[i]
        for j in range(i):
            x = row[j]
            r += np.int64(x == 1) * wS[j]
            R[j] += np.int64(x == 2) * wSi
        R[i] += r
    return R.astype(np.float64)


@numba.njit(cache=True)
def _kth(FT: F64, w: NDArray[np.int64], rows: NDArray[np.int64], k: int) -> F64:  # pragma: no cover - compiled
    # For each of ``rows`` (in that order; FT is (m, n), distinct members sorted by the first objective, each
    # standing for w of them), the k-th smallest squared distance to the other members: w[i] - 1 copies at 0,
    # then each other distinct member w[j] times (sqrt is monotone: it is taken of that one only).
    # It is selected among the values under an upper bound: the row's nearest earlier row e has k others within
    # sigma(e), so the row has k others within d(i, e) + sigma(e) (triangle inequality). The result is exact
    # whatever the bound: with fewer than k values under it, the whole row is used.
    n = FT.shape[1]
    d2 = np.empty(n)
    cand = np.empty(n, dtype=np.int64)  # the candidates' indices
    sig2 = np.empty(len(rows))
    near = np.empty((1, k))
    for t in range(len(rows)):
        i = rows[t]
        kk = k - (w[i] - 1)  # the copies of i fill the first places
        if kk <= 0:
            sig2[t] = 0.0
            continue
        _squared_row(FT, i, d2)
        d2[i] = np.inf
        bound, nearest, e = np.inf, np.inf, -1
        for p in range(t):
            v = d2[rows[p]]
            if v < nearest:
                nearest, e = v, p
        if e >= 0:
            bound = np.sqrt(nearest) + np.sqrt(sig2[e])
            bound = bound * bound * (1.0 + 1e-9)  # a margin for rounding: more candidates, same result
        count = 0
        for j in range(n):
            cand[count] = j
            count += d2[j] <= bound  # NaN (inf - inf) never: it counts as +inf, which a heap of +inf ignores
        total = 0
        for p in range(count):
            total += w[cand[p]]
        if total < kk:
            count = n
            for j in range(n):
                cand[j] = j
        for u in range(kk):
            near[0, u] = np.inf
        for p in range(count):
            j = cand[p]
            v, copies = d2[j], w[j]
            while copies > 0 and v < near[0, 0]:
                _push(near, 0, v, kk)
                copies -= 1
        sig2[t] = near[0, 0]
    return sig2


class _Pool(NamedTuple):
    """The kernels' inputs: the distinct members sorted by the first objective (NaN read as +inf)."""

    FT: F64  # (m, u) their objectives
    c: F64  # (u,) their violations
    w: NDArray[np.int64]  # (u,) how many members each stands for
    of: NDArray[np.int64]  # (n,) which one stands for each input member
    k: int  # floor(sqrt(n)), at most n - 1


def _prepared(F: F64, cv: F64 | None) -> _Pool:
    n = len(F)
    Fa = np.where(np.isnan(F), np.inf, np.asarray(F, dtype=np.float64)).reshape(n, -1)
    c = np.zeros(n) if cv is None else np.where(np.isnan(cv), np.inf, np.asarray(cv, dtype=np.float64))
    order = np.argsort(Fa[:, 0], kind="stable")  # nearby earlier members: tight bounds (same values in any order)
    FT, cs = np.ascontiguousarray(Fa[order].T), np.ascontiguousarray(c[order])
    gid, first, w = _groups(FT, cs)
    of = np.empty(n, dtype=np.int64)
    of[order] = gid
    k = min(int(math.floor(math.sqrt(n))), n - 1)
    if len(w) < n:
        FT, cs = np.ascontiguousarray(FT[:, first]), cs[first]
    return _Pool(FT, cs, w, of, k)


def _density(R: F64, sig2: F64) -> F64:
    return R + 1.0 / (np.sqrt(sig2) + 2.0)


def fitness(F: F64, cv: F64 | None = None) -> F64:
    """``(n,)`` SPEA2 fitness R(i) + 1 / (σ_i + 2); members with fitness < 1 are the non-dominated ones.

    S(i) counts whom i dominates, R(i) sums S over i's dominators, σ_i is the distance to the k-th nearest
    other member with k = floor(sqrt(n)). Dominance as :func:`dominance` (NaN objectives and violations count
    as +inf). Exact copies are computed once.
    """
    n = len(F)
    if n == 0:
        return np.zeros(0)
    if n == 1:
        return np.full(1, 0.5)
    p = _prepared(F, cv)
    return _density(_raw(p.FT, p.c, p.w), _kth(p.FT, p.w, np.arange(len(p.w)), p.k))[p.of]


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


LISTED = 8  # nearest members each row lists, in ascending distance, for finding its next levels


@numba.njit(cache=True)
def _relist(D: F64, alive: B, row: int, after: float, lv: F64, li: NDArray[np.int64],
            cap: float) -> None:  # pragma: no cover - compiled
    # lv[row], li[row]: the LISTED smallest distances of ``row`` to alive members that are > ``after``, ascending,
    # and who is at each (+inf, -1 past the end). Insertion into a sorted list: most values fail the first test.
    # ``cap`` (+inf if none): a value known to be at least the LISTED-th smallest, so that fewer values are
    # inserted on the way; if the list is not full under it after all, it is made again without.
    L = lv.shape[1]
    for _ in range(2):
        for p in range(L):
            lv[row, p], li[row, p] = cap, -1
        for j in range(D.shape[0]):
            d = D[row, j]
            if d < lv[row, L - 1] and d > after and alive[j]:
                p = L - 1
                while p > 0 and lv[row, p - 1] > d:
                    lv[row, p], li[row, p] = lv[row, p - 1], li[row, p - 1]
                    p -= 1
                lv[row, p], li[row, p] = d, j
        if cap == np.inf or li[row, L - 1] >= 0:
            return
        cap = np.inf


@numba.njit(cache=True)
def _next_listed(D: F64, alive: B, row: int, after: float, lv: F64,
                 li: NDArray[np.int64]) -> tuple[float, int]:  # pragma: no cover - compiled
    # As _next_value, read from the row's list: every member nearer than its last entry is listed, so a value
    # below the last entry is the next one with its full count. Otherwise the list is made again past
    # ``after``; a value that reaches the end of the new list too is counted by a scan.
    L = lv.shape[1]
    for attempt in range(2):
        p = 0
        while p < L and (lv[row, p] <= after or (li[row, p] >= 0 and not alive[li[row, p]])):
            p += 1
        if p < L:
            v = lv[row, p]
            if v == np.inf:  # the rest of the row is +inf
                return np.inf, 0
            count = 0
            while p < L and lv[row, p] == v:
                count += alive[li[row, p]]
                p += 1
            if p < L:
                return v, count
        if attempt == 0:
            _relist(D, alive, row, after, lv, li, np.inf)
    return _next_value(D, alive, row, after)


@numba.njit(cache=True)
def _fill(D: F64, alive: B, row: int, near: F64, start: int, lv: F64,
          li: NDArray[np.int64]) -> None:  # pragma: no cover - compiled
    # near[row, 2j], near[row, 2j + 1] for j >= start: the next distinct smallest distances of ``row`` to alive
    # members after level start - 1's value, and how many alive members are at each (+inf, 0: none).
    after = -np.inf if start == 0 else near[row, 2 * start - 2]
    for j in range(start, near.shape[1] // 2):
        v, c = _next_listed(D, alive, row, after, lv, li) if after < np.inf else (np.inf, 0)
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


@numba.njit(cache=True, fastmath={"nnan", "nsz"})
def _smallest(a: F64) -> float:  # pragma: no cover - compiled
    # The smallest value of a NaN-free array (+inf allowed): the flags let the loop vectorize.
    m = np.inf
    for v in a:
        m = min(m, v)
    return m


FREE, TIED, ZERO = 0, 1, 2  # _truncate's status


@numba.njit(cache=True)
def _truncate(D: F64, F: F64, keep: int, distinct: bool) -> tuple[B, int]:  # pragma: no cover - compiled
    # The alive mask and a status: FREE (no removal was decided by index: the same points in another order
    # lose the same members), TIED (one may have been: two candidate rows were equal), or ZERO (``distinct``,
    # the rows are distinct points and copies are not looked for, but two are at distance 0: nothing was cut).
    # Each alive row keeps its LEVELS smallest distinct distances to alive members and their counts; a removal
    # updates the rows it touches (a count drops; a level whose count reaches zero is dropped and the last
    # level found again by one scan). Only rows with the smallest first value are candidates, compared by
    # :func:`_less`: O(r^2) in all, where comparing whole rows made exact duplicates (CMOES's unions) and
    # mutual nearest neighbours cost a sort per row.
    r = D.shape[0]
    alive = np.ones(r, dtype=np.bool_)
    order = np.empty((r, r), dtype=np.int64)  # rows sorted on demand (_sorted_less); pages touched only then
    sorted_ = np.zeros(r, dtype=np.bool_)
    near = np.empty((r, 2 * LEVELS))
    lv = np.empty((r, min(LISTED, r)))
    li = np.empty((r, min(LISTED, r)), dtype=np.int64)
    # Exact copies first. While two members are at distance 0 the smallest first level is 0, so every removal
    # takes a copy, and of identical rows the lowest index: a point's copies go in index order, its last one
    # stays, and the rest is truncated among distinct points. Taken in one step when the removals cover all the
    # copies, and when every distance of 0 is between copies (not two points whose difference underflows).
    copies, exact = 0, True
    for i in range(0 if distinct else r):
        for j in range(i + 1, r):
            if D[i, j] == 0.0:
                if _same_point(F, i, j):
                    if alive[i]:
                        alive[i] = False
                        copies += 1
                else:
                    exact = False
    if not exact or copies > r - keep:
        alive[:] = True
        copies = 0
    L = lv.shape[1]
    for i in range(r):
        near[i, 0], near[i, 1] = np.inf, 0.0
        if not alive[i]:
            continue
        # The nearest earlier row e has its L nearest within lv[e, L - 1], so this row has L others (e and
        # those, less itself) within D[i, e] + lv[e, L - 1] (triangle inequality): a cap for its list.
        e, nearest = -1, np.inf
        for j in range(i):
            if alive[j] and D[i, j] < nearest:
                e, nearest = j, D[i, j]
        cap = np.inf if e < 0 or L >= r - 1 else (nearest + lv[e, L - 1]) * (1.0 + 1e-9)
        _relist(D, alive, i, -np.inf, lv, li, cap)
        _fill(D, alive, i, near, 0, lv, li)
        if distinct and near[i, 0] == 0.0:
            return alive, ZERO
    last = 2 * LEVELS - 2
    # Contiguous copies of each row's first and last level (dead rows: +inf, -inf), so the two scans a removal
    # makes over all rows are plain comparisons over arrays: the smallest first level, and the rows whose
    # levels reach the removed member's distance (the few that change).
    lead, tail = near[:, 0].copy(), np.where(alive, near[:, last], -np.inf)
    hit = np.empty(r, dtype=np.bool_)
    tied = copies > 0
    for _ in range(r - keep - copies):
        m = _smallest(lead)
        best = -1
        for i in range(r):  # ascending: ties go to the lowest index
            if lead[i] == m and alive[i]:
                if best < 0 or _less(D, F, order, sorted_, alive, near, i, best):
                    best = i
                elif not _less(D, F, order, sorted_, alive, near, best, i):
                    tied = True
        alive[best] = False
        lead[best], tail[best] = np.inf, -np.inf
        row = D[best]  # D is symmetric: the row is contiguous, the column is not
        for i in range(r):
            hit[i] = row[i] <= tail[i]
        for i in range(r):
            if not hit[i]:
                continue
            d = row[i]
            for j in range(LEVELS):
                if d == near[i, 2 * j]:
                    near[i, 2 * j + 1] -= 1
                    if near[i, 2 * j + 1] == 0:
                        for q in range(2 * j, 2 * LEVELS - 2):
                            near[i, q] = near[i, q + 2]
                        _fill(D, alive, i, near, LEVELS - 1, lv, li)
                        lead[i], tail[i] = near[i, 0], near[i, last]
                    break
                if d < near[i, 2 * j]:
                    break
    return alive, TIED if tied else FREE


Cuts = dict[tuple[int, tuple[int, ...], bytes], tuple[B, bool, NDArray[np.int64]]]
"""Truncations already made in a generation, keyed on keep and the rows sorted by their first objective (the same
points in any order): the mask in that order, whether it holds for any order, and the order it was made in.
Selections that cut the same members pass one dict: CMOES's P1 and P2; CMOEMT's P1 and P3, IMTCMO's and
DRLOS-EMCMO's P1 and P2, MCCMO's archive and P0 when every member is feasible."""


def truncate(F: F64, keep: int, cuts: Cuts | None = None) -> B:
    """``(n,)`` mask of the members kept when cutting n down to ``keep``: repeatedly drop the member whose
    ascending distances to the other remaining members are lexicographically smallest (ties: lowest index).
    ``cuts``: earlier results, looked up and added to. A result is reused for the same rows in another order
    when no removal was decided by index; copies of a point keep their last one in either order."""
    n = len(F)
    if keep >= n:
        return np.ones(n, dtype=bool)
    F = np.ascontiguousarray(F, dtype=np.float64).reshape(n, -1)
    if cuts is None:
        return _cut(F, keep)[0]
    lex = np.argsort(F[:, 0], kind="stable")  # copies stay in input order; equal first objectives of other
    # points too, so such points in another order are a new key (cut anew): a sort by every objective cost 6x
    key = (int(keep), F.shape, F[lex].tobytes())
    got = cuts.get(key)
    if got is not None and (got[1] or np.array_equal(got[2], lex)):
        mask = np.empty(n, dtype=bool)
        mask[lex] = got[0]
        return mask
    mask, free = _cut(F, keep)
    if got is None:
        cuts[key] = (mask[lex], free, lex)
    return mask


def _cut(F: F64, keep: int) -> tuple[B, bool]:
    """:func:`truncate` of a contiguous ``(n, m)`` F to ``keep`` < n members, and whether the same points in any
    order give the same mask (no removal decided by index)."""
    n = len(F)
    p = _prepared(F, None)
    if keep <= len(p.w) < n or len(p.w) == n:
        # Exact copies go first, each point's last one stays (see _truncate): the rest is truncated among the
        # distinct points alone, unless two of them are at distance 0 (a difference that underflows).
        last = np.sort(np.argsort(p.of, kind="stable")[np.cumsum(p.w) - 1])
        alive, status = _truncate(distances(F[last], _distance_scratch(len(last))), F[last], int(keep), True)
        if status != ZERO:
            mask = np.zeros(n, dtype=bool)
            mask[last[alive]] = True
            return mask, status == FREE
    return _truncate(distances(F, _distance_scratch(n)), F, int(keep), False)[0], False


def survivors(F: F64, n: int, cv: F64 | None = None) -> B:
    """``(len(F),)`` the mask of :func:`select`'s survivors, without their fitness and order where they are not
    needed to find them (at least n non-dominated members): DRLOS-EMCMO's success counts."""
    return select(F, n, cv, rank=False)[2]


def select(F: F64, n: int, cv: F64 | None = None, fit_F: F64 | None = None, fill: bool = True,
           cuts: Cuts | None = None, rank: bool = True) -> tuple[NDArray[np.int64], F64, B]:
    """SPEA2 environmental selection of n members (spec §1.3).

    ``fit_F`` (optional) is the space the fitness is computed in when it differs from the truncation's
    (IMTCMO: fitness on [f, CV], truncation on f). ``fill=False`` keeps only non-dominated members, fewer than
    n if so (CMOES's EvenSearch). ``cuts``: truncations already made, passed on to :func:`truncate`.
    ``rank=False`` (see :func:`survivors`): the survivors in index order with fitness 0 when at least n are
    non-dominated.

    Returns:
        order: survivor indices sorted by ascending fitness (stable), n of them (fewer without ``fill``);
        fit: their fitness;
        mask: ``(len(F),)`` survivor mask over the input pool.

    When at least n members are non-dominated (R = 0), they are found by a non-dominated filter and only the
    survivors' densities are computed: R of the others decides nothing.
    """
    space = F if fit_F is None else fit_F
    size = len(space)
    if size < 2 or n <= 0:  # nobody, or one member (non-dominated)
        return _lowest(fitness(space, cv), n)
    p = _prepared(space, cv)
    marked = _nondominated(p)[p.of]
    count = int(marked.sum())
    if count < n and fill:
        R = _raw(p.FT, p.c, p.w)[p.of]
        fit = _density(R, _kth(p.FT, p.w, np.arange(len(p.w)), p.k)[p.of])
        return _lowest(fit, n)
    if count > n:
        idx = np.flatnonzero(marked)
        mask = np.zeros(size, dtype=bool)
        mask[idx[truncate(np.asarray(F)[idx], n, cuts)]] = True
    else:
        mask = marked
    surv = np.flatnonzero(mask)
    if not rank:
        return surv, np.zeros(len(surv)), mask
    rows = np.unique(p.of[surv])  # in the kernels' order, for tight bounds
    sigma2 = np.empty(len(p.w))
    sigma2[rows] = _kth(p.FT, p.w, rows, p.k)
    fit = np.empty(size)
    fit[surv] = _density(np.zeros(len(surv)), sigma2[p.of[surv]])
    return _ordered(fit, mask)


def _nondominated(p: _Pool) -> B:
    """``(u,)`` True for the distinct members no other dominates: under constraint domination, the Pareto set
    of the members with the smallest violation (moocore's filter: O(u log u) for 2 and 3 objectives)."""
    least = np.flatnonzero(p.c == p.c.min())
    out = np.zeros(len(p.c), dtype=bool)
    out[least] = moocore.is_nondominated(np.ascontiguousarray(p.FT[:, least].T), keep_weakly=True)
    return out


def _lowest(fit: F64, n: int) -> tuple[NDArray[np.int64], F64, B]:
    """The n members of lowest fitness (ties: the lower index), as :func:`select` returns them."""
    mask = np.zeros(len(fit), dtype=bool)
    mask[np.argsort(fit, kind="stable")[: max(n, 0)]] = True
    return _ordered(fit, mask)


def _ordered(fit: F64, mask: B) -> tuple[NDArray[np.int64], F64, B]:
    surv = np.flatnonzero(mask)
    order = surv[np.argsort(fit[surv], kind="stable")]
    return order, fit[order], mask
