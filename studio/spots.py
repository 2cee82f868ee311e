"""Where a label goes: boxes ``(x0, y0, x1, y1)`` tried in order against boxes already taken (other labels,
markers). One set of rules for the studio's three label placers: the bench chart's (``studio.bench_svg``), the
Pareto chart's (``studio.figures``) and the scene's (``studio.frames``); each keeps its own tries and order."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

Box = tuple[float, float, float, float]
F64 = NDArray[np.float64]


def overlaps(a: Box, b: Box) -> bool:
    """True if the boxes share some area (touching edges do not)."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def cover(a: Box, b: Box) -> float:
    """The area the boxes share."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def spill(box: Box, bounds: Box) -> float:
    """How far ``box`` reaches past ``bounds``, summed over its four sides (0 inside)."""
    return (max(0.0, bounds[0] - box[0]) + max(0.0, box[2] - bounds[2]) + max(0.0, bounds[1] - box[1])
            + max(0.0, box[3] - bounds[3]))


def first_clear(tries: Sequence[Box], taken: Sequence[Box]) -> int | None:
    """The index of the first box of ``tries`` that overlaps none of ``taken``; None if each overlaps one."""
    return next((k for k, box in enumerate(tries) if not any(overlaps(box, t) for t in taken)), None)


def covers(boxes: Sequence[Box], taken: Sequence[Box]) -> NDArray[np.float64]:
    """``(len(boxes),)``: the area each box shares with all of ``taken`` (:func:`cover` summed, on arrays: a chart
    tries a dozen spots against hundreds of dots)."""
    a = np.asarray(boxes, dtype=np.float64).reshape(-1, 1, 4)
    b = np.asarray(taken, dtype=np.float64).reshape(1, -1, 4)
    w = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0.0, None)
    h = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0.0, None)
    return (w * h).sum(axis=1)


def clusters(points: Sequence[tuple[float, float]], tol: float) -> list[list[int]]:
    """Indices of ``points`` grouped greedily: each joins the first group whose first point lies within ``tol``
    (0: the same point), else starts one; groups and members in the points' order. Feature points sharing a label."""
    groups: list[list[int]] = []
    for k, (x, y) in enumerate(points):
        for g in groups:
            qx, qy = points[g[0]]
            if math.hypot(x - qx, y - qy) <= tol:
                g.append(k)
                break
        else:
            groups.append([k])
    return groups


def _clip(a: F64, d: F64, box: Box) -> tuple[F64, F64]:
    """The parameter range [lo, hi] of segments ``a + t d`` (t in [0, 1]; ``(..., 2)`` arrays) inside the open box
    (Liang-Barsky); empty where lo >= hi."""
    lo, hi = np.zeros(a.shape[:-1]), np.ones(a.shape[:-1])
    for k, (b0, b1) in enumerate(((box[0], box[2]), (box[1], box[3]))):
        ak, dk = a[..., k], d[..., k]
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (b0 - ak) / dk, (b1 - ak) / dk
        flat = dk == 0.0  # parallel to this slab: in it throughout, or never
        inside = (ak > b0) & (ak < b1)
        lo = np.maximum(lo, np.where(flat, np.where(inside, 0.0, np.inf), np.minimum(t0, t1)))
        hi = np.minimum(hi, np.where(flat, np.where(inside, 1.0, -np.inf), np.maximum(t0, t1)))
    return lo, hi


def crosses_box(a: F64, d: F64, box: Box) -> np.ndarray:
    """Whether segments ``a + t d`` (t in [0, 1]; ``(..., 2)`` arrays) pass through the open box."""
    lo, hi = _clip(a, d, box)
    return lo < hi


def inside_length(a: F64, d: F64, box: Box) -> float:
    """How much of the segments ``a + t d`` (t in [0, 1]) runs inside the open box (in their units)."""
    lo, hi = _clip(a, d, box)
    return float((np.clip(hi - lo, 0.0, None) * np.hypot(d[..., 0], d[..., 1])).sum())


class Segments(NamedTuple):
    """Segments ready for :func:`length_under`: their starts and steps ``(k, 2)`` and bounding boxes (lo, hi)."""

    a: F64
    d: F64
    lo: F64
    hi: F64


def as_segments(*sets: F64, offset: tuple[float, float] = (0.0, 0.0)) -> Segments:
    """Sets of segments ``(..., 2, 2)`` (moved by ``offset``) as one :class:`Segments`."""
    seg = np.concatenate([np.asarray(s, dtype=np.float64).reshape(-1, 2, 2) for s in sets] or
                         [np.zeros((0, 2, 2))]) + np.asarray(offset, dtype=np.float64)
    return Segments(seg[:, 0], seg[:, 1] - seg[:, 0], seg.min(axis=1), seg.max(axis=1))


def length_under(segs: Segments, box: Box) -> float:
    """How much of ``segs`` runs inside the open box: clipped only where a segment's box meets it (the scene's
    labels clipped all ~700 segments at every spot, half of a parameter edit's frames in session 38)."""
    near = (segs.lo[:, 0] < box[2]) & (segs.hi[:, 0] > box[0]) & (segs.lo[:, 1] < box[3]) & (segs.hi[:, 1] > box[1])
    return inside_length(segs.a[near], segs.d[near], box) if near.any() else 0.0
