"""Predesign X0 (paper §3.1): Fourier-descriptor shape matching, then analytic placement.

The ``predesign`` problem searches a mechanism's global bounds. Every new member is first
*placed* (the problem's Lamarckian repair): its design-frame path is mapped onto the target
by the best similarity transform (``core.analysis.fourier.similarity_transform``: scale, rotation,
translation, cyclic shift), and the transform is applied to the design itself:

- lengths and signed offsets are multiplied by the scale;
- absolute ground points (``Ground`` steps without origin, e.g. the crank pivot x_a, y_a)
  are rotated, scaled and translated; world-frame offsets of a ground point from another one
  are rotated and scaled;
- direction angles of ground links (``Ground(..., angle=b)``) get the rotation added;
- crank phases get the rotation plus the cyclic shift as a crank angle (``Similarity.phase``).

The placed design's path is then exactly ``scale R path_(i + shift) + translation``, the
least-squares fit of the target. Objectives: ``fd`` (distance between the normalised Fourier
descriptors of path and target: the shape alone, invariant to placement and timing) and
``f1`` (the time-aligned shape error after placement). Constraint: assembly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from core.analysis import fourier
from core.analysis.evaluate import Backend
from core.kinematics.design import Design
from core.kinematics.model import Crank, Dyad, Ground, Mechanism, Operand
from core.optimize.objectives import DEFAULT_TARGET, LABELS, load_target, quantize, shape_metrics, target_scale
from core.optimize.problem import ASSEMBLY, Metrics, ProblemSpec, transmission_limits

F64 = NDArray[np.float64]

# Arc-length samples of the descriptors and grid of the start-point search (>= 4 harmonics each):
# enough for 16 harmonics, and half the cost of fourier's defaults.
N_RESAMPLE = 128
N_GRID = 256


@dataclass(frozen=True)
class Placement:
    """How a similarity transform of the design frame acts on a mechanism's parameter vector.

    Attributes:
        scaled: ``(n_params,)`` entries multiplied by the scale (lengths, offsets).
        points: ``(ix, iy, sx, sy, absolute)`` coordinate pairs (column indices, operand signs):
            absolute points are rotated, scaled and translated, relative ones rotated and scaled.
        directions: ``(n_params,)`` angles that get the rotation added.
        phases: ``(n_params,)`` crank phases that get the rotation plus the cyclic-shift angle.
    """

    scaled: NDArray[np.bool_]
    points: tuple[tuple[int, int, float, float, bool], ...]
    directions: NDArray[np.bool_]
    phases: NDArray[np.bool_]


def _operand(m: Mechanism, op: Operand) -> tuple[int, float] | None:
    """(column, sign) of a parameter operand; None for a constant."""
    if not isinstance(op, str):
        return None
    sign, name = (-1.0, op[1:]) if op.startswith("-") else (1.0, op)
    if name not in m.param_names:
        raise ValueError(f"{m.name}: no analytic placement (operand {op!r} is a derived value)")
    return m.param_names.index(name), sign


def placement_misfit(m: Mechanism) -> str | None:
    """Why a problem that places every design on its target analytically cannot optimize ``m``; None if it can."""
    try:
        placement(m)
    except ValueError as e:
        return f"it places every design on the target analytically, which this mechanism does not allow ({e})"
    return None


def placement(m: Mechanism) -> Placement:
    """The placement plan of a mechanism (see the module doc).

    Raises:
        ValueError: the mechanism's construction cannot follow a similarity transform (a fixed
            ground point, a constant length, a derived coupling), naming the step.
    """
    if m.derive is not None:
        raise ValueError(f"{m.name}: no analytic placement for a mechanism with derived values")
    n = m.n_params
    kinds = np.array([p.kind for p in m.params])
    scaled = np.isin(kinds, ("length", "offset"))
    directions = np.zeros(n, dtype=bool)
    phases = np.zeros(n, dtype=bool)
    points: list[tuple[int, int, float, float, bool]] = []
    paired = np.zeros(n, dtype=bool)

    def needs_scale(step: str, *ops: Operand) -> None:
        for op in ops:
            col = _operand(m, op)
            if col is None and float(op) != 0.0:
                raise ValueError(f"{m.name}: no analytic placement (step {step!r} has a constant length {op!r})")
            if col is not None and not scaled[col[0]]:
                raise ValueError(f"{m.name}: no analytic placement (step {step!r} uses {op!r} as a length)")

    def angle(step: str, op: Operand, into: NDArray[np.bool_]) -> None:
        col = _operand(m, op)
        if col is None:
            raise ValueError(f"{m.name}: no analytic placement (step {step!r} has a constant angle {op!r})")
        if col[1] < 0 or kinds[col[0]] != "angle":
            raise ValueError(f"{m.name}: no analytic placement (step {step!r}: angle operand {op!r})")
        into[col[0]] = True

    for s in m.steps:
        if isinstance(s, Ground):
            cu, cv = _operand(m, s.u), _operand(m, s.v)
            if isinstance(s.angle, str) and s.origin is not None:
                angle(s.name, s.angle, directions)
                needs_scale(s.name, s.u, s.v)
                continue
            if isinstance(s.angle, str) or float(s.angle) != 0.0 or cu is None or cv is None:
                raise ValueError(f"{m.name}: no analytic placement (ground point {s.name!r} cannot be moved)")
            points.append((cu[0], cv[0], cu[1], cv[1], s.origin is None))
            paired[[cu[0], cv[0]]] = True
        elif isinstance(s, Crank):
            angle(s.name, s.phase, phases)
            needs_scale(s.name, s.u, s.v)
        elif isinstance(s, Dyad):
            needs_scale(s.name, s.l1, s.l2)
        else:
            needs_scale(s.name, s.u, s.v)
    if (directions & phases).any():
        raise ValueError(f"{m.name}: no analytic placement (an angle is both a direction and a crank phase)")
    loose = (kinds == "position") & ~paired
    if loose.any():
        raise ValueError(f"{m.name}: no analytic placement (position {m.param_names[int(np.argmax(loose))]!r} "
                         "is not a ground point)")
    return Placement(scaled & ~paired, tuple(points), directions, phases)


def apply_placement(plan: Placement, params: F64, sim: fourier.Similarity) -> F64:
    """Parameter vectors ``(pop, n_params)`` after the similarity ``sim`` (NaN rows where sim is NaN)."""
    p = np.array(params, dtype=np.float64, copy=True)
    s, rot = sim.scale, sim.rotation
    factor = s * np.exp(1j * rot)
    shift = sim.translation[:, 0] + 1j * sim.translation[:, 1]
    p[:, plan.scaled] *= s[:, None]
    for ix, iy, sx, sy, absolute in plan.points:
        z = factor * (sx * params[:, ix] + 1j * sy * params[:, iy]) + (shift if absolute else 0.0)
        p[:, ix], p[:, iy] = sx * z.real, sy * z.imag
    p[:, plan.directions] += rot[:, None]
    p[:, plan.phases] += (rot + sim.phase)[:, None]
    p[~np.isfinite(s)] = np.nan
    return p


def place(design: Design, target: str = DEFAULT_TARGET, n_samples: int = 360, backend: Backend = "auto",
          fit: str = "lsq") -> tuple[F64, fourier.Similarity]:
    """Place a population on a target: parameters whose design-frame paths best fit it.

    Args:
        design: population to place.
        target: target option string (``cycloid`` or a CSV path, see ``objectives.load_target``).
        n_samples: crank samples (against the target's n time-uniform samples).
        backend: solver backend.
        fit: ``lsq`` the least-squares similarity; ``extent`` refined so the width and the lowest
            point match the target exactly (:func:`fit_extent`).

    Returns:
        ``(pop, n_params)`` placed parameters (angles not wrapped; NaN rows for unassemblable
        members) and the similarity that was applied.
    """
    plan = placement(design.mechanism)
    tgt = load_target(target).sample(n_samples)
    sol = design.solve(n_samples, joints=False, derivatives=False, backend=backend)
    point = np.where(sol.violation[:, None, None] == 0.0, sol.point, np.nan)
    sim = fourier.similarity_transform(point, tgt)
    if fit == "hold":
        sim = fit_extent(keep_rotation(sim, point, tgt), point, tgt)
    elif fit == "extent":
        sim = fit_extent(sim, point, tgt)
    return apply_placement(plan, design.params, sim), sim


def keep_rotation(sim: fourier.Similarity, point: F64, target: F64) -> fourier.Similarity:
    """The least-squares scale and translation at zero rotation (same cyclic shift as ``sim``)."""
    n = point.shape[1]
    idx = (np.arange(n)[None, :] + sim.shift[:, None]) % n
    src = np.take_along_axis(point, idx[..., None], 1)
    zs = src[..., 0] + 1j * src[..., 1]
    zq = target[None, :, 0] + 1j * target[None, :, 1]
    cs, cq = zs - zs.mean(1, keepdims=True), zq - zq.mean(1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.real((np.conj(cs) * cq).sum(1)) / (np.abs(cs) ** 2).sum(1)
    t = zq.mean(1) - scale * zs.mean(1)
    return fourier.Similarity(scale=scale, rotation=np.zeros_like(scale), translation=np.stack([t.real, t.imag], -1),
                              shift=sim.shift, phase=sim.phase, rms=sim.rms)


def fit_extent(sim: fourier.Similarity, point: F64, target: F64) -> fourier.Similarity:
    """Refine a similarity so the placed path has the target's width and lowest y exactly.

    The placed path is scaled about its centroid by target width / placed width, then shifted
    in y so its lowest point is the target's (the f2 and f3 inputs of subtask 1); rotation,
    cyclic shift and the x position of the centroid are kept.

    Args:
        sim: a similarity of ``point`` onto ``target`` (least squares, or with rotation held).
        point: ``(pop, n, 2)`` design-frame paths (mm).
        target: ``(n, 2)`` target samples (mm).
    """
    # Extent and centroid do not depend on the cyclic shift: transform the samples as they are.
    a, b = sim.scale * np.cos(sim.rotation), sim.scale * np.sin(sim.rotation)
    ext = np.empty((len(a), 5))
    _extent(np.ascontiguousarray(point), a, b, sim.translation[:, 0].copy(), sim.translation[:, 1].copy(), ext)
    xmin, xmax, ymin, cx, cy = ext.T
    width0, ymin0 = float(np.ptp(target[:, 0])), float(target[:, 1].min())
    with np.errstate(invalid="ignore", divide="ignore"):
        k = width0 / (xmax - xmin)
    # Scaled about the centroid: q' = c + k (q - c); then y shifted so min y' = ymin0.
    dy = ymin0 - (cy + k * (ymin - cy))
    tx = cx * (1.0 - k) + k * sim.translation[:, 0]
    ty = cy * (1.0 - k) + k * sim.translation[:, 1] + dy
    return fourier.Similarity(scale=sim.scale * k, rotation=sim.rotation, translation=np.stack([tx, ty], -1),
                              shift=sim.shift, phase=sim.phase, rms=sim.rms)


@numba.njit(cache=True, nogil=True)
def _extent(point: F64, a: F64, b: F64, tx: F64, ty: F64, out: F64) -> None:  # pragma: no cover - compiled
    # Per path after q = (a + ib) p + t: x min, x max, y min, centroid x, centroid y (NaN stays NaN).
    n = point.shape[1]
    for i in range(point.shape[0]):
        xmin, xmax, ymin, sx, sy = np.inf, -np.inf, np.inf, 0.0, 0.0
        for j in range(n):
            px, py = point[i, j, 0], point[i, j, 1]
            x = a[i] * px - b[i] * py + tx[i]
            y = b[i] * px + a[i] * py + ty[i]
            xmin, xmax, ymin = min(xmin, x), max(xmax, x), min(ymin, y)
            sx += x
            sy += y
        if not (np.isfinite(sx) and np.isfinite(sy)):
            xmin = xmax = ymin = np.nan
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = xmin, xmax, ymin, sx / n, sy / n


def predesign_problem(target: str = DEFAULT_TARGET, n_samples: int = 360, backend: str = "auto",
                      n_harmonics: int = fourier.DEFAULT_HARMONICS, fit: str = "extent",
                      transmission_min: float = 0.0) -> ProblemSpec:
    """Predesign: objectives fd (Fourier-descriptor distance) and f1 (MSE after placement).

    Registered as ``predesign`` by ``core.optimize.subtasks`` (the module the problem registry loads).
    """
    tgt = load_target(target)
    d_target = fourier.descriptors(tgt.sample(n_samples), n_harmonics, N_RESAMPLE)

    def evaluate(design: Design) -> Metrics:
        out = shape_metrics(design, target, n_samples, backend)  # type: ignore[arg-type]
        sol = design.solve(n_samples, joints=False, derivatives=False, backend=backend)
        point = np.where(sol.violation[:, None, None] == 0.0, sol.point, np.nan)
        d = fourier.descriptors(point, n_harmonics, N_RESAMPLE)
        out["fd"] = quantize(fourier.descriptor_distance(d, d_target, n_grid=N_GRID))
        return out

    def repair(design: Design) -> F64:
        return place(design, target, n_samples, backend, fit)[0]  # type: ignore[arg-type]

    return ProblemSpec("predesign", evaluate, ("fd", "f1"), (ASSEMBLY, *transmission_limits(transmission_min)),
                       labels={**LABELS, "fd": "Fourier-descriptor distance (-)"}, repair=repair,
                       misfit=placement_misfit, scale=target_scale(target, n_samples))
