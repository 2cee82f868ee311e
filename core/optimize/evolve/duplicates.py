"""Exact-duplicate elimination over arrays (what pymoo's default duplicate elimination does for NSGA-II)."""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
B = NDArray[np.bool_]


@numba.njit(cache=True)
def _fresh(A: F64, start: int) -> B:  # pragma: no cover - compiled
    n, d = A.shape
    # A sequential weighted sum per row: identical rows get bit-identical keys (no BLAS, no SIMD reordering).
    key = np.empty(n)
    for i in range(n):
        s = 0.0
        for j in range(d):
            s += A[i, j] * (1.0 + 0.6180339887498949 * j)
        key[i] = s
    order = np.argsort(key, kind="mergesort")  # stable: equal keys stay in index order
    keep = np.ones(n, dtype=np.bool_)
    g = 0
    while g < n:
        h = g + 1
        while h < n and key[order[h]] == key[order[g]]:
            h += 1
        for a in range(g + 1, h):  # compare with every earlier member of the group (exact, not just the key)
            i = order[a]
            for b in range(g, a):
                k = order[b]
                if not keep[k]:
                    continue
                same = True
                for j in range(d):
                    if A[i, j] != A[k, j]:
                        same = False
                        break
                if same:
                    keep[i] = False
                    break
        g = h
    return keep[start:]


def fresh_rows(C: F64, existing: F64) -> B:
    """``(n,)`` mask of the rows of C equal to no row of ``existing`` and no earlier row of C (exact equality;
    a row holding NaN equals nothing)."""
    C = np.asarray(C, dtype=np.float64)
    if len(C) == 0:
        return np.zeros(0, dtype=bool)
    E = np.asarray(existing, dtype=np.float64).reshape(-1, C.shape[1])
    return _fresh(np.ascontiguousarray(np.vstack([E, C])), len(E))
