"""The paper's subtasks 1-3 (§3.2) and the single-level problem (§3.4.3) as registered problems.

Every problem evaluates a population with ``core.evaluate`` and returns named ``(pop,)``
metrics (see :func:`shape_metrics`):

- ``subtask1``: minimise f1 (shape error, mm), f2 (width penalty, Eq. 20, mm^2) and f3
  ((y_min - y_target_min)^2, mm^2; ``(y_min + H)^2`` for the cycloid), subject to assembly.
- ``subtask2``: minimise f4 = h_s (mm) and f5 = I (mm/s) subject to assembly and Eq. 22
  (f1 <= 6, f2 <= 5, f3 <= 5).
- ``subtask3``: as subtask 2, plus Eq. 23 (f4 <= 6.5, f5 <= 20).
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

from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.design import Design
from core.evaluate import Backend, Evaluation, evaluate
from core.optimize.problem import ASSEMBLY, Constraint, Metrics, ProblemSpec, register
from core.targets import Target, parse_target

F64 = NDArray[np.float64]

DEFAULT_TARGET = "cycloid"
# Added to the violation of a design that does not assemble (or whose path cannot be read). pymoo
# sums constraint violations, and an unassembled member's other constraints are undefined (counted
# 0): without a tier, a design at the edge of assembly (violation ~1e-9) would outrank every
# assembled design that misses a threshold by a little, and a stage that starts infeasible drifts
# to such degenerate designs. With it: feasible < assembled but over a threshold < unassembled,
# and inside each tier the measure stays continuous (the shortfall in mm).
ASSEMBLY_TIER = 1000.0
WIDTH_BAND = 10.0  # mm: Eq. 20's 290 < l < 310 around L = 300
WIDTH_STEEP = 5.0  # Eq. 20's factor outside the band
# Eq. 22 and Eq. 23 thresholds.
EQ22 = {"f1": 6.0, "f2": 5.0, "f3": 5.0}
EQ23 = {"h_s": 6.5, "I": 20.0}

LABELS: dict[str, str] = {
    "f1": "f1 = MSE (mm)",
    "f2": "f2 = width penalty (mm^2)",
    "f3": "f3 = (y_min + H)^2 (mm^2)",
    "h_s": "f4 = h_s (mm)",
    "I": "f5 = I (mm/s)",
    "mse": "MSE (mm)",
    "S": "S (%)",
    "width": "width (mm)",
    "y_min": "y_min (mm)",
    "l_s": "l_s (mm)",
    "theta1": "theta1 (rad)",
    "theta2": "theta2 (rad)",
    "order": "Eq. 30 order (rad)",
    "theta1_margin": "15 deg - theta1 (rad)",
    "theta2_margin": "15 deg - theta2 (rad)",
    "violation": "violation",
    "violation_mm": "assembly shortfall (mm)",
}


def width_penalty(width: F64, nominal: float, band: float = WIDTH_BAND) -> F64:
    """Eq. 20's f2, continuous reading (module doc): ``e^2 + (5 - 1) max(0, |e| - band)^2`` (mm^2).

    Args:
        width: ``(pop,)`` path width x_max - x_min (mm); NaN stays NaN.
        nominal: the target width L (mm).
        band: half-width of the quadratic band (mm).
    """
    e = np.asarray(width, dtype=np.float64) - nominal
    return e * e + (WIDTH_STEEP - 1.0) * np.maximum(0.0, np.abs(e) - band) ** 2


@lru_cache(maxsize=32)
def load_target(spec: str) -> Target:
    """A target from its option string (``cycloid``, ``cycloid:L=300,H=100,T=2`` or a CSV path); cached."""
    return parse_target(spec)


def target_extent(target: Target, n_samples: int) -> tuple[float, float]:
    """The target's nominal width (x extent, mm) and lowest y (mm) at n samples."""
    pts = target.sample(n_samples)
    return float(pts[:, 0].max() - pts[:, 0].min()), float(pts[:, 1].min())


def shape_metrics(design: Design, target: str = DEFAULT_TARGET, n_samples: int = 360,
                  backend: Backend = "auto") -> Metrics:
    """Every metric the shape-target problems use, ``{name: (pop,)}``.

    Keys: f1, f2, f3 (subtask 1 objectives), mse, width, y_min, h_s, S, I, l_s, theta1,
    theta2, order (Eq. 30 order value, rad), theta1_margin, theta2_margin (15 degrees minus
    the angle, rad), violation (assembly and path validity, >= 0).
    """
    tgt = load_target(target)
    ev = evaluate(design, n_samples, target=tgt, period=tgt.period, backend=backend,
                  phase_optimal=not tgt.has_time)
    return {k: quantize(v) for k, v in metrics_of(ev, tgt).items()}


def metrics_of(ev: Evaluation, target: Target) -> Metrics:
    """Named metrics of an :class:`Evaluation` against a shape target (see :func:`shape_metrics`)."""
    width0, ymin0 = target_extent(target, ev.n_samples)
    f1 = ev.mse if target.has_time else ev.mse_phase
    return {
        "f1": f1,
        "f2": width_penalty(ev.width, width0),
        "f3": (ev.y_min - ymin0) ** 2,
        "mse": f1,
        "width": ev.width,
        "y_min": ev.y_min,
        "h_s": ev.h_s,
        "S": ev.S,
        "I": ev.I,
        "l_s": ev.l_s,
        "theta1": ev.theta1,
        "theta2": ev.theta2,
        "order": ev.constraints[:, 0],
        "theta1_margin": ev.constraints[:, 1],
        "theta2_margin": ev.constraints[:, 2],
        "violation_mm": ev.violation,
        "violation": tiered(ev.violation),
    }


