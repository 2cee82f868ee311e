"""The paper's subtasks 1-3 (§3.2) and the single-level problem (§3.4.3) as registered problems.

Every problem evaluates a population with ``core.analysis.evaluate`` and returns named ``(pop,)``
metrics (see :func:`shape_metrics`):

- ``subtask1``: minimise f1 (shape error, mm), f2 (width penalty, Eq. 20, mm^2) and f3
  ((y_min - y_target_min)^2, mm^2; ``(y_min + H)^2`` for the cycloid), subject to assembly.
- ``subtask2``: minimise f4 = h_s (mm) and f5 = I (mm/s) subject to assembly and Eq. 22
  (f1 <= 6, f2 <= 5, f3 <= 5).
- ``subtask3``: as subtask 2, plus Eq. 23 (f4 <= 6.5, f5 <= 20).

The thresholds are the paper's for its 300 mm stride. A limit left out (None) is the paper's, sized to the
target (``core.optimize.scale``: x k for mm and mm/s, x k^2 for mm^2); the spec records the number it took.
- ``single_level``: all five objectives at once, subject to assembly (paper §3.4.3).

Decisions where the paper is silent or misprinted (docs/optimization.md):
- Eq. 20 as printed jumps at l = 290 and 310 (0.05 just outside, ~100 just inside). We read
  it as "(l - L)^2 inside the ±10 mm band, five times steeper outside" and make it continuous
  and smooth: ``f2 = e^2 + 4 max(0, |e| - 10)^2`` with ``e = l - L``.
- The thresholds of Eqs. 22-23 are ``<=`` constraints (pymoo's convention); they are options.
- Eq. 30 (order, 15 degree landing/take-off angles) was not applied in §3 (the paper's own X3
  has theta1 < 15 degrees); ``eq30=True`` adds it as three constraints.
- A target without a time law (a CSV curve of points only) is compared at the best cyclic
  shift (``mse_phase``); the nominal width and lowest point come from the target itself.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.design import Design
from core.optimize.objectives import (
    DEFAULT_TARGET,
    EQ22,
    EQ23,
    LABELS,
    load_target,
    shape_metrics,
    target_scale,
)
from core.optimize.predesign import place as place_designs
from core.optimize.predesign import placement_misfit, predesign_problem
from core.optimize.problem import ASSEMBLY, Constraint, Metrics, ProblemSpec, register, transmission_limits
from core.optimize.scale import scaled_limit

F64 = NDArray[np.float64]

def _evaluator(target: str, n_samples: int, backend: str) -> Any:
    load_target(target)  # fail early (ValueError) on a bad target option

    def ev(design: Design) -> Metrics:
        return shape_metrics(design, target, n_samples, backend)  # type: ignore[arg-type]

    return ev


def _limits(target: str, n_samples: int, **given: float | None) -> tuple[float, dict[str, float]]:
    """The target's scale and every limit in ``given`` (``f1_max=None``: Eq. 22/23's, sized to the target)."""
    k = target_scale(target, n_samples)
    paper = {"f1_max": EQ22["f1"], "f2_max": EQ22["f2"], "f3_max": EQ22["f3"], "h_s_max": EQ23["h_s"],
             "I_max": EQ23["I"]}
    return k, {key: float(v) if v is not None else scaled_limit(key[:-4], paper[key], k) for key, v in given.items()}


def _eq30(on: bool) -> tuple[Constraint, ...]:
    if not on:
        return ()
    return (Constraint("order", upper=0.0), Constraint("theta1_margin", upper=0.0),
            Constraint("theta2_margin", upper=0.0))


def _placement(place: str, target: str, n_samples: int, backend: str) -> dict[str, Any]:
    """A problem's ``repair`` (the Lamarckian placement) and its ``misfit`` (the mechanisms it cannot place)."""
    repair = _placer(place, target, n_samples, backend)
    return {"repair": repair, "misfit": None if repair is None else placement_misfit}


def _placer(place: str, target: str, n_samples: int, backend: str) -> Any:
    if place == "none":
        return None
    if place not in ("lsq", "extent", "hold"):
        raise ValueError(f"place must be 'none', 'lsq', 'extent' or 'hold', got {place!r}")

    def repair(design: Design) -> F64:
        return place_designs(design, target, n_samples, backend, fit=place)[0]  # type: ignore[arg-type]

    return repair


@register("subtask1")
def subtask1(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
             eq30: bool = False, place: str = "extent", transmission_min: float = 0.0) -> ProblemSpec:
    """Subtask 1 (Eq. 20): overall shape and position, objectives f1, f2, f3.

    Args:
        place: Lamarckian placement of every new member before evaluation (``core.optimize.predesign``):
            ``extent`` (default) scales, rotates and shifts the design so its path has the target's
            width and lowest point (f2 = f3 = 0 up to clipping to the box) and is otherwise the
            least-squares fit; ``lsq`` the plain least-squares fit; ``none`` the paper's literal
            search, where the optimizer finds the position itself (much slower).
        transmission_min: a lower limit on the worst transmission angle (deg; 0, the default, sets none). Every
            subtask and ``single_level`` take it.
    """
    return ProblemSpec("subtask1", _evaluator(target, n_samples, backend), ("f1", "f2", "f3"),
                       (ASSEMBLY, *_eq30(eq30), *transmission_limits(transmission_min)), labels=LABELS,
                       **_placement(place, target, n_samples, backend), scale=target_scale(target, n_samples))


