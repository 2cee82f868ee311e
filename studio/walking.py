"""The walking view, as pure geometry: a biped module or a quadruped walking over one stride (spec §5).

``core.analysis.gait.world_paths`` gives the trunk (leg A's hip) and every foot in the world frame of leg
A; this module turns them into what the scene draws per crank sample (trunk and legs as
segments, feet as points), the feet's paths over the stride, the ground line, and the ψ
obstacle: an ``a x b`` rectangle standing on the ground at a chosen place within the stride.
Whether the obstacle at that place is crossed uses the same exact interval test as ψ
(``core.analysis.metrics.blocked_intervals``), so the fraction of places where it is clear is ψ2 (biped)
or ψ4 (quadruped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from core.analysis.evaluate import DEFAULT_OBSTACLE
from core.analysis.features import FeaturePoints, feature_points
from core.analysis.gait import (
    BIPED,
    DEFAULT_TRUNK,
    Layout,
    WalkingTrajectory,
    arc_offsets,
    quadruped,
    walking_trajectory,
)
from core.analysis.gait import world_paths as core_world_paths
from core.analysis.metrics import blocked_intervals
from core.kinematics.checks import MAX_ABS

F64 = NDArray[np.float64]

LAYOUTS = ("biped", "quadruped")


PAPER_STEP = (300.0, 100.0)  # mm: the paper's target cycloid (length, height), which the default obstacle and
# trunk go with


def sizes_for(step: tuple[float, float]) -> tuple[float, float, float]:
    """The obstacle (a, b) and trunk (mm) the walking view starts with for a target step (length, height) mm: the
    paper's (25 x 25 mm, 450 mm at its 300 x 100 mm cycloid), a and the trunk scaled with the length, b with the
    height, to 0.1 mm (a trunk at least 0.1 mm: psi4 needs hips apart)."""
    kx, ky = step[0] / PAPER_STEP[0], step[1] / PAPER_STEP[1]
    return (round(DEFAULT_OBSTACLE[0] * kx, 1), round(DEFAULT_OBSTACLE[1] * ky, 1),
            max(round(DEFAULT_TRUNK * kx, 1), 0.1))


@dataclass(frozen=True)
class WalkSpec:
    """Walking view settings.

    Attributes:
        layout: ``biped`` (one module, ψ2) or ``quadruped`` (two modules, ψ4).
        a: obstacle length (mm), >= 0.
        b: obstacle height (mm), >= 0.
        place: where the obstacle stands, as a fraction of one stride across the view (0 ... 1).
        trunk: quadruped hip distance (mm).
    """

    layout: str = "biped"
    a: float = DEFAULT_OBSTACLE[0]
    b: float = DEFAULT_OBSTACLE[1]
    place: float = 0.5
    trunk: float = DEFAULT_TRUNK

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ValueError(f"walking layout must be one of {', '.join(LAYOUTS)}, got {self.layout!r}")
        for name, unit in (("a", "mm"), ("b", "mm")):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= MAX_ABS:
                raise ValueError(f"obstacle {name} must be a number from 0 to {MAX_ABS:g} ({unit}), got {v!r}")
        t = self.trunk  # psi4 is measured on it (core's evaluate takes 0 < trunk <= 1e6 mm)
        if isinstance(t, bool) or not isinstance(t, int | float) or not 0.0 < t <= MAX_ABS:
            raise ValueError(f"trunk (the quadruped's hip distance) must be a number > 0 and at most {MAX_ABS:g} "
                             f"(mm), got {t!r}")
        p = self.place
        if isinstance(p, bool) or not isinstance(p, int | float) or not 0.0 <= p <= 1.0:
            raise ValueError(f"obstacle place must be a fraction of the stride in [0, 1], got {p!r}")

    @property
    def obstacle(self) -> tuple[float, float]:
        return (float(self.a), float(self.b))

    def robot(self) -> Layout:
        return BIPED if self.layout == "biped" else quadruped(self.trunk)

    def to_dict(self) -> dict[str, float | str]:
        return {"layout": self.layout, "a": float(self.a), "b": float(self.b), "place": float(self.place),
                "trunk": float(self.trunk)}

    @staticmethod
    def from_dict(data: object) -> WalkSpec:
        if not isinstance(data, dict):
            raise ValueError(f"walk must be an object {{layout, a, b, place, trunk}}, got {data!r}")
        unknown = [k for k in data if k not in ("layout", "a", "b", "place", "trunk")]
        if unknown:
            raise ValueError(f"unknown walk key {unknown[0]!r}; expected layout, a, b, place, trunk")
        d = WalkSpec()
        return WalkSpec(data.get("layout", d.layout), data.get("a", d.a), data.get("b", d.b),
                        data.get("place", d.place), data.get("trunk", d.trunk))


@dataclass(frozen=True)
class WalkFrames:
    """Everything the walking view draws for one design (mm, world frame of leg A).

    Attributes:
        hip: ``(n_samples, 2)`` leg A's hip at crank sample i (the trunk: the leg-frame origin's motion,
            drawn a constant offset above the feet).
        feet: ``(n_samples, n_legs, 2)`` feet at crank sample i.
        trunk: ``(n_samples, 2, 2)`` the trunk as one segment at crank sample i.
        legs: ``(n_samples, n_legs, 2, 2)`` hip -> foot segments at crank sample i.
        trails: ``(n_legs, m, 2)`` each foot's path over one stride (open polylines).
        ground: ground height y_g (mm).
        obstacle: ``(4, 2)`` corners of the obstacle rectangle (mm).
        hit: True if a foot path enters the obstacle where it stands.
        stride: ``2 |advance|``, the distance the robot covers per period (mm).
        bounds: ``(4,)`` ``[x_min, y_min, x_max, y_max]`` of everything drawn (mm).
        legs_names: leg names of the layout.
    """

    hip: F64
    feet: F64
    trunk: F64
    legs: F64
    trails: F64
    ground: float
    obstacle: F64
    hit: bool
    stride: float
    bounds: F64
    leg_names: tuple[str, ...]


def hit_intervals(wt: WalkingTrajectory, robot: Layout, a: float, b: float) -> tuple[F64, F64, float]:
    """Obstacle positions x0 (left edge, mm) where some swing arc enters ``[x0, x0 + a] x [y_g, y_g + b]``.

    Member 0 of ``wt``. The set is periodic with the stride; returned as intervals ``[lo, hi]``
    (NaN rows are empty) and the stride (mm). Same construction as ``core.analysis.metrics.psi``.
    """
    lo, hi = blocked_intervals(wt, b)
    shift = arc_offsets(wt.advance, robot)[0]
    lo0 = (lo[0][None, :] + shift[:, None] - a).reshape(-1)
    hi0 = (hi[0][None, :] + shift[:, None]).reshape(-1)
    keep = np.isfinite(lo0) & np.isfinite(hi0)
    return lo0[keep], hi0[keep], float(2.0 * abs(wt.advance[0]))


def is_hit(x0: float, lo: F64, hi: F64, stride: float) -> bool:
    """True if an obstacle with its left edge at x0 lies in a hit interval (modulo the stride)."""
    if not (stride > 0.0 and math.isfinite(stride)):
        return True
    if len(lo) and np.any(hi - lo >= stride):
        return True
    k = np.floor((x0 - lo) / stride)
    return bool(np.any(x0 - k * stride <= hi))


def build_walk(leg: F64, dleg: F64 | None, period: float, spec: WalkSpec) -> WalkFrames | None:
    """The walking view of a bench trajectory, or None if it has no well-defined feature points.

    Args:
        leg: ``(n_samples, 2)`` leg-frame bench trajectory (mm), uniform in time.
        dleg: its d/dtheta (mm/rad), or None.
        period: crank period T (s).
        spec: layout and obstacle.
    """
    leg = np.asarray(leg, dtype=np.float64)
    n = leg.shape[0]
    if not np.isfinite(leg).all():
        return None
    fp: FeaturePoints = feature_points(leg[None], None if dleg is None else np.asarray(dleg)[None], period)
    if not fp.valid[0]:
        return None
    robot = spec.robot()
    wp = core_world_paths(leg[None], None if dleg is None else np.asarray(dleg)[None], fp, robot, n_strides=1)
    wt = walking_trajectory(leg[None], None if dleg is None else np.asarray(dleg)[None], fp)
    hip_w, feet_w = wp.hip[0], np.moveaxis(wp.feet[0], 0, 1)  # (m, 2), (m, n_legs, 2), m = n + 1
    if not (np.isfinite(hip_w).all() and np.isfinite(feet_w).all()):
        return None
    # Walk sample k is crank position q2 + k (k = 0 at leg A's take-off).
    q2 = float(fp.index[0, 1])
    k = np.mod(np.round(np.arange(n) - q2).astype(np.int64), n)
    hip, feet = hip_w[k], feet_w[k]
    # The trunk is drawn a constant offset above the leg-frame origin (which is all world_paths moves):
    # over the middle of the path, half the path's height above its top. Its motion is exact.
    y_lo, y_hi = float(leg[:, 1].min()), float(leg[:, 1].max())
    anchor = np.array([0.5 * (leg[:, 0].min() + leg[:, 0].max()), y_hi + 0.5 * max(y_hi - y_lo, 1.0)])
    hip = hip + anchor
    offsets = np.array(robot.offsets)
    hips = hip[:, None, :] + np.stack([offsets, np.zeros_like(offsets)], -1)[None]  # (n, n_legs, 2)
    legs = np.stack([hips, feet], axis=2)
    stride = float(2.0 * abs(wt.advance[0]))
    half = 0.12 * max(stride, 1.0)
    ends = np.array([[offsets.min() - half, 0.0], [offsets.max() + half, 0.0]])
    trunk = hip[:, None, :] + ends[None]
    trails = np.moveaxis(feet_w, 0, 1)
    ground = float(wp.ground[0])
    lo, hi, period_x = hit_intervals(wt, robot, float(spec.a), float(spec.b))
    x_lo, x_hi = float(trails[..., 0].min()), float(trails[..., 0].max())
    # The obstacle's left edge sweeps one stride centred on the feet's range as place goes 0 -> 1.
    x0 = 0.5 * (x_lo + x_hi) - 0.5 * float(spec.a) + (float(spec.place) - 0.5) * stride
    rect = np.array([[x0, ground], [x0 + spec.a, ground], [x0 + spec.a, ground + spec.b], [x0, ground + spec.b]])
    pts = np.concatenate([trunk.reshape(-1, 2), legs.reshape(-1, 2), trails.reshape(-1, 2), rect])
    bounds = np.concatenate([pts.min(0), pts.max(0)])
    return WalkFrames(hip=hip, feet=feet, trunk=trunk, legs=legs, trails=trails, ground=ground, obstacle=rect,
                      hit=is_hit(x0, lo, hi, period_x), stride=stride, bounds=bounds, leg_names=robot.legs)


def resized(walk: WalkSpec, sizes: tuple[float, float, float]) -> WalkSpec:
    """The walking view with another leg's obstacle and trunk (a, b, trunk mm; :func:`sizes_for`). The paper's
    25 x 25 mm obstacle stood as tall as a Theo Jansen leg's 22 mm step, whose ψ read 0 % (QA walk, session 36)."""
    return replace(walk, a=sizes[0], b=sizes[1], trunk=sizes[2])
