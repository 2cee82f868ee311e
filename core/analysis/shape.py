"""Shape error between a population of paths and a target curve (spec §3)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def _batch(path: F64, target: F64) -> tuple[F64, F64]:
    p = np.asarray(path, dtype=np.float64)
    p = p[None] if p.ndim == 2 else p
    t = np.asarray(target, dtype=np.float64)
    t = t[None] if t.ndim == 2 else t
    if p.shape[1:] != t.shape[1:]:
        raise ValueError(f"path {p.shape[1:]} and target {t.shape[1:]} need the same (n_samples, 2)")
    return p, t


def mse(path: F64, target: F64) -> F64:
    """Time-aligned shape error: mean Euclidean distance, sample i against sample i (spec §3).

    Despite the paper's name it is neither squared nor a sum (its Appendix B values are means).

    Args:
        path: ``(pop, n, 2)`` or ``(n, 2)`` (mm).
        target: ``(n, 2)`` or ``(pop, n, 2)`` (mm).

    Returns:
        ``(pop,)`` mm; NaN where a path has a NaN sample.
    """
    p, t = _batch(path, target)
    return np.hypot(p[..., 0] - t[..., 0], p[..., 1] - t[..., 1]).mean(1)


def mse_phase_optimal(path: F64, target: F64) -> tuple[F64, NDArray[np.int64]]:
    """Shape error at the best cyclic shift, for targets without a time law.

    ``min over k`` of ``mean_i |path_i - target_(i+k mod n)|`` by exhaustive search (n shifts).

    Returns:
        ``(pop,)`` error (mm) and ``(pop,)`` best shift k (samples); NaN error and shift 0 for NaN paths.
    """
    p, t = _batch(path, target)
    n = p.shape[1]
    best = np.full(p.shape[0], np.inf)
    shift = np.zeros(p.shape[0], np.int64)
    for k in range(n):
        tk = np.roll(t, -k, 1)
        e = np.hypot(p[..., 0] - tk[..., 0], p[..., 1] - tk[..., 1]).mean(1)
        better = e < best
        best = np.where(better, e, best)
        shift = np.where(better, k, shift)
    return np.where(np.isfinite(best), best, np.nan), shift
