"""The target the studio compares against: the compound cycloid of spec §3 with the Target panel's L, H, T.

The curve itself comes from ``core.targets``; this is the panel's small, validated, JSON-ready
set of settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.targets import Target, compound_cycloid, cycloid_target

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class TargetSpec:
    """The compound-cycloid target: step length L (mm), height H (mm), period T (s)."""

    length: float = 300.0
    height: float = 100.0
    period: float = 2.0

    def __post_init__(self) -> None:
        for name, unit in (("length", "mm"), ("height", "mm"), ("period", "s")):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0.0:
                raise ValueError(f"target {name} must be a positive number ({unit}), got {v!r}")

    def points(self, n_samples: int) -> F64:
        """``(n_samples, 2)`` target in the design frame (mm), uniform in time over one period."""
        return compound_cycloid(n_samples, float(self.length), float(self.height))[0]

    def target(self) -> Target:
        """The ``core.targets.Target`` for ``core.evaluate``."""
        return cycloid_target(float(self.length), float(self.height), float(self.period))

    def to_dict(self) -> dict[str, float]:
        return {"L": float(self.length), "H": float(self.height), "T": float(self.period)}

    @staticmethod
    def from_dict(data: object) -> TargetSpec:
        if not isinstance(data, dict):
            raise ValueError(f"target must be an object {{L, H, T}}, got {data!r}")
        unknown = [k for k in data if k not in ("L", "H", "T")]
        if unknown:
            raise ValueError(f"unknown target key {unknown[0]!r}; expected L, H, T")
        d = TargetSpec()
        return TargetSpec(data.get("L", d.length), data.get("H", d.height), data.get("T", d.period))
