"""The search box of a stage: global bounds, or a neighbourhood of the previous pick (spec §6).

Subtask k searches ``x ± max(s|x|, d)`` around the previous pick x, clipped to the
mechanism's global bounds; for angles ``d = s·π``. A *periodic* parameter (an angle whose
global bounds span exactly one turn, such as the crank phase g) is not clipped: its box is
``c ± min(h, π)`` around the wrapped centre and decoded values wrap back into ``[lo, lo + 2π)``.
Parameters can be held fixed at the centre; the optimizer then sees only the free ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Mechanism
from core.optimize.scale import sized_bounds

F64 = NDArray[np.float64]
TWO_PI = 2.0 * np.pi

# (s, d) of the paper's subtasks: 20 %, 20 mm; 10 %, 10 mm; 5 %, 5 mm (spec §6).
SUBTASK_STEPS: dict[int, tuple[float, float]] = {1: (0.2, 20.0), 2: (0.1, 10.0), 3: (0.05, 5.0)}


def periodic_mask(mechanism: Mechanism) -> NDArray[np.bool_]:
    """``(n_params,)`` True for angles whose global bounds span one full turn (they wrap)."""
    return np.array([p.kind == "angle" and abs((p.hi - p.lo) - TWO_PI) < 1e-9 for p in mechanism.params])


def wrap(values: F64, lo: F64) -> F64:
    """Angles into ``[lo, lo + 2π)`` (rad), elementwise."""
    return lo + np.mod(values - lo, TWO_PI)


@dataclass(frozen=True)
class Box:
    """Bounds of one stage's search over a mechanism's parameter vector.

    Attributes:
        names: parameter names, ``(n_params,)``.
        lower, upper: ``(n_params,)`` box bounds (mm, rad); periodic entries may leave the
            global bounds (values wrap).
        center: ``(n_params,)`` the design the box is built around (wrapped, clipped).
        bound_lo, bound_hi: ``(n_params,)`` the mechanism's global bounds.
        periodic: ``(n_params,)`` True where values wrap into ``[bound_lo, bound_lo + 2π)``.
        fixed: ``(n_params,)`` True where the value is held at ``center``.
    """

    names: tuple[str, ...]
    lower: F64
    upper: F64
    center: F64
    bound_lo: F64
    bound_hi: F64
    periodic: NDArray[np.bool_]
    fixed: NDArray[np.bool_]

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "center", "bound_lo", "bound_hi", "periodic", "fixed"):
            a = np.array(getattr(self, name), dtype=bool if name in ("periodic", "fixed") else np.float64)
            if a.shape != (len(self.names),):
                raise ValueError(f"box {name} has shape {a.shape}, expected ({len(self.names)},)")
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def free(self) -> NDArray[np.bool_]:
        """``(n_params,)`` True for the optimizer's variables."""
        return ~self.fixed

    @property
    def n_var(self) -> int:
        return int(self.free.sum())

    @property
    def xl(self) -> F64:
        """``(n_var,)`` lower bounds of the free variables."""
        return self.lower[self.free]

    @property
    def xu(self) -> F64:
        """``(n_var,)`` upper bounds of the free variables."""
        return self.upper[self.free]

    def decode(self, X: F64) -> F64:
        """Optimizer variables ``(pop, n_var)`` -> parameter vectors ``(pop, n_params)``.

        Fixed entries take the centre value; periodic entries wrap into their global range.
        """
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        out = np.repeat(self.center[None, :], X.shape[0], axis=0)
        out[:, self.free] = X
        out[:, self.periodic] = wrap(out[:, self.periodic], self.bound_lo[self.periodic])
        return out

    def encode(self, params: F64) -> F64:
        """Parameter vectors ``(pop, n_params)`` -> optimizer variables ``(pop, n_var)``.

        Periodic entries are shifted by whole turns to lie nearest the centre; nothing is clipped.
        """
        p = np.atleast_2d(np.asarray(params, dtype=np.float64)).copy()
        per = self.periodic
        p[:, per] = self.center[per] + wrap(p[:, per] - self.center[per], np.full(int(per.sum()), -np.pi))
        return p[:, self.free]

    def contains(self, params: F64, atol: float = 1e-9) -> NDArray[np.bool_]:
        """``(pop,)`` True where parameter vectors lie in the box (periodic entries modulo 2π)."""
        p = np.atleast_2d(np.asarray(params, dtype=np.float64))
        v = self.encode(p)
        inside = ((v >= self.xl - atol) & (v <= self.xu + atol)).all(axis=1)
        diff = p - self.center
        diff[:, self.periodic] = wrap(diff[:, self.periodic], np.full(int(self.periodic.sum()), -np.pi))
        return np.asarray(inside & np.all(np.abs(diff[:, self.fixed]) <= atol, axis=1), dtype=bool)

    def to_dict(self) -> dict[str, Any]:
        """Named bounds, JSON-ready apart from float encoding (see ``core.optimize.result``)."""
        return {
            "names": list(self.names),
            "lower": [float(v) for v in self.lower],
            "upper": [float(v) for v in self.upper],
            "center": [float(v) for v in self.center],
            "bound_lo": [float(v) for v in self.bound_lo],
            "bound_hi": [float(v) for v in self.bound_hi],
            "periodic": [bool(v) for v in self.periodic],
            "fixed": [bool(v) for v in self.fixed],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Box:
        return cls(
            names=tuple(d["names"]),
            lower=np.asarray(d["lower"], dtype=np.float64),
            upper=np.asarray(d["upper"], dtype=np.float64),
            center=np.asarray(d["center"], dtype=np.float64),
            bound_lo=np.asarray(d["bound_lo"], dtype=np.float64),
            bound_hi=np.asarray(d["bound_hi"], dtype=np.float64),
            periodic=np.asarray(d["periodic"], dtype=bool),
            fixed=np.asarray(d["fixed"], dtype=bool),
        )


def _fixed_mask(mechanism: Mechanism, fixed: Iterable[str]) -> NDArray[np.bool_]:
    names = mechanism.param_names
    fixed = tuple(fixed)
    unknown = [f for f in fixed if f not in names]
    if unknown:
        raise ValueError(f"{mechanism.name} has no parameter {unknown[0]!r}; known: {', '.join(names)}")
    mask = np.array([n in fixed for n in names])
    if mask.all():
        raise ValueError(f"every parameter of {mechanism.name} is fixed: a search needs at least one free parameter")
    return mask


def _center(mechanism: Mechanism, center: F64 | None, lo: F64, hi: F64) -> F64:
    per = periodic_mask(mechanism)
    if center is None:
        c = 0.5 * (lo + hi)
    else:
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (mechanism.n_params,):
            raise ValueError(f"{mechanism.name} takes {mechanism.n_params} parameters, got {c.shape[0]}")
        if not np.isfinite(c).all():
            raise ValueError("the box centre has non-finite entries")
    # A centre outside the global bounds (a hand-made design) is first clipped onto them.
    return np.where(per, wrap(c, lo), np.clip(c, lo, hi))


def global_box(mechanism: Mechanism, center: F64 | None = None, fixed: Iterable[str] = (), scale: float = 1.0) -> Box:
    """The mechanism's global bounds (predesign, single-level runs).

    Args:
        mechanism: the topology.
        center: ``(n_params,)`` values of the fixed parameters (and the reference point);
            default the middle of the bounds.
        fixed: names of parameters held at ``center``.
        scale: the leg's size relative to the paper's 300 mm stride; sized bounds are multiplied by it
            (``core.optimize.scale``).
    """
    lo, hi = sized_bounds(mechanism, scale)
    return Box(mechanism.param_names, lo, hi, _center(mechanism, center, lo, hi), lo, hi, periodic_mask(mechanism),
               _fixed_mask(mechanism, fixed))


def half_widths(mechanism: Mechanism, center: F64, s: float, d: float) -> F64:
    """``(n_params,)`` spec §6 half-widths ``max(s|x|, d)``, with ``d = s·π`` for angles."""
    is_angle = np.array([p.kind == "angle" for p in mechanism.params])
    dd = np.where(is_angle, s * np.pi, d)
    return np.maximum(s * np.abs(np.asarray(center, dtype=np.float64)), dd)


def search_box(mechanism: Mechanism, center: F64, s: float, d: float, fixed: Iterable[str] = (),
               scale: float = 1.0) -> Box:
    """The box ``x ± max(s|x|, d)`` around a pick, clipped to the global bounds (spec §6).

    Args:
        mechanism: the topology.
        center: ``(n_params,)`` the previous pick (mm, rad).
        s: relative half-width (0.2 for subtask 1).
        d: absolute minimum half-width (mm; 20 for subtask 1); angles use ``s·π``.
        fixed: names of parameters held at the centre.
        scale: as for ``global_box`` (the clipping bounds; ``d`` is taken as given).
    """
    if not (0.0 < s < np.inf and 0.0 < d < np.inf):
        raise ValueError(f"box scale s and width d must be finite and > 0, got s={s}, d={d}")
    lo, hi = sized_bounds(mechanism, scale)
    per = periodic_mask(mechanism)
    c = _center(mechanism, center, lo, hi)
    h = half_widths(mechanism, c, s, d)
    lower = np.where(per, c - np.minimum(h, np.pi), np.maximum(c - h, lo))
    upper = np.where(per, c + np.minimum(h, np.pi), np.minimum(c + h, hi))
    return Box(mechanism.param_names, lower, upper, c, lo, hi, per, _fixed_mask(mechanism, fixed))
