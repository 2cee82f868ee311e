"""Performance metrics of paper §2.4 as plain functions over batches (spec §4-5).

Body fluctuation h_s and straightness S, stance length l_s, tangent angles theta_i, landing impact
I, obstacle-crossing heights h_m and h_bar, crossing probability psi(a, b), and the constraint
values of Eqs. 30-31 (pymoo convention: G <= 0 is satisfied). Every function takes ``(pop, ...)``
arrays and returns ``(pop,)`` (or ``(pop, k)``); NaN rows stay NaN.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from core.analysis.features import FeaturePoints
from core.analysis.gait import Layout, WalkingTrajectory, arc_offsets

F64 = NDArray[np.float64]

MIN_ANGLE = np.deg2rad(15.0)  # Eq. 30: landing and take-off angles above 15 degrees
MIN_PSI2 = 0.20  # Eq. 31: psi2(25, 25) > 20 %


def _window_extreme(y: F64, start: F64, length: float, largest: bool) -> F64:
    """Extreme of y over the samples strictly inside ``(start, start + length)`` (fractional indices).

    A sample extreme whose two neighbours are inside too is refined by a parabola through them.
    Rows with no sample inside give -inf (largest) or +inf.
    """
    pop, n = y.shape
    rel = (np.arange(n)[None, :] - start[:, None]) % n
    inside = (rel > 0.0) & (rel < length)
    fill = -np.inf if largest else np.inf
    w = np.where(inside, y, fill)
    i = np.argmax(w, 1) if largest else np.argmin(w, 1)
    rows = np.arange(pop)
    a, b, c = y[rows, (i - 1) % n], y[rows, i], y[rows, (i + 1) % n]
    ok = inside[rows, (i - 1) % n] & inside[rows, (i + 1) % n]
    den = a - 2.0 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.clip(np.where(den != 0.0, 0.5 * (a - c) / den, 0.0), -0.5, 0.5)
    refined = b - 0.25 * (a - c) * delta
    best = np.where(ok, refined, b)
    return np.where(inside.any(1), best, fill)


def stance_fluctuation(path: F64, fp: FeaturePoints) -> F64:
    """h_s: max - min of y over the stance half-cycle [t1, t2] (spec §4), ``(pop,)`` mm.

    Args:
        path: ``(pop, n_samples, 2)`` leg-frame path (mm).
        fp: its feature points.
    """
    y = np.nan_to_num(np.asarray(path, dtype=np.float64).reshape(fp.valid.shape[0], fp.n_samples, 2)[..., 1])
    q1 = np.where(fp.valid, fp.index[:, 0], 0.0)
    ends = fp.points[:, :2, 1]
    hi = np.maximum(_window_extreme(y, q1, fp.n_samples / 2.0, True), ends.max(1))
    lo = np.minimum(_window_extreme(y, q1, fp.n_samples / 2.0, False), ends.min(1))
    return np.where(fp.valid, hi - lo, np.nan)


def stance_length(fp: FeaturePoints) -> F64:
    """l_s = |x(t2) - x(t1)|, ``(pop,)`` mm."""
    return np.abs(fp.points[:, 1, 0] - fp.points[:, 0, 0])


def straightness(h_s: F64, l_s: F64) -> F64:
    """S = h_s / l_s x 100 (%), ``(pop,)``; NaN where l_s is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(l_s > 0.0, 100.0 * h_s / l_s, np.nan)


def tangent_angles(fp: FeaturePoints) -> F64:
    """theta_i in [0, pi/2]: angle between the path tangent at t_i and the x axis, ``(pop, 8)`` rad.

    A zero tangent (a cusp sample) gives 0.
    """
    t = fp.tangents
    return np.arctan2(np.abs(t[..., 1]), np.abs(t[..., 0]))


def landing_speed(fp: FeaturePoints) -> F64:
    """Vertical foot speed at landing, ``y'(t1) = dy/dtheta * 2 pi / T``, ``(pop,)`` mm/s (signed)."""
    return fp.tangents[:, 0, 1] * (2.0 * np.pi / fp.period)


def impact(fp: FeaturePoints) -> F64:
    """I = |y'(t1)| sin(theta1) (Eq. 14, spec §4), ``(pop,)`` mm/s."""
    return np.abs(landing_speed(fp)) * np.sin(tangent_angles(fp)[:, 0])


def _to_arc(p: F64, lo: float, hi: float) -> tuple[F64, F64]:
    """Distance from circular positions p (cycle fractions) to the arc [lo, hi], and the nearest arc point."""
    p = p % 1.0
    inside = (p >= lo) & (p <= hi)
    d_lo = np.minimum((lo - p) % 1.0, (p - lo) % 1.0)
    d_hi = np.minimum((hi - p) % 1.0, (p - hi) % 1.0)
    dist = np.where(inside, 0.0, np.minimum(d_lo, d_hi))
    near = np.where(inside, p, np.where(d_lo <= d_hi, lo, hi))
    return dist, near


def order_violation(fp: FeaturePoints) -> F64:
    """Eq. 30 non-retrograde order t1 -> t2 -> t5 -> t4 (cyclic) as a continuous value, ``(pop,)`` rad.

    With phases measured from t1 (cycle fractions), t5 and t4 must lie in the swing [1/2, 1] with
    t5 no later than t4. The value is the crank angle by which t5 and t4 miss the swing plus the
    angle by which their projections onto it are out of order; 0 when the order holds.
    """
    t1 = fp.times[:, 0]
    p5 = (fp.times[:, 4] - t1) / fp.period
    p4 = (fp.times[:, 3] - t1) / fp.period
    d5, n5 = _to_arc(p5, 0.5, 1.0)
    d4, n4 = _to_arc(p4, 0.5, 1.0)
    # A t4 exactly at t1 (phase 0) is the swing's end (phase 1).
    n4 = np.where(n4 < 0.5, 1.0, n4)
    n5 = np.where(n5 < 0.5, 1.0, n5)
    return 2.0 * np.pi * (d5 + d4 + np.maximum(0.0, n5 - n4))


