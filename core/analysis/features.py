"""Feature points t1 ... t8 of a bench trajectory (spec §4), for a batch of closed leg-frame paths.

A path is ``(pop, n_samples, 2)`` in the leg frame (y up, stance the lowest half-cycle); sample i
is at time ``t_i = i T / n_samples`` and crank angle ``2 pi i / n_samples``. Times are handled as
fractional sample indices ``q`` (``t = q T / n``); positions between samples come from the periodic
cubic Hermite interpolant built on the samples and their d/dtheta derivatives.

Rules where the paper and spec are silent (see ``docs/metrics.md``):
- landing candidates are the sign changes of ``f(t) = y(t) - y(t + T/2)``; among all of them the
  one whose half-cycle ``[t1, t1 + T/2]`` has the lowest mean height is the landing t1;
- several landing-root pairs: ``root_violation`` = the summed peak ``|f|`` (mm) of every lobe of
  ``|f|`` but the two largest (the main pair), less ``LOBE_TOL`` each (zero when the extra roots merge away,
  or are round-off);
- no root (``f`` identically zero, a path folded on itself): ``root_violation = 1`` mm;
- the turning number of the sampled polygon must be +-1 (a simple closed curve); otherwise the
  path self-intersects (``turning`` reports it; the constraint is in ``core.analysis.metrics``);
- a row with any NaN sample is NaN everywhere with ``root_violation = inf``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

FEATURE_NAMES = ("t1", "t2", "t3", "t4", "t5", "t6", "t7", "t8")
DEFAULT_PERIOD = 2.0  # s; spec §4: the paper's "2 Hz" means omega = pi rad/s
NO_ROOT_VIOLATION = 1.0  # mm, for a finite path whose f(t) vanishes identically
# mm: an extra lobe of |f| this small is round-off, not a second landing. A dwell (f = 0 over part of the cycle, a
# flat stance longer than T/2) changes sign on noise alone: 1e-13 mm of it made such a path infeasible.
LOBE_TOL = 1e-9
ROOT_ITERATIONS = 6  # safeguarded Newton steps per landing root


@dataclass(frozen=True)
class FeaturePoints:
    """Feature points of a population of bench trajectories.

    Attributes:
        index: ``(pop, 8)`` fractional sample index of t1 ... t8, in ``[0, n_samples)``.
        times: ``(pop, 8)`` t1 ... t8 (s), in ``[0, period)``.
        points: ``(pop, 8, 2)`` leg-frame positions (mm).
        tangents: ``(pop, 8, 2)`` d/dtheta at those times (mm/rad).
        n_roots: ``(pop,)`` number of sign changes of ``y(t) - y(t + T/2)`` over a cycle (2 when regular).
        root_violation: ``(pop,)`` >= 0 (mm), 0 iff there is exactly one landing/take-off pair.
        turning: ``(pop,)`` turning number of the sampled polygon (+1 counter-clockwise, -1 clockwise).
        valid: ``(pop,)`` True where the path is finite.
        period: crank period T (s).
        n_samples: samples per cycle.
    """

    index: F64
    times: F64
    points: F64
    tangents: F64
    n_roots: NDArray[np.int64]
    root_violation: F64
    turning: NDArray[np.int64]
    valid: NDArray[np.bool_]
    period: float
    n_samples: int

    def time(self, name: str) -> F64:
        """``(pop,)`` the time (s) of a feature point by name (``"t1"``)."""
        return self.times[:, FEATURE_NAMES.index(name)]

    def point(self, name: str) -> F64:
        """``(pop, 2)`` the leg-frame position (mm) of a feature point by name."""
        return self.points[:, FEATURE_NAMES.index(name)]


def periodic_derivative(path: F64) -> F64:
    """d/dtheta of a uniformly sampled closed path by 4th-order central differences.

    Args:
        path: ``(pop, n, 2)`` (mm), samples uniform in theta over one turn.

    Returns:
        ``(pop, n, 2)`` (mm/rad).
    """
    n = path.shape[1]
    d = (8.0 * (np.roll(path, -1, 1) - np.roll(path, 1, 1)) - (np.roll(path, -2, 1) - np.roll(path, 2, 1))) / 12.0
    return d * (n / (2.0 * np.pi))


def hermite(path: F64, dpath: F64, q: F64) -> tuple[F64, F64]:
    """Periodic cubic Hermite interpolation at fractional sample indices.

    Args:
        path: ``(pop, n, 2)`` samples (mm).
        dpath: ``(pop, n, 2)`` d/dtheta at the samples (mm/rad).
        q: ``(pop, k)`` fractional indices (any real; taken modulo n). Must be finite.

    Returns:
        ``(pop, k, 2)`` positions (mm) and ``(pop, k, 2)`` d/dtheta (mm/rad).
    """
    n = path.shape[1]
    h = 2.0 * np.pi / n
    fl = np.floor(q)
    u = (q - fl)[..., None]
    i0 = fl.astype(np.int64) % n
    i1 = (i0 + 1) % n
    p0 = np.take_along_axis(path, i0[..., None], 1)
    p1 = np.take_along_axis(path, i1[..., None], 1)
    m0 = np.take_along_axis(dpath, i0[..., None], 1) * h
    m1 = np.take_along_axis(dpath, i1[..., None], 1) * h
    u2, u3 = u * u, u * u * u
    pos = (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1
    der = (6 * u2 - 6 * u) * p0 + (3 * u2 - 4 * u + 1) * m0 + (-6 * u2 + 6 * u) * p1 + (3 * u2 - 2 * u) * m1
    return pos, der / h


def half_shift(path: F64, dpath: F64) -> tuple[F64, F64]:
    """The path and its derivative half a period later, ``C(t + T/2)`` at every sample."""
    n = path.shape[1]
    if n % 2 == 0:
        return np.roll(path, -n // 2, 1), np.roll(dpath, -n // 2, 1)
    q = np.broadcast_to(np.arange(n) + n / 2.0, path.shape[:2])
    return hermite(path, dpath, q)


def _circular_rel(n: int, start: F64) -> F64:
    """``(pop, n)`` position of every sample after ``start`` (fractional index), in ``[0, n)``."""
    return (np.arange(n)[None, :] - start[:, None]) % n


def _parabolic(v: F64, i: NDArray[np.int64]) -> F64:
    """Sub-sample offset in [-0.5, 0.5] of the vertex of the parabola through v[i-1], v[i], v[i+1]."""
    n = v.shape[1]
    a = np.take_along_axis(v, ((i - 1) % n)[:, None], 1)[:, 0]
    b = np.take_along_axis(v, i[:, None], 1)[:, 0]
    c = np.take_along_axis(v, ((i + 1) % n)[:, None], 1)[:, 0]
    den = a - 2.0 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(den != 0.0, 0.5 * (a - c) / den, 0.0)
    return np.clip(d, -0.5, 0.5)


TIE = 1e-9  # samples within this fraction of the path's largest |coordinate| of an extremum tie with it


@numba.njit(cache=True)
def _first_extremum(v: F64, mask: NDArray[np.bool_], largest: bool) -> NDArray[np.int64]:  # pragma: no cover
    # Per row: argmin (argmax) over the masked samples as numpy finds it (the first NaN if any; 0 if none is
    # masked), then, if it is finite, the first masked sample within TIE x the largest finite masked |v| of it.
    pop, n = v.shape
    out = np.zeros(pop, dtype=np.int64)
    for r in range(pop):
        best, e, scale, nan_at = -1, 0.0, 0.0, -1
        for j in range(n):
            if not mask[r, j]:
                continue
            x = v[r, j]
            if np.isnan(x):
                if nan_at < 0:
                    nan_at = j
                continue
            if np.isfinite(x):
                scale = max(scale, abs(x))
            if best < 0 or (x > e if largest else x < e):
                best, e = j, x
        if nan_at >= 0:
            out[r] = nan_at
            continue
        if best < 0:
            continue
        out[r] = best
        tol = TIE * scale
        if np.isfinite(e):
            for j in range(best):
                if mask[r, j] and abs(v[r, j] - e) <= tol:
                    out[r] = j
                    break
    return out


def _extremum(v: F64, mask: NDArray[np.bool_], largest: bool) -> tuple[NDArray[np.int64], F64]:
    """Index of the largest (smallest) masked sample and its parabolic sub-sample index.

    Samples that tie with the extremum to within rounding (TIE) go to the first in sample order: a symmetric
    path has two equal left-most points, and which one argmin found depended on the last bit (a translation
    by 181 mm moved t4 from 0.93 s to 1.07 s of a 2 s cycle).
    """
    i = _first_extremum(np.asarray(v, dtype=np.float64), np.asarray(mask), largest)  # strided views as they are
    return i, i + _parabolic(v, i)


def _landing(y: F64, f: F64, df: F64) -> tuple[F64, NDArray[np.int64], F64]:
    """Landing index q1, root count and root violation from ``f = y(t) - y(t + T/2)``.

    Sign changes are taken on ``f >= 0`` so exact zeros at samples (polygonal or analytic paths)
    count once. Each root is refined on the Hermite cubic of f (safeguarded Newton steps from the secant).
    """
    pop, n = f.shape
    h = 2.0 * np.pi / n
    s = f >= 0.0
    f1 = np.roll(f, -1, 1)
    cross = s != np.roll(s, -1, 1)
    n_roots = cross.sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(cross, f / (f - f1), 0.0)
    m0, m1 = df * h, np.roll(df, -1, 1) * h
    # Safeguarded Newton: keep a bracket of the sign change, bisect when a step leaves it.
    lo, hi = np.zeros_like(u), np.ones_like(u)
    for _ in range(ROOT_ITERATIONS):
        u2, u3 = u * u, u * u * u
        val = (2 * u3 - 3 * u2 + 1) * f + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * f1 + (u3 - u2) * m1
        der = (6 * u2 - 6 * u) * f + (3 * u2 - 4 * u + 1) * m0 + (-6 * u2 + 6 * u) * f1 + (3 * u2 - 2 * u) * m1
        left = (val >= 0.0) == s  # same side as the interval's start
        lo = np.where(left, u, lo)
        hi = np.where(left, hi, u)
        with np.errstate(divide="ignore", invalid="ignore"):
            nxt = u - val / der
        ok = (der != 0.0) & (nxt >= lo) & (nxt <= hi)  # inclusive: a converged step stays put
        u = np.where(val == 0.0, u, np.where(ok, nxt, 0.5 * (lo + hi)))
    # Mean height of the half-cycle that starts at each root (circular moving average of y).
    half = n // 2
    ext = np.concatenate([y, y[:, : half + 1]], 1)
    cs = np.concatenate([np.zeros((pop, 1)), np.cumsum(ext, 1)], 1)
    window = (cs[:, half + 2 : half + 2 + n] - cs[:, 1 : n + 1]) / (half + 1)  # samples i+1 ... i+1+half
    score = np.where(cross, window, np.inf)
    i = np.argmin(score, 1)
    q1 = i + np.take_along_axis(u, i[:, None], 1)[:, 0]
    # Extra roots: every lobe of |f| beyond the main pair is a defect of that lobe's peak size.
    viol = np.zeros(pop)
    many = n_roots > 2
    if many.any():
        a = np.abs(f[many])
        # Sample i belongs to the lobe after the crossings before it (a crossing at i is between i and i + 1).
        lab = (np.cumsum(cross[many], 1) - cross[many]) % n_roots[many][:, None]
        rows = np.arange(a.shape[0])[:, None] * n + lab
        peak = np.zeros(a.shape[0] * n)
        np.maximum.at(peak, rows.ravel(), a.ravel())
        peak = np.sort(peak.reshape(-1, n), 1)
        viol[many] = 0.5 * np.maximum(peak[:, :-2] - LOBE_TOL, 0.0).sum(1)
    viol[n_roots == 0] = NO_ROOT_VIOLATION
    return q1 % n, n_roots, viol


def turning_number(path: F64) -> NDArray[np.int64]:
    """``(pop,)`` turning number of the closed sampled polygon (net turns of its edge direction).

    Counted as signed passes of the edge direction through the +x direction: from the lower to
    the upper half-plane (y >= 0) turning counter-clockwise is +1, the reverse clockwise -1 (the
    turn between two edges is taken below pi; an exact reversal passes through -x by convention).
    A simple closed polygon has +-1; any other value proves a self-intersection.
    """
    seg = np.roll(path, -1, 1) - path
    nxt = np.roll(seg, -1, 1)
    up0, up1 = seg[..., 1] >= 0.0, nxt[..., 1] >= 0.0
    cross = seg[..., 0] * nxt[..., 1] - seg[..., 1] * nxt[..., 0]
    return ((~up0 & up1 & (cross > 0.0)).sum(1) - (up0 & ~up1 & (cross < 0.0)).sum(1)).astype(np.int64)


def feature_points(path: F64, dpath: F64 | None = None, period: float = DEFAULT_PERIOD) -> FeaturePoints:
    """Feature points t1 ... t8 of a batch of bench trajectories (leg frame, spec §4).

    t1 landing, t2 = t1 + T/2 take-off, t3 lowest, t4 left-most, t5 right-most, t7 and t8 the two
    highest local maxima of the swing (in time order; both the swing's highest point if it has a
    single peak) and t6 the lowest point between them. Never raises for odd paths.

    Args:
        path: ``(pop, n_samples, 2)`` or ``(n_samples, 2)`` leg-frame path (mm), uniform in time.
        dpath: same shape, exact d/dtheta (mm/rad); estimated by periodic differences when None.
        period: crank period T (s).

    Returns:
        FeaturePoints with ``(pop, ...)`` arrays.
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim == 2:
        path = path[None]
    pop, n = path.shape[:2]
    valid = np.asarray(np.isfinite(path).all(axis=(1, 2)), dtype=bool)
    p = np.where(valid[:, None, None], path, 0.0)
    if dpath is None:
        d = periodic_derivative(p)
    else:
        d = np.asarray(dpath, dtype=np.float64).reshape(path.shape)
        valid &= np.isfinite(d).all((1, 2))
        d = np.where(valid[:, None, None], d, 0.0)
    x, y = p[..., 0], p[..., 1]
    ps, ds = half_shift(p, d)
    q1, n_roots, root_viol = _landing(y, y - ps[..., 1], d[..., 1] - ds[..., 1])
    q2 = (q1 + n / 2.0) % n

    all_mask = np.ones((pop, n), bool)
    _, q3 = _extremum(y, all_mask, largest=False)
    _, q4 = _extremum(x, all_mask, largest=False)
    _, q5 = _extremum(x, all_mask, largest=True)

    # Swing: samples strictly inside (t2, t2 + T/2).
    rel = _circular_rel(n, q2)
    swing = (rel > 0.0) & (rel < n / 2.0)
    ym, yp = np.roll(y, 1, 1), np.roll(y, -1, 1)
    peaks = swing & (y > ym) & (y >= yp)
    # Shoulders (neighbours outside the swing) are no peaks; fall back to the swing maximum.
    no_peak = ~peaks.any(1)
    top = np.where(peaks, y, -np.inf)
    a = np.argmax(top, 1)
    top[np.arange(pop), a] = -np.inf
    b = np.where(np.isfinite(top).any(1), np.argmax(top, 1), a)
    i_sw, _ = _extremum(y, swing, largest=True)
    a = np.where(no_peak, i_sw, a)
    b = np.where(no_peak, i_sw, b)
    ra, rb = rel[np.arange(pop), a], rel[np.arange(pop), b]
    i7, i8 = np.where(ra <= rb, a, b), np.where(ra <= rb, b, a)
    q7, q8 = i7 + _parabolic(y, i7), i8 + _parabolic(y, i8)
    r7, r8 = np.minimum(ra, rb), np.maximum(ra, rb)
    between = (rel >= r7[:, None]) & (rel <= r8[:, None])
    i6, q6 = _extremum(y, between, largest=False)
    q6 = np.where(i6 == i7, q7, q6)

    index = np.stack([q1, q2, q3, q4, q5, q6, q7, q8], 1) % n
    pts, tan = hermite(p, d, index)
    nan = ~valid
    index[nan] = np.nan
    pts[nan] = np.nan
    tan[nan] = np.nan
    root_viol[nan] = np.inf
    turning = turning_number(p)
    return FeaturePoints(
        index=index,
        times=index * (period / n),
        points=pts,
        tangents=tan,
        n_roots=np.where(valid, n_roots, 0),
        root_violation=root_viol,
        turning=np.where(valid, turning, 0),
        valid=valid,
        period=float(period),
        n_samples=n,
    )