@register("subtask2")
def subtask2(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto", f1_max: float | None = None,
             f2_max: float | None = None, f3_max: float | None = None, eq30: bool = False,
             place: str = "none", transmission_min: float = 0.0) -> ProblemSpec:
    """Subtask 2 (Eqs. 21-22): objectives h_s, I; the subtask-1 objectives become constraints.

    Limits left None are Eq. 22's 6 mm, 5 mm^2, 5 mm^2 sized to the target (module doc).
    """
    k, lim = _limits(target, n_samples, f1_max=f1_max, f2_max=f2_max, f3_max=f3_max)
    cons = (ASSEMBLY, Constraint("f1", upper=lim["f1_max"]), Constraint("f2", upper=lim["f2_max"]),
            Constraint("f3", upper=lim["f3_max"]))
    return ProblemSpec("subtask2", _evaluator(target, n_samples, backend), ("h_s", "I"),
                       cons + _eq30(eq30) + transmission_limits(transmission_min), options=lim,
                       labels=LABELS, **_placement(place, target, n_samples, backend), scale=k)


@register("subtask3")
def subtask3(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto", f1_max: float | None = None,
             f2_max: float | None = None, f3_max: float | None = None, h_s_max: float | None = None,
             I_max: float | None = None, eq30: bool = False, place: str = "none",
             transmission_min: float = 0.0) -> ProblemSpec:
    """Subtask 3 (Eqs. 21-23): objectives h_s, I under Eq. 22 and f4 <= 6.5, f5 <= 20.

    Limits left None are the paper's sized to the target (module doc).
    """
    k, lim = _limits(target, n_samples, f1_max=f1_max, f2_max=f2_max, f3_max=f3_max, h_s_max=h_s_max, I_max=I_max)
    cons = (ASSEMBLY, Constraint("f1", upper=lim["f1_max"]), Constraint("f2", upper=lim["f2_max"]),
            Constraint("f3", upper=lim["f3_max"]), Constraint("h_s", upper=lim["h_s_max"]),
            Constraint("I", upper=lim["I_max"]))
    return ProblemSpec("subtask3", _evaluator(target, n_samples, backend), ("h_s", "I"),
                       cons + _eq30(eq30) + transmission_limits(transmission_min), options=lim,
                       labels=LABELS, **_placement(place, target, n_samples, backend), scale=k)


@register("single_level")
def single_level(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
                 eq30: bool = False, place: str = "none", transmission_min: float = 0.0) -> ProblemSpec:
    """Single-level optimization (§3.4.3): f1 ... f5 at once, subject to assembly.

    Args:
        place: as for ``subtask1`` (``none``, the paper's direct search, by default).
    """
    return ProblemSpec("single_level", _evaluator(target, n_samples, backend), ("f1", "f2", "f3", "h_s", "I"),
                       (ASSEMBLY, *_eq30(eq30), *transmission_limits(transmission_min)), labels=LABELS,
                       **_placement(place, target, n_samples, backend), scale=target_scale(target, n_samples))


@register("predesign")
def predesign(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
              n_harmonics: int = 16, fit: str = "extent", transmission_min: float = 0.0) -> ProblemSpec:
    """Predesign X0 (§3.1): Fourier-descriptor matching over the global box with analytic placement.

    See ``core.optimize.predesign`` (registered here, the module the problem registry imports).
    ``transmission_min``: a lower limit on the worst transmission angle (deg; 0, the paper's, sets none): the
    predesign's only constraint is assembly, and matching the shape pushes designs onto a dead point.
    """

    return predesign_problem(target, n_samples, backend, n_harmonics, fit, transmission_min)


# Options that are upper limits on a metric, and that metric: a configuration may give them
# relative to the stage's start design ("start+0.5", "start*1.05"), see ``resolve_limits``.
LIMIT_METRICS: dict[str, str] = {"f1_max": "f1", "f2_max": "f2", "f3_max": "f3", "h_s_max": "h_s", "I_max": "I"}


def parse_relative(text: str) -> tuple[str, float]:
    """``"start+0.5"`` -> ("+", 0.5), ``"start*1.05"`` -> ("*", 1.05).

    Raises:
        ValueError: anything else (negative offsets and factors below 1 included: a limit below
            the start's own value would make the start infeasible).
    """
    t = text.replace(" ", "")
    if len(t) > 6 and t.startswith("start") and t[5] in "+*":
        try:
            v = float(t[6:])
        except ValueError:
            v = float("nan")
        if np.isfinite(v) and (v >= 0.0 if t[5] == "+" else v >= 1.0):
            return t[5], v
    raise ValueError(f"{text!r} is not a relative limit; use 'start+X' (X >= 0) or 'start*X' (X >= 1)")


def resolve_limits(options: dict[str, Any], start: Metrics) -> dict[str, Any]:
    """Options with relative limits replaced by numbers computed from the start design's metrics.

    A limit is a number, a relative string (``"start+0.5"``, ``"start*1.05"``), or a list of
    those meaning the loosest of them (``[4.0, "start+0.05"]``: 4, or a little above the start
    if the start already exceeds 4, so a stage never starts infeasible).

    Args:
        options: problem options; values of ``LIMIT_METRICS`` keys may be relative or lists.
        start: ``{metric: (1,)}`` metrics of the stage's start design (``shape_metrics``).

    Raises:
        ValueError: a relative limit on a metric the start does not have, or whose value is not finite.
    """
    out = dict(options)
    for key, value in options.items():
        if key not in LIMIT_METRICS or not isinstance(value, (str, list, tuple)):
            continue
        resolved = []
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if not isinstance(item, str):
                resolved.append(float(item))
                continue
            op, v = parse_relative(item)
            base = float(np.asarray(start[LIMIT_METRICS[key]]).reshape(-1)[0])
            if not np.isfinite(base):
                raise ValueError(f"{key} = {value!r}: the start design has no finite {LIMIT_METRICS[key]}")
            resolved.append(base + v if op == "+" else base * v)
        out[key] = max(resolved)
    return out