def angle_margins(fp: FeaturePoints, min_angle: float = MIN_ANGLE) -> F64:
    """Eq. 30 angle constraints ``min_angle - theta1``, ``min_angle - theta2``, ``(pop, 2)`` rad (<= 0 ok)."""
    th = tangent_angles(fp)[:, :2]
    return min_angle - th


def crossing_height(wt: WalkingTrajectory) -> F64:
    """h_m: maximum height of the swing above the ground (Eq. 16, spec §5), ``(pop,)`` mm."""
    return np.max(wt.heights, 1)


def mean_crossing_height(wt: WalkingTrajectory) -> F64:
    """h_bar: time-mean height of the swing above the ground (Eq. 17, spec §5), ``(pop,)`` mm."""
    h = wt.heights
    return (h[:, 1:] + h[:, :-1]).sum(1) / (2.0 * (h.shape[1] - 1))


def blocked_intervals(wt: WalkingTrajectory, b: float) -> tuple[F64, F64]:
    """x intervals ``(pop, n-1)`` of the swing arc's segments clipped to height <= b (mm).

    Segment j of the polyline keeps the part below height b; its x-projection is [lo, hi]. Empty
    parts are NaN. Points below the ground count as below b (the foot is in the obstacle's column).
    """
    x, h = wt.points[..., 0], wt.heights
    x0, x1, h0, h1 = x[:, :-1], x[:, 1:], h[:, :-1], h[:, 1:]
    dh = h1 - h0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (b - h0) / dh
    flat = dh == 0.0
    ulo = np.where(flat, 0.0, np.where(dh > 0.0, 0.0, np.maximum(u, 0.0)))
    uhi = np.where(flat, 1.0, np.where(dh > 0.0, np.minimum(u, 1.0), 1.0))
    empty = np.where(flat, h0 > b, ulo > uhi)
    xa, xb = x0 + ulo * (x1 - x0), x0 + uhi * (x1 - x0)
    lo, hi = np.minimum(xa, xb), np.maximum(xa, xb)
    lo[empty] = np.nan
    hi[empty] = np.nan
    return lo, hi


def _union_length(lo: F64, hi: F64) -> F64:
    """Total length of the union of intervals ``[lo, hi]`` per row (NaN rows of intervals ignored)."""
    lo = np.where(np.isnan(lo), np.inf, lo)
    hi = np.where(np.isnan(hi), -np.inf, hi)
    order = np.argsort(lo, 1)
    lo = np.take_along_axis(lo, order, 1)
    hi = np.take_along_axis(hi, order, 1)
    reach = np.maximum.accumulate(hi, 1)
    prev = np.concatenate([np.full((lo.shape[0], 1), -np.inf), reach[:, :-1]], 1)
    with np.errstate(invalid="ignore"):
        gain = np.maximum(0.0, hi - np.maximum(lo, prev))
    return np.where(np.isfinite(gain), gain, 0.0).sum(1)


def psi(wt: WalkingTrajectory, layout: Layout, a: float, b: float) -> F64:
    """Crossing probability psi(a, b) of an a x b obstacle (spec §5, general form), ``(pop,)`` in [0, 1].

    The fraction of obstacle positions x0, uniform over one stride ``2 l_s``, for which no swing
    arc of the layout's legs enters ``[x0, x0 + a] x [y_g, y_g + b]``. Exact: the arcs' parts below
    height b are x-intervals; the obstacle hits an interval [lo, hi] iff x0 is in [lo - a, hi]; the
    hit set is periodic with the stride, so psi = 1 - |union of hit intervals mod stride| / stride.

    Args:
        wt: leg A's walking trajectory (every leg swings the same arc, shifted).
        layout: legs that meet the obstacle (BIPED: psi2; quadruped: psi4).
        a: obstacle length (mm) >= 0.
        b: obstacle height (mm) >= 0.
    """
    period = 2.0 * np.abs(wt.advance)
    lo, hi = blocked_intervals(wt, b)
    shift = arc_offsets(wt.advance, layout)  # (pop, n_legs)
    lo = (lo[:, None, :] + shift[:, :, None] - a).reshape(lo.shape[0], -1)
    hi = (hi[:, None, :] + shift[:, :, None]).reshape(lo.shape)
    P = period[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        base = np.floor(lo / P) * P
        lo1, hi1 = lo - base, hi - base
        full = (hi1 - lo1) >= P
        lo2 = np.where(hi1 > P, 0.0, np.nan)
        hi2 = np.where(hi1 > P, np.minimum(hi1 - P, P), np.nan)
        hi1 = np.minimum(hi1, P)
    covered = _union_length(np.concatenate([lo1, lo2], 1), np.concatenate([hi1, hi2], 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = 1.0 - np.minimum(covered, period) / period
    out = np.where(full.any(1), 0.0, out)
    return np.where(np.isfinite(wt.heights).all(1) & (period > 0.0), out, np.nan)


def eq31(h_m: F64, h_bar: F64, psi2: F64, min_psi2: float = MIN_PSI2) -> F64:
    """Eq. 31 constraint values ``(pop, 2)``: ``h_m / 4 - h_bar`` (mm) and ``min_psi2 - psi2`` (<= 0 ok)."""
    return np.stack([h_m / 4.0 - h_bar, min_psi2 - psi2], 1)
