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
    "violation": "violation",
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
    return metrics_of(ev, tgt)


def metrics_of(ev: Evaluation, target: Target) -> Metrics:
    """Named metrics of an :class:`Evaluation` against a shape target (see :func:`shape_metrics`)."""
    width0, ymin0 = target_extent(target, ev.n_samples)
    f1 = ev.mse if target.has_time else ev.mse_phase
    viol = np.where(np.isfinite(ev.violation), ev.violation, np.nan)
    # A path the analysis cannot read (non-finite violation) is never feasible; keep it finite for pymoo.
    viol = np.where(np.isnan(viol), 1e6, viol)
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
        "violation": viol,
    }


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
    if place not in ("lsq", "extent"):
        raise ValueError(f"place must be 'none', 'lsq' or 'extent', got {place!r}")
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
             f2_max: float = EQ22["f2"], f3_max: float = EQ22["f3"], eq30: bool = False) -> ProblemSpec:
    """Subtask 2 (Eqs. 21-22): objectives h_s, I; the subtask-1 objectives become constraints."""
    cons = (ASSEMBLY, Constraint("f1", upper=f1_max), Constraint("f2", upper=f2_max), Constraint("f3", upper=f3_max))
    return ProblemSpec("subtask2", _evaluator(target, n_samples, backend), ("h_s", "I"), cons + _eq30(eq30),
                       labels=LABELS)


@register("subtask3")
def subtask3(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto", f1_max: float = EQ22["f1"],
             f2_max: float = EQ22["f2"], f3_max: float = EQ22["f3"], h_s_max: float = EQ23["h_s"],
             I_max: float = EQ23["I"], eq30: bool = False) -> ProblemSpec:
    """Subtask 3 (Eqs. 21-23): objectives h_s, I under Eq. 22 and f4 <= 6.5, f5 <= 20."""
    cons = (ASSEMBLY, Constraint("f1", upper=f1_max), Constraint("f2", upper=f2_max), Constraint("f3", upper=f3_max),
            Constraint("h_s", upper=h_s_max), Constraint("I", upper=I_max))
    return ProblemSpec("subtask3", _evaluator(target, n_samples, backend), ("h_s", "I"), cons + _eq30(eq30),
                       labels=LABELS)


@register("single_level")
def single_level(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
                 eq30: bool = False) -> ProblemSpec:
    """Single-level optimization (§3.4.3): f1 ... f5 at once, subject to assembly."""
    return ProblemSpec("single_level", _evaluator(target, n_samples, backend), ("f1", "f2", "f3", "h_s", "I"),
                       (ASSEMBLY, *_eq30(eq30)), labels=LABELS)


@register("predesign")
def predesign(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
              n_harmonics: int = 16) -> ProblemSpec:
    """Predesign X0 (§3.1): Fourier-descriptor matching over the global box with analytic placement.

    See ``core.optimize.predesign`` (registered here, the module the problem registry imports).
    """
    from core.optimize.predesign import predesign_problem

    return predesign_problem(target, n_samples, backend, n_harmonics)
