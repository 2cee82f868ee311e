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


def distances(F: F64) -> F64:
    """``(n, n)`` Euclidean distances between members, +inf on the diagonal."""
    F = np.asarray(F, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf (penalised members): NaN, then +inf below
        diff = F[:, None, :] - F[None, :, :]
        D = np.sqrt((diff * diff).sum(axis=2))
    D = np.where(np.isnan(D), np.inf, D)
    np.fill_diagonal(D, np.inf)
    return D


def fitness(F: F64, cv: F64 | None = None) -> F64:
    """``(n,)`` SPEA2 fitness R(i) + 1 / (σ_i + 2); members with fitness < 1 are the non-dominated ones.

    S(i) counts whom i dominates, R(i) sums S over i's dominators, σ_i is the distance to the k-th nearest
    other member with k = floor(sqrt(n)).
    """
    n = len(F)
    if n == 0:
        return np.zeros(0)
    D = dominance(F, cv)
    S = D.sum(axis=1).astype(np.float64)
    R = (D * S[:, None]).sum(axis=0)
    if n == 1:
        return R + 0.5
    dist = np.sort(distances(F), axis=1)
    k = int(math.floor(math.sqrt(n)))
    sigma = dist[:, min(k, n - 1) - 1]
    with np.errstate(over="ignore"):
        return R + 1.0 / (sigma + 2.0)


@numba.njit(cache=True)
def _truncate(D: F64, keep: int) -> B:  # pragma: no cover - compiled
    r = D.shape[0]
    S = np.empty((r, r))
    for i in range(r):
        S[i] = np.sort(D[i])
    alive = np.ones(r, dtype=np.bool_)
    length = r
    for _ in range(r - keep):
        best = -1
        for i in range(r):
            if not alive[i]:
                continue
            if best < 0:
                best = i
                continue
            for c in range(length):
                if S[i, c] < S[best, c]:
                    best = i
                    break
                if S[i, c] > S[best, c]:
                    break
        alive[best] = False
        for i in range(r):
            if not alive[i]:
                continue
            v = D[i, best]
            lo, hi = 0, length - 1
            while lo < hi:  # first position holding v in the sorted row
                mid = (lo + hi) // 2
                if S[i, mid] < v:
                    lo = mid + 1
                else:
                    hi = mid
            for c in range(lo, length - 1):
                S[i, c] = S[i, c + 1]
        length -= 1
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