def quantize(values: F64) -> F64:
    """Values rounded to 10 significant digits, and never finer than 1e-9 (NaN and inf unchanged).

    Two designs whose metrics differ only by floating-point noise (~1e-14) then compare equal, so
    a front never holds two "different" members closer than the knee-point code can normalise
    (``core.decision.normalize`` treats such spans as zero and, as of this writing, fails when
    every column of a front is such a span).
    """
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(np.isfinite(v) & (v != 0.0), np.floor(np.log10(np.abs(v))), 0.0)
    step = np.maximum(1e-9, 10.0 ** (mag - 9.0))
    return np.where(np.isfinite(v), np.round(v / step) * step, v)


def tiered(violation: F64) -> F64:
    """``(pop,)`` assembly violation for pymoo: 0 where a design assembles, else ``ASSEMBLY_TIER`` + the
    shortfall (mm); a non-finite violation (a path that cannot be read) becomes twice the tier."""
    v = np.asarray(violation, dtype=np.float64)
    return np.where(v > 0.0, ASSEMBLY_TIER + np.where(np.isfinite(v), v, ASSEMBLY_TIER), 0.0)


def _evaluator(target: str, n_samples: int, backend: str) -> Any:
    load_target(target)  # fail early (ValueError) on a bad target option

    def ev(design: Design) -> Metrics:
        return shape_metrics(design, target, n_samples, backend)  # type: ignore[arg-type]

    return ev


def _eq30(on: bool) -> tuple[Constraint, ...]:
    if not on:
        return ()
    return (Constraint("order", upper=0.0), Constraint("theta1_margin", upper=0.0),
            Constraint("theta2_margin", upper=0.0))


def _placer(place: str, target: str, n_samples: int, backend: str) -> Any:
    if place == "none":
        return None
    if place not in ("lsq", "extent", "hold"):
        raise ValueError(f"place must be 'none', 'lsq', 'extent' or 'hold', got {place!r}")
    from core.optimize.predesign import place as place_designs

    def repair(design: Design) -> F64:
        return place_designs(design, target, n_samples, backend, fit=place)[0]  # type: ignore[arg-type]

    return repair


@register("subtask1")
def subtask1(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
             eq30: bool = False, place: str = "extent") -> ProblemSpec:
    """Subtask 1 (Eq. 20): overall shape and position, objectives f1, f2, f3.

    Args:
        place: Lamarckian placement of every new member before evaluation (``core.optimize.predesign``):
            ``extent`` (default) scales, rotates and shifts the design so its path has the target's
            width and lowest point (f2 = f3 = 0 up to clipping to the box) and is otherwise the
            least-squares fit; ``lsq`` the plain least-squares fit; ``none`` the paper's literal
            search, where the optimizer finds the position itself (much slower).
    """
    return ProblemSpec("subtask1", _evaluator(target, n_samples, backend), ("f1", "f2", "f3"),
                       (ASSEMBLY, *_eq30(eq30)), labels=LABELS, repair=_placer(place, target, n_samples, backend))


@register("subtask2")
def subtask2(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto", f1_max: float = EQ22["f1"],
             f2_max: float = EQ22["f2"], f3_max: float = EQ22["f3"], eq30: bool = False,
             place: str = "none") -> ProblemSpec:
    """Subtask 2 (Eqs. 21-22): objectives h_s, I; the subtask-1 objectives become constraints."""
    cons = (ASSEMBLY, Constraint("f1", upper=f1_max), Constraint("f2", upper=f2_max), Constraint("f3", upper=f3_max))
    return ProblemSpec("subtask2", _evaluator(target, n_samples, backend), ("h_s", "I"), cons + _eq30(eq30),
                       labels=LABELS, repair=_placer(place, target, n_samples, backend))


@register("subtask3")
def subtask3(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto", f1_max: float = EQ22["f1"],
             f2_max: float = EQ22["f2"], f3_max: float = EQ22["f3"], h_s_max: float = EQ23["h_s"],
             I_max: float = EQ23["I"], eq30: bool = False, place: str = "none") -> ProblemSpec:
    """Subtask 3 (Eqs. 21-23): objectives h_s, I under Eq. 22 and f4 <= 6.5, f5 <= 20."""
    cons = (ASSEMBLY, Constraint("f1", upper=f1_max), Constraint("f2", upper=f2_max), Constraint("f3", upper=f3_max),
            Constraint("h_s", upper=h_s_max), Constraint("I", upper=I_max))
    return ProblemSpec("subtask3", _evaluator(target, n_samples, backend), ("h_s", "I"), cons + _eq30(eq30),
                       labels=LABELS, repair=_placer(place, target, n_samples, backend))


@register("single_level")
def single_level(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
                 eq30: bool = False, place: str = "none") -> ProblemSpec:
    """Single-level optimization (§3.4.3): f1 ... f5 at once, subject to assembly.

    Args:
        place: as for ``subtask1`` (``none``, the paper's direct search, by default).
    """
    return ProblemSpec("single_level", _evaluator(target, n_samples, backend), ("f1", "f2", "f3", "h_s", "I"),
                       (ASSEMBLY, *_eq30(eq30)), labels=LABELS, repair=_placer(place, target, n_samples, backend))


@register("predesign")
def predesign(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
              n_harmonics: int = 16, fit: str = "extent") -> ProblemSpec:
    """Predesign X0 (§3.1): Fourier-descriptor matching over the global box with analytic placement.

    See ``core.optimize.predesign`` (registered here, the module the problem registry imports).
    """
    from core.optimize.predesign import predesign_problem

    return predesign_problem(target, n_samples, backend, n_harmonics, fit)


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
