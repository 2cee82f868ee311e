"""A design: a mechanism, a population of parameter vectors and an output stage."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from core.kinematics.checks import instance, real_array
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.kinematics.solver import Solution, solve


@dataclass(frozen=True)
class Design:
    """Frozen: a topology plus ``params`` of shape ``(pop, n_params)`` (mm, rad).

    One design is ``pop = 1``. The output stage maps the tracked point to the leg frame.
    ``params`` must be real numbers: floats of any width, or integers, are stored as float64;
    strings, booleans, complex numbers, dates and ``Decimal`` raise TypeError. Any float value
    is accepted (NaN, inf, negative lengths): the solvers judge it with a violation.
    """

    mechanism: Mechanism
    params: NDArray[np.float64]
    output: OutputStage = field(default=IDENTITY)

    def __post_init__(self) -> None:
        instance(self.mechanism, Mechanism, "design mechanism")
        instance(self.output, OutputStage, "design output")
        p = np.atleast_2d(real_array(self.params, f"{self.mechanism.name} params"))
        if p.ndim != 2 or p.shape[1] != self.mechanism.n_params:
            raise ValueError(
                f"{self.mechanism.name} takes {self.mechanism.n_params} parameters "
                f"({', '.join(self.mechanism.param_names)}), got shape {np.shape(self.params)}"
            )
        p.setflags(write=False)
        object.__setattr__(self, "params", p)

    @property
    def pop(self) -> int:
        return int(self.params.shape[0])

    def named(self, i: int = 0) -> dict[str, float]:
        """Member i as ``{name: value}``."""
        return {n: float(v) for n, v in zip(self.mechanism.param_names, self.params[i], strict=True)}

    def replace(self, **values: float) -> Design:
        """A copy with some named parameters changed (for every member)."""
        p = self.params.copy()
        names = self.mechanism.param_names
        for name, v in values.items():
            if name not in names:
                raise ValueError(f"{self.mechanism.name} has no parameter {name!r}; its parameters: {', '.join(names)}")
            p[:, names.index(name)] = v
        return Design(self.mechanism, p, self.output)

    def scaled(self, factor: float) -> Design:
        """The same linkage ``factor`` times the size: every length, offset and position (and the output stage's
        centre) multiplied, angles and the output ratio kept, so the motion is the same and every path scales by
        ``factor``. ValueError unless ``factor`` is a positive finite number."""
        f = float(factor)
        if not (np.isfinite(f) and f > 0):
            raise ValueError(f"a scale factor must be a positive number, got {factor}")
        sized = np.array([p.kind != "angle" for p in self.mechanism.params])
        params = np.where(sized, self.params * f, self.params)
        out = dataclasses.replace(self.output, ox=self.output.ox * f, oy=self.output.oy * f)
        return Design(self.mechanism, params, out)

    def solve(self, n_samples: int = 360, **kw: object) -> Solution:
        return solve(self.mechanism, self.params, n_samples, output=self.output, **kw)  # type: ignore[arg-type]
