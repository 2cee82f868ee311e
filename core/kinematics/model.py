"""The generic construction model: a mechanism is an ordered list of steps over named points.

Every topology is data: a tuple of steps, each placing one point from points placed
before it. The solvers (``core/kinematics/solver.py``) interpret the compiled form
(:class:`Program`) and never branch on the topology.

Step kinds (spec notation, ``rot90(v) = (-v_y, v_x)``, ``R(a)`` a rotation by ``a``):

- :class:`Ground`: ``X = O + R(angle) (u, v)`` with O a ground point placed before or
  the world origin. Fixed over the cycle.
- :class:`Crank`: ``X = O + R(phase + theta) (u, v)`` with O a ground point and theta the
  input crank angle. Several crank steps with one pivot and phase form one rigid crank.
- :class:`Dyad`: ``X`` with ``|PX| = l1``, ``|QX| = l2``, left of P->Q for side +1, right for -1.
- :class:`Attach`: ``X = P + u e + v rot90(e)``, ``e = unit(Q - P)``: a point rigidly
  carried by the link through P and Q.

An operand is a parameter name (``"r1"``), a negated name (``"-r8"``) or a number.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.params import Param

Operand = str | float

GROUND, CRANK, DYAD, ATTACH = 0, 1, 2, 3


@dataclass(frozen=True)
class Ground:
    name: str
    u: Operand
    v: Operand = 0.0
    origin: str | None = None
    angle: Operand = 0.0


@dataclass(frozen=True)
class Crank:
    name: str
    pivot: str
    u: Operand
    v: Operand = 0.0
    phase: Operand = 0.0


@dataclass(frozen=True)
class Dyad:
    name: str
    p: str
    q: str
    l1: Operand
    l2: Operand
    side: int = 1


@dataclass(frozen=True)
class Attach:
    name: str
    p: str
    q: str
    u: Operand
    v: Operand = 0.0


Step = Ground | Crank | Dyad | Attach


@dataclass(frozen=True)
class OutputStage:
    """Maps the tracked point from the design frame to the leg frame (spec §2).

    ``P_leg = O + k M (P - O)``: identity for k = 1, a pantograph of signed ratio k about O
    otherwise (the paper's Stephenson presets use k = -1 about (150, 0)). M is the identity, or
    with ``mirror`` the reflection x -> -x: a leg whose foot goes round clockwise under our
    counter-clockwise crank (Klann, Chebyshev) walks toward -x; mirrored, its leg frame is
    the spec's (stance moving +x), as if the robot were seen from its other side.
    """

    k: float = 1.0
    ox: float = 0.0
    oy: float = 0.0
    mirror: bool = False

    def __post_init__(self) -> None:
        from core.kinematics.checks import MAX_ABS, flag, real

        for key, unit in (("k", "ratio"), ("ox", "mm"), ("oy", "mm")):
            v = real(getattr(self, key), f"output {key} ({unit})")
            if not abs(v) <= MAX_ABS:
                raise ValueError(f"output {key} ({unit}) must be within +-{MAX_ABS:g}, got {v:g}")
            object.__setattr__(self, key, v)
        # A ratio near 0 collapses the leg onto O (every path "flat"); beyond 1e6 the leg path overflows.
        if not abs(self.k) >= 1.0 / MAX_ABS:
            raise ValueError(f"output k (ratio) must be non-zero, |k| >= {1.0 / MAX_ABS:g}, got {self.k:g}")
        object.__setattr__(self, "mirror", flag(self.mirror, "output mirror"))

    @property
    def ratios(self) -> tuple[float, float]:
        """``(kx, ky)``: the per-axis factors of the map (kx = -k when mirrored)."""
        return (-self.k if self.mirror else self.k), self.k

    def kernel_args(self) -> tuple[float, float, float, float]:
        """``(kx, ky, ox, oy)`` as the numba kernels take the stage."""
        kx, ky = self.ratios
        return float(kx), float(ky), float(self.ox), float(self.oy)

    def apply(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Points ``(*, 2)`` in the design frame -> leg frame."""
        # One output array, no temporaries: the optimizer maps (pop, n, 2) batches every generation.
        kx, ky = self.ratios
        out = np.multiply(p, np.array([kx, ky]))
        out += np.array([(1.0 - kx) * self.ox, (1.0 - ky) * self.oy])
        return out

    @property
    def is_identity(self) -> bool:
        """True when the map changes nothing (k = 1, not mirrored: its centre then does not matter)."""
        return self.k == 1.0 and not self.mirror

    def describe(self) -> str:
        """The map in words: ``k = -1 about (150, 0) mm`` (``, mirrored`` when it is)."""
        return f"k = {self.k:g} about ({self.ox:g}, {self.oy:g}) mm" + (", mirrored" if self.mirror else "")

    def invert(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Points ``(*, 2)`` in the leg frame -> design frame (the inverse of :meth:`apply`)."""
        kx, ky = self.ratios
        o = np.array([self.ox, self.oy])
        return (np.asarray(p, dtype=np.float64) - o) / np.array([kx, ky]) + o

    def apply_derivative(self, dp: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.multiply(dp, np.array(self.ratios))

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"k": self.k, "ox": self.ox, "oy": self.oy}
        if self.mirror:
            d["mirror"] = True
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> OutputStage:
        """Inverse of :meth:`to_dict` (numbers, or the strings ``float`` reads, e.g. "1.5");
        ``mirror`` is optional (false) and must be a boolean ("false" is not read as true)."""
        return cls(float(d["k"]), float(d["ox"]), float(d["oy"]), d.get("mirror", False))


IDENTITY = OutputStage()

# derive(params (pop, n_params)) -> (derived (pop, n_derived), violation (pop,))
Derive = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]


@dataclass(frozen=True)
class Program:
    """A mechanism compiled for the solvers.

    Attributes:
        ops: ``(n_steps, 4)`` int64 rows ``[kind, a, b, side]``; a, b are indices of earlier
            points (-1 for none). Point j is placed by step j.
        slots: ``(n_steps, 3)`` operand columns into the internal vector (-1: constant).
        scale: ``(n_steps, 3)`` factor on the column (+1 or -1).
        const: ``(n_steps, 3)`` value used when the column is -1.
        tracked: index of the tracked point.
    """

    ops: NDArray[np.int64]
    slots: NDArray[np.int64]
    scale: NDArray[np.float64]
    const: NDArray[np.float64]
    tracked: int

    def operands(self, internal: NDArray[np.float64]) -> NDArray[np.float64]:
        """Internal vectors ``(pop, n_internal)`` -> operand values ``(pop, n_steps, 3)``."""
        cols = np.where(self.slots >= 0, self.slots, 0)
        vals = internal[:, cols] * self.scale
        return np.where(self.slots >= 0, vals, self.const)


@dataclass(frozen=True)
class Mechanism:
    """A single-DoF planar linkage: named parameters + construction steps.

    Attributes:
        name: registry name (``stephenson1``).
        title: human name.
        params: the design vector's entries, in order.
        steps: construction steps, in solve order.
        tracked: name of the foot point.
        derived: names of extra internal values computed by ``derive`` from the design
            vector (RTCLM's coupling); operands may name them.
        derive: vectorized map ``params -> (derived, violation)``; None if not needed.
        derive_failure: what a positive derive violation means, for messages (``clm simulate``).
        doc: a paragraph on the construction.
        locked: groups of ground points that are moving links held still in this mechanism (the RTCLM's auxiliary
            mode locks the primary mode's crank, coupler and rocker in the switching state): drawn as the links
            they are, in the frame's colour.
        held_cranks: cranks this mechanism holds still on the link that carries their motor, as (motor axis, crank
            end): parts of their own on the leg built (the RTCLM's primary mode holds crank H-F on the rocker D-C-H,
            which has a bore at H for the second motor), one body to the solver.
    """

    name: str
    title: str
    params: tuple[Param, ...]
    steps: tuple[Step, ...]
    tracked: str
    derived: tuple[str, ...] = ()
    derive: Derive | None = field(default=None, compare=False)
    derive_failure: str = "its derived values have no solution"
    doc: str = ""
    locked: tuple[tuple[str, ...], ...] = ()
    held_cranks: tuple[tuple[str, str], ...] = ()

    @property
    def n_params(self) -> int:
        return len(self.params)

    @cached_property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.steps)

    @property
    def lower(self) -> NDArray[np.float64]:
        return np.array([p.lo for p in self.params], dtype=np.float64)

    @property
    def upper(self) -> NDArray[np.float64]:
        return np.array([p.hi for p in self.params], dtype=np.float64)

    def internal(self, params: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Design vectors ``(pop, n_params)`` -> internal vectors and derive violation ``(pop,)``."""
        params = np.asarray(params, dtype=np.float64)
        if self.derive is None:
            return params, np.zeros(params.shape[0])
        extra, viol = self.derive(params)
        return np.concatenate([params, extra], axis=1), viol

    def compile(self) -> Program:
        """The mechanism's step program, built once per mechanism (kept on the instance, then in a cache)."""
        program = self.__dict__.get("_program")
        if program is None:
            program = _compile(self)
            self.__dict__["_program"] = program  # not a field: equality and hashing ignore it
        return program

    def bodies(self) -> tuple[tuple[str, ...], ...]:
        """Rigid bodies as tuples of point names (ground first), found from the steps."""
        return _bodies(self.steps)

    def pivots(self) -> tuple[str, ...]:
        """The ground points a moving body holds, in step order: what a drawing shows of the frame (the RTCLM's
        auxiliary mode locks A..D as ground points no moving body holds)."""
        grounds = [s.name for s in self.steps if isinstance(s, Ground)]
        moving = [b for b in self.bodies() if not set(b) <= set(grounds)]
        return tuple(g for g in grounds if any(g in b for b in moving))


@cache
def _compile(m: Mechanism) -> Program:
    names = list(m.param_names) + list(m.derived)
    col = {n: i for i, n in enumerate(names)}
    index: dict[str, int] = {}
    n = len(m.steps)
    ops = np.full((n, 4), -1, dtype=np.int64)
    slots = np.full((n, 3), -1, dtype=np.int64)
    scale = np.ones((n, 3))
    const = np.zeros((n, 3))

    def point(name: str | None) -> int:
        if name is None:
            return -1
        if name not in index:
            raise ValueError(f"{m.name}: point {name!r} used before it is placed")
        return index[name]

    def operand(j: int, k: int, op: Operand) -> None:
        if isinstance(op, str):
            sign, key_ = (-1.0, op[1:]) if op.startswith("-") else (1.0, op)
            if key_ not in col:
                raise ValueError(f"{m.name}: unknown parameter {key_!r}")
            slots[j, k], scale[j, k] = col[key_], sign
        else:
            const[j, k] = float(op)

    for j, s in enumerate(m.steps):
        if s.name in index:
            raise ValueError(f"{m.name}: point {s.name!r} placed twice")
        if isinstance(s, Ground):
            ops[j, :3] = GROUND, point(s.origin), -1
            for k, op in enumerate((s.u, s.v, s.angle)):
                operand(j, k, op)
        elif isinstance(s, Crank):
            if not isinstance(m.steps[point(s.pivot)], Ground):
                raise ValueError(f"{m.name}: crank {s.name!r} must turn about a ground point")
            ops[j, :3] = CRANK, point(s.pivot), -1
            for k, op in enumerate((s.u, s.v, s.phase)):
                operand(j, k, op)
        elif isinstance(s, Dyad):
            if s.side not in (1, -1):
                raise ValueError(f"{m.name}: dyad {s.name!r} side must be +1 or -1")
            ops[j] = DYAD, point(s.p), point(s.q), s.side
            operand(j, 0, s.l1)
            operand(j, 1, s.l2)
        else:
            ops[j, :3] = ATTACH, point(s.p), point(s.q)
            operand(j, 0, s.u)
            operand(j, 1, s.v)
        index[s.name] = j
    return Program(ops, slots, scale, const, point(m.tracked))


def _bodies(steps: tuple[Step, ...]) -> tuple[tuple[str, ...], ...]:
    groups: list[list[str]] = [[s.name for s in steps if isinstance(s, Ground)]]
    cranks: dict[tuple[str, Operand], list[str]] = {}
    for s in steps:
        if isinstance(s, Crank):
            cranks.setdefault((s.pivot, s.phase), [s.pivot]).append(s.name)
        elif isinstance(s, Dyad):
            groups += [[s.p, s.name], [s.q, s.name]]
        elif isinstance(s, Attach):
            groups.append([s.p, s.q, s.name])
    groups += list(cranks.values())
    # Two bodies sharing two points are one rigid body, and so are three moving bodies pinned to each other in a
    # triangle (three distinct pins: no freedom left; Jansen's Q-U-V and K-T-F, written as dyads, came out as three
    # bars each, cut as 11 parts for a 7-link leg): merge until stable.
    while _merge_pair(groups) or _merge_triangle(groups):
        pass
    return tuple(tuple(g) for g in groups if len(g) >= 2)


def _join(groups: list[list[str]], idx: list[int]) -> None:
    """Merge ``groups[idx]`` into the first of them, in order."""
    first = groups[idx[0]]
    for i in idx[1:]:
        first += [p for p in groups[i] if p not in first]
    for i in sorted(idx[1:], reverse=True):
        del groups[i]


def _merge_pair(groups: list[list[str]]) -> bool:
    for i in range(len(groups)):
        for j in range(i + 1, len(groups)):
            if len(set(groups[i]) & set(groups[j])) >= 2:
                _join(groups, [i, j])
                return True
    return False


def _merge_triangle(groups: list[list[str]]) -> bool:
    # groups[0] is the frame, which merges with nothing here (a body pinned to it at two points: _merge_pair).
    sets = [set(g) for g in groups]
    for i in range(1, len(groups)):
        for j in range(i + 1, len(groups)):
            ij = sets[i] & sets[j]
            if len(ij) != 1:
                continue
            for k in range(j + 1, len(groups)):
                ik, jk = sets[i] & sets[k], sets[j] & sets[k]
                if len(ik) == len(jk) == 1 and len(ij | ik | jk) == 3:
                    _join(groups, [i, j, k])
                    return True
    return False
