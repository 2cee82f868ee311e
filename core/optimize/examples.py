"""Small problems for tests and docs (``EXAMPLES``; the studio's Problem list leaves them out).

- ``bowl``: analytic, no kinematics. Over a mechanism's non-angle parameters scaled to
  u in [-1, 1]: f1 = mean((u - a)^2), f2 = mean((u + a)^2), subject to mean(u) <= limit and a
  continuous pseudo-assembly violation sum(max(0, |u| - 0.9)). Its Pareto set is u_i = c for
  all i, c in [-a, min(a, limit)]: f1 = (c - a)^2, f2 = (c + a)^2.
- ``path_box``: the real solver. The tracked point's design-frame path should be ``width``
  wide and reach down to ``y_min``: f1 = (x_max - x_min - width)^2, f2 = (min y - y_min)^2
  (mm^2), subject to assembly.
"""

from __future__ import annotations

import numpy as np

from core.kinematics.design import Design
from core.kinematics.solver import solve
from core.optimize.problem import ASSEMBLY, Constraint, Metrics, ProblemSpec, register

EXAMPLES = ("bowl", "path_box")


@register("bowl")
def bowl(a: float = 0.2, limit: float = 0.1) -> ProblemSpec:
    """The analytic two-objective test problem (see module doc)."""

    def evaluate(design: Design) -> Metrics:
        m = design.mechanism
        keep = np.array([p.kind != "angle" for p in m.params])
        lo, hi = m.lower[keep], m.upper[keep]
        u = 2.0 * (design.params[:, keep] - lo) / (hi - lo) - 1.0
        return {
            "f1": np.mean((u - a) ** 2, axis=1),
            "f2": np.mean((u + a) ** 2, axis=1),
            "mean_u": u.mean(axis=1),
            "violation": np.maximum(0.0, np.abs(u) - 0.9).sum(axis=1),
        }

    return ProblemSpec("bowl", evaluate, ("f1", "f2"), (ASSEMBLY, Constraint("mean_u", upper=limit)),
                       labels={"f1": "f1 (-)", "f2": "f2 (-)"})


@register("path_box")
def path_box(width: float = 300.0, y_min: float = -100.0, n_samples: int = 72, backend: str = "numpy") -> ProblemSpec:
    """Path width and lowest point of the tracked point (design frame), by the batch solver."""

    def evaluate(design: Design) -> Metrics:
        sol = solve(design.mechanism, design.params, n_samples, output=design.output, joints=False,
                    backend=backend)  # type: ignore[arg-type]
        x, y = sol.point[..., 0], sol.point[..., 1]
        ok = sol.valid.all(axis=1)
        with np.errstate(invalid="ignore"):
            w = np.where(ok, np.max(x, axis=1) - np.min(x, axis=1), np.nan)
            low = np.where(ok, np.min(y, axis=1), np.nan)
        return {
            "f1": (w - width) ** 2,
            "f2": (low - y_min) ** 2,
            "width": w,
            "y_min": low,
            "violation": sol.violation,
        }

    return ProblemSpec("path_box", evaluate, ("f1", "f2"), (ASSEMBLY,),
                       labels={"f1": "(width - L)^2 (mm^2)", "f2": "(y_min + H)^2 (mm^2)", "width": "width (mm)",
                               "y_min": "y_min (mm)"})
