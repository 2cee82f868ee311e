"""Bench trajectory -> walking trajectory (spec §5) and the biped / quadruped layouts (paper §2.2-2.3).

World frame of one leg ("leg A"): the hip is at the origin when leg A takes off (t2); the ground is
``y_g = y_b(t1)``. While leg A swings, the other leg of its biped module stands still where it
landed, so (spec §5)

    C_m(t) = C_b(t) - C_b(t - T/2) + C_b(t1),   t in [t2, t2 + T/2],

from ``C_b(t2)`` to ``2 C_b(t1) - C_b(t2)``: a step of ``2 l_s``. Every half period the hip advances
by ``C_b(t1) - C_b(t2)`` (``-l_s`` in x for the paper's convention x(t1) < x(t2)).

A layout places legs as (hip offset along x, phase lag as a fraction of T). A leg lagging by phase
``phi`` (0 or 1/2 in a biped module) swings the same arc as leg A, shifted along x by
``offset + 2 phi (x_b(t1) - x_b(t2))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.analysis.features import FeaturePoints, hermite, periodic_derivative

F64 = NDArray[np.float64]

DEFAULT_TRUNK = 450.0  # mm; 1.5 x the paper's 300 mm stance: the four feet interleave evenly


@dataclass(frozen=True)
class Layout:
    """Legs of a robot in side view.

    Attributes:
        name: ``"biped"`` or ``"quadruped"``.
        legs: leg names.
        offsets: ``(n_legs,)`` hip x offset of each leg from leg A's hip (mm).
        phases: ``(n_legs,)`` phase lag of each leg behind leg A, as a fraction of the period.
    """

    name: str
    legs: tuple[str, ...]
    offsets: tuple[float, ...]
    phases: tuple[float, ...]


BIPED = Layout("biped", ("A", "B"), (0.0, 0.0), (0.0, 0.5))


def quadruped(trunk: float = DEFAULT_TRUNK) -> Layout:
    """Two biped modules a trunk length apart, diagonal pairs in phase (paper Eqs. 7-10).

    Args:
        trunk: distance between the front and rear hips (mm).
    """
    return Layout(
        "quadruped",
        ("front-left", "front-right", "rear-left", "rear-right"),
        (0.0, 0.0, -float(trunk), -float(trunk)),
        (0.0, 0.5, 0.5, 0.0),
    )


@dataclass(frozen=True)
class WalkingTrajectory:
    """The swing arc of leg A in its world frame, sampled uniformly in time.

    Attributes:
        times: ``(pop, n)`` absolute crank times (s) from t2 to t2 + T/2 (may exceed T).
        points: ``(pop, n, 2)`` world-frame foot positions (mm); hip at the origin at t2.
        heights: ``(pop, n)`` ``y_m - y_g`` (mm); exactly 0 at both ends.
        ground: ``(pop,)`` ground height ``y_g = y_b(t1)`` (mm).
        step: ``(pop,)`` distance from the first to the last point (mm), ``2 l_s``.
        advance: ``(pop,)`` hip x displacement per half period, ``x_b(t1) - x_b(t2)`` (mm).
    """

    times: F64
    points: F64
    heights: F64
    ground: F64
    step: F64
    advance: F64


def _prepare(path: F64, dpath: F64 | None) -> tuple[F64, F64]:
    path = np.asarray(path, dtype=np.float64)
    if path.ndim == 2:
        path = path[None]
    p = np.nan_to_num(path)
    if dpath is None:
        return p, periodic_derivative(p)
    d = np.nan_to_num(np.asarray(dpath, dtype=np.float64).reshape(path.shape))
    return p, d


def walking_trajectory(
    path: F64, dpath: F64 | None, fp: FeaturePoints, n_swing: int | None = None
) -> WalkingTrajectory:
    """Swing arc of the walking trajectory (spec §5) for a population.

    Args:
        path: ``(pop, n_samples, 2)`` leg-frame bench trajectory (mm).
        dpath: its d/dtheta (mm/rad), or None to estimate it.
        fp: the path's feature points.
        n_swing: samples along the swing, ends included (default ``n_samples // 2 + 1``).

    Returns:
        WalkingTrajectory; NaN rows where the path is invalid.
    """
    p, d = _prepare(path, dpath)
    n = p.shape[1]
    m = n // 2 + 1 if n_swing is None else int(n_swing)
    valid = fp.valid
    q1 = np.where(valid, fp.index[:, 0], 0.0)
    q2 = np.where(valid, fp.index[:, 1], 0.0)
    j = np.arange(m) * ((n / 2.0) / (m - 1))
    now, _ = hermite(p, d, q2[:, None] + j[None, :])
    before, _ = hermite(p, d, q1[:, None] + j[None, :])
    c1 = fp.points[:, 0]
    pts = now - before + np.nan_to_num(c1)[:, None, :]
    heights = now[..., 1] - before[..., 1]
    heights[:, 0] = 0.0
    heights[:, -1] = 0.0
    ground = c1[:, 1].copy()
    pts[..., 1] = ground[:, None] + heights
    pts[:, 0] = fp.points[:, 1]
    pts[:, -1] = 2.0 * fp.points[:, 0] - fp.points[:, 1]
    advance = fp.points[:, 0, 0] - fp.points[:, 1, 0]
    times = fp.times[:, 1:2] + j[None, :] * (fp.period / n)
    nan = ~valid
    pts[nan] = np.nan
    heights[nan] = np.nan
    return WalkingTrajectory(
        times=times,
        points=pts,
        heights=heights,
        ground=ground,
        step=np.hypot(pts[:, -1, 0] - pts[:, 0, 0], pts[:, -1, 1] - pts[:, 0, 1]),
        advance=advance,
    )


def arc_offsets(advance: F64, layout: Layout) -> F64:
    """``(pop, n_legs)`` x shift of each leg's swing arcs relative to leg A's (mm).

    The paper's relative WT positions (Eqs. 7-10) are differences of these between legs.

    Args:
        advance: ``(pop,)`` hip advance per half period, ``x_b(t1) - x_b(t2)`` (mm).
        layout: the legs.
    """
    o = np.asarray(layout.offsets)[None, :]
    ph = np.asarray(layout.phases)[None, :]
    return o + 2.0 * ph * np.asarray(advance)[:, None]


@dataclass(frozen=True)
class WorldPaths:
    """Hip and feet of a walking robot in the world frame of leg A.

    Attributes:
        tau: ``(n,)`` time since leg A's take-off (s).
        hip: ``(pop, n, 2)`` position of leg A's hip, i.e. the trunk (mm).
        feet: ``(pop, n_legs, n, 2)`` foot positions (mm).
        ground: ``(pop,)`` ground height (mm).
        layout: the legs.
    """

    tau: F64
    hip: F64
    feet: F64
    ground: F64
    layout: Layout


def world_paths(
    path: F64, dpath: F64 | None, fp: FeaturePoints, layout: Layout = BIPED, n_strides: int = 2
) -> WorldPaths:
    """Trunk and foot paths over several strides (biped: one hip; quadruped: a rigid trunk).

    At any time one leg of the front module stands still where it landed; the hip follows from
    it: over half period h (counted from t2) ``hip = F_h - C_b(t1 + r)`` with footprint
    ``F_h = C_b(t1) + h (C_b(t1) - C_b(t2))``. Every foot is then ``hip + offset + C_b(own phase)``,
    so the hip's vertical range is h_s and each swing is the walking trajectory.

    Args:
        path: ``(pop, n_samples, 2)`` leg-frame bench trajectory (mm).
        dpath: its d/dtheta (mm/rad), or None.
        fp: feature points of the path.
        layout: legs (BIPED or ``quadruped(trunk)``).
        n_strides: number of periods to cover.

    Returns:
        WorldPaths sampled every ``T / n_samples`` from leg A's take-off; NaN rows for invalid paths.
    """
    p, d = _prepare(path, dpath)
    pop, n = p.shape[:2]
    m = n_strides * n + 1
    k = np.arange(m, dtype=np.float64)  # samples since t2
    tau = k * (fp.period / n)
    half = np.minimum(np.floor(k / (n / 2.0)), 2 * n_strides - 1)
    r = k - half * (n / 2.0)
    q1 = np.where(fp.valid, fp.index[:, 0], 0.0)
    q2 = np.where(fp.valid, fp.index[:, 1], 0.0)
    c1 = np.nan_to_num(fp.points[:, 0])
    c2 = np.nan_to_num(fp.points[:, 1])
    foot = c1[:, None, :] + half[None, :, None] * (c1 - c2)[:, None, :]
    stance, _ = hermite(p, d, q1[:, None] + r[None, :])
    hip = foot - stance
    feet = np.empty((pop, len(layout.legs), m, 2))
    for leg, (off, ph) in enumerate(zip(layout.offsets, layout.phases, strict=True)):
        own, _ = hermite(p, d, q2[:, None] + k[None, :] - ph * n)
        feet[:, leg] = hip + own
        feet[:, leg, :, 0] += off
    nan = ~fp.valid
    hip[nan] = np.nan
    feet[nan] = np.nan
    return WorldPaths(tau=tau, hip=hip, feet=feet, ground=fp.points[:, 0, 1].copy(), layout=layout)
