"""Ground clearance: how far the rest of the leg stays above the ground its foot stands on.

The ground is the foot's lowest level over the cycle (the stance line of the bench trajectory, where the trunk
is held at one height). A joint below it (a crank tip, a rocker, a frame pivot) would strike the ground, and a
frame pivot below it means the trunk hangs below its feet: the leg works upside down. Joints are enough: a link
is the convex hull of its joints, so its lowest point is one of them. Defined in the leg frame when it is the
design frame moved rigidly (an output stage of ratio k = 1, mirrored or not); a pantograph (k != 1) maps the
foot alone and its bars are not modelled, so there the clearance is NaN (docs/metrics.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Ground, Mechanism, OutputStage
from core.kinematics.solver import Solution

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Clearance:
    """Frozen: the ground clearance of a population.

    Attributes:
        height: ``(pop, n_joints)`` each joint's lowest y over the cycle above the ground, the foot's lowest y
            (mm); NaN for the foot itself, for every joint of a member that does not assemble, and everywhere when
            the output stage is not rigid.
        names: the joint names.
        frame: ``(n_joints,)`` True for the points fixed in this mechanism (its ground points).
        ground: ``(pop,)`` the foot's lowest y (mm, design frame), NaN where the heights are.
    """

    height: F64
    names: tuple[str, ...]
    frame: NDArray[np.bool_]
    ground: F64

    def with_fixed(self, names: tuple[str, ...], y: F64) -> Clearance:
        """With more fixed points of the leg that its mechanism does not draw, at heights ``y`` ``(pop, k)`` (mm,
        design frame): the RTCLM's auxiliary mode locks the left leg's crank and rocker too."""
        extra = np.asarray(y, dtype=np.float64) - self.ground[:, None]
        return Clearance(np.concatenate([self.height, extra], axis=1), self.names + tuple(names),
                         np.concatenate([self.frame, np.ones(len(names), dtype=bool)]), self.ground)

    @property
    def value(self) -> F64:
        """``(pop,)`` the lowest joint but the foot above the ground (mm; < 0: below it), NaN where not defined."""
        h = np.where(np.isnan(self.height), np.inf, self.height).min(axis=1, initial=np.inf)
        return np.where(np.isinf(h), np.nan, h)

    def lowest(self, i: int = 0, frame: bool = False) -> int:
        """Index of member i's lowest joint but the foot (among the fixed points with ``frame``), -1 if none."""
        h = np.where(self.frame, self.height[i], np.nan) if frame else self.height[i]
        return -1 if np.isnan(h).all() else int(np.nanargmin(h))

    def text(self, i: int = 0) -> str:
        """Member i in words: ``12.3 mm (lowest point after the foot: B)``, what goes below the ground and by how
        much (the lowest joint first: the value beside it is that joint's), or ``n/a``."""
        j = self.lowest(i)
        if j < 0:
            return "n/a"
        v = float(self.height[i, j])
        if v >= 0.0:
            return f"{v:.1f} mm (lowest point after the foot: {self.names[j]})"
        warn = self.warning(i)
        if warn.startswith(f"{self.names[j]} "):
            return warn
        # A fixed point below the ground is said first, but the value is the lowest joint's: "-164.2 mm: A (fixed)
        # sits 108.9 mm below" read as A's (review of session 30).
        return f"{self.names[j]} is lowest, {-v:.1f} mm below the ground the foot stands on; {warn}"

    def warning(self, i: int = 0) -> str:
        """What is wrong with member i's leg ("" when nothing is): a fixed point below the ground the foot stands
        on (said first: the leg works upside down), else the joint that dips lowest below it."""
        f = self.lowest(i, frame=True)
        if f >= 0 and self.height[i, f] < 0.0:
            return (f"{self.names[f]} (fixed) sits {-self.height[i, f]:.1f} mm below the ground the foot stands on: "
                    "the frame would reach the ground before the foot")
        j = self.lowest(i)
        if j < 0 or not self.height[i, j] < 0.0:
            return ""
        return (f"{self.names[j]} dips {-self.height[i, j]:.1f} mm below the ground the foot stands on: the leg "
                "would strike the ground with it")


def rigid(output: OutputStage) -> bool:
    """Whether the leg frame is the design frame moved rigidly (k = 1), so the joints' heights are the leg's."""
    return output.k == 1.0


def ground_clearance(solution: Solution, mechanism: Mechanism, output: OutputStage) -> Clearance:
    """The ground clearance of a solved population (solved with ``joints=True``).

    Args:
        solution: joints ``(pop, n_samples, n_joints, 2)`` (mm) and violation ``(pop,)``.
        mechanism: the topology solved (its tracked point is the foot; its ground points are fixed).
        output: the output stage; the clearance is NaN unless it is rigid (``rigid``).
    """
    if solution.joints is None:
        raise ValueError("ground_clearance needs the joints: solve with joints=True")
    lowest = np.fmin.reduce(solution.joints[..., 1], axis=1)  # NaN samples skipped, as the fused kernel does
    return from_lowest(lowest, mechanism, output, solution.violation)


def from_lowest(lowest: F64, mechanism: Mechanism, output: OutputStage, violation: F64) -> Clearance:
    """The clearance from each joint's lowest y over the cycle, ``(pop, n_joints)`` (design frame, mm, in the
    mechanism's step order), and the assembly violation ``(pop,)``: NaN where it is not 0."""
    names = mechanism.joint_names
    foot = names.index(mechanism.tracked)
    frame = np.array([isinstance(s, Ground) for s in mechanism.steps])
    lowest = np.asarray(lowest, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # a joint never placed is +inf: inf - inf
        height = lowest - lowest[:, foot : foot + 1]
    height[:, foot] = np.nan
    if not rigid(output):
        height[:] = np.nan
    bad = (np.asarray(violation) != 0.0) | ~np.isfinite(height).any(axis=1)
    height[bad] = np.nan
    height[~np.isfinite(height)] = np.nan
    ground = np.where(bad | (not rigid(output)), np.nan, lowest[:, foot])
    return Clearance(height, names, frame, ground)
