"""What every shape-target problem measures: f1-f3 and the named metrics, targets by option string, tiers.

Shared by the predesign (``predesign``) and the subtasks (``subtasks``), below both of them.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from core.analysis.evaluate import Backend, Evaluation, evaluate
from core.analysis.targets import Target, parse_target
from core.kinematics.design import Design
from core.optimize.problem import Metrics
from core.optimize.scale import PAPER_STRIDE, stride_scale

F64 = NDArray[np.float64]

DEFAULT_TARGET = "cycloid"
# Added to the violation of a design that does not assemble (or whose path cannot be read). pymoo
# sums constraint violations, and an unassembled member's other constraints are undefined (counted
# 0): without a tier, a design at the edge of assembly (violation ~1e-9) would outrank every
# assembled design that misses a threshold by a little, and a stage that starts infeasible drifts
# to such degenerate designs. With it: feasible < assembled but over a threshold < unassembled,
# and inside each tier the measure stays continuous (the shortfall in mm).
ASSEMBLY_TIER = 1000.0
WIDTH_BAND = 10.0  # mm: Eq. 20's 290 < l < 310 around L = 300 (scaled with the target's width)
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
    "crank_margin": "crank margin (mm)",
    "transmission": "worst transmission angle (deg)",
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


def target_scale(target: str, n_samples: int) -> float:
    """The leg's size relative to the paper's: the target's width / 300 mm (``core.optimize.scale``)."""
    return stride_scale(target_extent(load_target(target), n_samples)[0])


def shape_metrics(design: Design, target: str = DEFAULT_TARGET, n_samples: int = 360,
                  backend: Backend = "auto") -> Metrics:
    """Every metric the shape-target problems use, ``{name: (pop,)}``.

    Keys: f1, f2, f3 (subtask 1 objectives), mse, width, y_min, h_s, S, I, l_s, theta1,
    theta2, order (Eq. 30 order value, rad), theta1_margin, theta2_margin (15 degrees minus
    the angle, rad), violation (assembly and path validity, >= 0), crank_margin (mm from a dead point),
    transmission (the worst transmission angle, deg).
    """
    tgt = load_target(target)
    ev = evaluate(design, n_samples, target=tgt, period=tgt.period, backend=backend,
                  phase_optimal=not tgt.has_time)
    return quantize_all(metrics_of(ev, tgt))


def metrics_of(ev: Evaluation, target: Target) -> Metrics:
    """Named metrics of an :class:`Evaluation` against a shape target (see :func:`shape_metrics`)."""
    width0, ymin0 = target_extent(target, ev.n_samples)
    f1 = ev.mse if target.has_time else ev.mse_phase
    return {
        "f1": f1,
        "f2": width_penalty(ev.width, width0, WIDTH_BAND * width0 / PAPER_STRIDE),
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
        # How far from a dead point (mm): a pick_where / starts.where limit ({crank_margin_min = 1.0}); picks 0.002 mm
        # from one, with transmission angles of 179.9 deg, could not be refused.
        "crank_margin": ev.crank_margin,
        # The worst transmission angle (deg, 90 ideal): {transmission_min = 40} keeps a pick away from designs that
        # assemble but transmit almost no force (the paper's X3 reads 21 deg).
        "transmission": ev.transmission,
    }


def quantize(values: F64) -> F64:
    """Values rounded to 10 significant digits, and never finer than 1e-9 (NaN and inf unchanged).

    Two designs whose metrics differ only by floating-point noise (~1e-14) then compare equal, so
    a front never holds two "different" members closer than the knee-point code can normalise
    (``core.optimize.decision.normalize`` treats such spans as zero and, as of this writing, fails when
    every column of a front is such a span).
    """
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(np.isfinite(v) & (v != 0.0), np.floor(np.log10(np.abs(v))), 0.0)
    step = np.maximum(1e-9, 10.0 ** (mag - 9.0))
    return np.where(np.isfinite(v), np.round(v / step) * step, v)


def quantize_all(metrics: Metrics) -> Metrics:
    """:func:`quantize` of every ``(pop,)`` metric, in one pass over their stack (one design at a time pays
    the per-call cost once, not once per metric)."""
    keys = list(metrics)
    if not keys:
        return {}
    q = quantize(np.stack([np.asarray(metrics[k], dtype=np.float64) for k in keys]))
    return {k: q[i] for i, k in enumerate(keys)}


def tiered(violation: F64) -> F64:
    """``(pop,)`` assembly violation for pymoo: 0 where a design assembles, else ``ASSEMBLY_TIER`` + the
    shortfall (mm); a non-finite violation (a path that cannot be read) becomes twice the tier."""
    v = np.asarray(violation, dtype=np.float64)
    return np.where((v > 0.0) | np.isnan(v), ASSEMBLY_TIER + np.where(np.isfinite(v), v, ASSEMBLY_TIER), 0.0)
