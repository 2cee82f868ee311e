"""Pure drawing geometry: link edges, segments, the two-view layout and the camera fit.

Everything here is numpy in, numpy out (mm in, scene units out where noted), so it is
tested without a server. The scene is in metres (``SCENE_SCALE`` m per mm) because viser's
camera and grid defaults are sized for metre-scale scenes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Crank, Ground, Mechanism

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

SCENE_SCALE = 1e-3
EDGE_GROUND, EDGE_CRANK, EDGE_LINK = 0, 1, 2


@dataclass(frozen=True)
class LinkEdges:
    """Edges to draw for every rigid body of a mechanism.

    Attributes:
        pairs: ``(n_edges, 2)`` joint indices (along ``Mechanism.joint_names``).
        kinds: ``(n_edges,)`` ``EDGE_GROUND``, ``EDGE_CRANK`` or ``EDGE_LINK``.
    """

    pairs: NDArray[np.int64]
    kinds: NDArray[np.int64]


def link_edges(mechanism: Mechanism) -> LinkEdges:
    """Edges to draw: every pair of points of every moving body (a binary link's bar, a ternary
    link's triangle), and for the ground only each ground point's tie to the ground point it is
    placed from (pivots placed from the world origin stand alone, as in a kinematic diagram) and the
    links it holds still (``Mechanism.locked``: the RTCLM's auxiliary mode drew the four-bar alone, and a
    switch of mode looked like another mechanism; rehearsal 7)."""
    index = {name: j for j, name in enumerate(mechanism.joint_names)}
    grounds = {s.name for s in mechanism.steps if isinstance(s, Ground)}
    # The crank is the body turning about a ground pivot: it holds a crank point and its pivot.
    cranks = [(s.name, s.pivot) for s in mechanism.steps if isinstance(s, Crank)]
    pairs: list[tuple[int, int]] = [
        (index[s.origin], index[s.name]) for s in mechanism.steps if isinstance(s, Ground) and s.origin is not None
    ]
    for group in mechanism.locked:
        for a in range(len(group)):
            for b in range(a + 1, len(group)):
                pairs.append((index[group[a]], index[group[b]]))
    kinds: list[int] = [EDGE_GROUND] * len(pairs)
    for body in mechanism.bodies():
        members = set(body)
        if members <= grounds:
            continue
        kind = EDGE_CRANK if any(c in members and pivot in members for c, pivot in cranks) else EDGE_LINK
        for a in range(len(body)):
            for b in range(a + 1, len(body)):
                pairs.append((index[body[a]], index[body[b]]))
                kinds.append(kind)
    return LinkEdges(np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(kinds, dtype=np.int64))


def link_segments(joints: F64, pairs: NDArray[np.int64]) -> F64:
    """Joints ``(..., n_joints, 2)`` -> segments ``(..., n_edges, 2, 2)`` (mm)."""
    return np.stack([joints[..., pairs[:, 0], :], joints[..., pairs[:, 1], :]], axis=-2)


def closed_polyline(points: F64) -> F64:
    """Closed curve ``(n, 2)`` -> segments ``(m, 2, 2)`` joining each point to the next.

    Segments touching a non-finite point are dropped, so a partly unassemblable path draws
    its valid arcs only.
    """
    seg = np.stack([points, np.roll(points, -1, axis=0)], axis=1)
    return seg[np.isfinite(seg).all(axis=(1, 2))]


SEED = 32  # a kept sample at least every SEED: fewer levels of splits (~1.6x faster), 0-15 more segments a curve
DRAWN = 5e-4  # a drawn curve keeps within this share of its extent of every sample (a fraction of a pixel)


def simplified(*curves: tuple[F64, NDArray[np.uint8] | None]) -> list[tuple[F64, NDArray[np.uint8] | None]]:
    """Segments ``(m, 2, 2)`` of polylines -> fewer segments drawing the same curves, for each ``(segments,
    colors)`` given (per-vertex ``colors`` ``(m, 2, 3)``, one colour a segment, or None). Each chain of joined
    segments of one colour keeps the samples Ramer-Douglas-Peucker needs to pass within ``DRAWN`` x its
    curve's extent of every sample; its ends and every break (a gap, a colour change) stay where they were.
    A segment with a non-finite end is left out (a gap), as viser needs finite arrays.

    A software-rendered page draws each segment of a line for ~20 us a frame (session 39: the default scene's
    2242 segments were ~40 of its ~90 ms a frame, 10 frames a second, the page's main thread always waiting on
    them); a 360-sample path needs 40-70 to look the same. The curves are done together (numpy's calls, not
    the points, are what a level of splits costs).
    """
    pts, a, b, tol, owner_of = [], [], [], [], []
    base = 0
    finite = []
    for seg, colors in curves:
        seg = np.asarray(seg, dtype=np.float64)
        ok = np.isfinite(seg).all(axis=(1, 2))
        finite.append((seg[ok], None if colors is None else colors[ok]))
    curves = tuple(finite)
    for k, (seg, colors) in enumerate(curves):
        m = len(seg)
        brk = np.any(seg[1:, 0] != seg[:-1, 1], axis=1)
        if colors is not None:
            brk |= np.any(colors[1:, 0] != colors[:-1, 0], axis=1)
        starts = np.concatenate([[0], np.flatnonzero(brk) + 1, [m]]) if m else np.zeros(1, dtype=np.int64)
        # Chain c's points are its segments' starts and its last end: its segments s..e-1 are points s+c..e+c.
        first, last = starts[:-1], starts[1:]
        c = np.arange(len(first))
        p = np.empty((m + len(first), 2))
        p[np.arange(m) + np.repeat(c, last - first)] = seg[:, 0]
        p[last + c] = seg[last - 1, 1]
        ext = float(np.ptp(seg.reshape(-1, 2), axis=0).max()) if m else 0.0
        pts.append(p)
        a.append(base + first + c)
        b.append(base + last + c)
        tol.append(np.full(len(first), DRAWN * ext))
        owner_of.append(np.full(len(p), k))
        base += len(p)
    if not base:
        return list(curves)
    flat = np.concatenate(pts)
    ends = np.zeros(base, dtype=bool)
    ends[np.concatenate(b)] = True
    kept = np.flatnonzero(_kept(flat, np.concatenate(a), np.concatenate(b), np.concatenate(tol)))
    start = kept[:-1][~ends[kept[:-1]]]  # each kept point but a chain's last starts a segment to the next kept one
    end = kept[1:][~ends[kept[:-1]]]
    curve = np.concatenate(owner_of)[start]
    out: list[tuple[F64, NDArray[np.uint8] | None]] = []
    offset = 0
    for k, (_, colors) in enumerate(curves):
        s, e = start[curve == k], end[curve == k]
        drawn = np.stack([flat[s], flat[e]], axis=1)
        if colors is not None:
            # the colour of the chain each drawn segment starts in: the original segment at the same point
            c = np.searchsorted(b[k], s, side="left")  # the chain of point s (points s..b[k][c] belong to chain c)
            colors = colors[s - offset - c]
        out.append((drawn, colors))
        offset += len(pts[k])
    return out


def _kept(pts: F64, a: NDArray[np.int64], b: NDArray[np.int64], tol: F64) -> NDArray[np.bool_]:
    """``(n,)`` the points Ramer-Douglas-Peucker keeps at ``tol[i]`` of the open polylines ``pts[a[i]..b[i]]``
    (their ends, every SEED-th point, and each point farther than ``tol`` from the kept segment over it: the
    segment, not its line, so a foot path's hairpin past a chord's end stays; a piece whose ends are one point is
    measured from that point). All polylines a level of splits at a time, in numpy."""
    keep = np.zeros(len(pts), dtype=bool)
    keep[a], keep[b] = True, True
    # Seeded: a point every SEED samples is kept as well (a few more segments; about half the levels of splits).
    n = (b - a + SEED - 1) // SEED
    owner = np.repeat(np.arange(len(a)), n)
    cuts = a[owner] + SEED * (np.arange(len(owner)) - (np.cumsum(n) - n)[owner])
    keep[cuts] = True
    a, b, tol = cuts, np.minimum(cuts + SEED, b[owner]), tol[owner]
    while len(a):
        inner = b - a - 1
        a, b, tol, inner = a[inner > 0], b[inner > 0], tol[inner > 0], inner[inner > 0]
        if not len(a):
            break
        at = np.cumsum(inner) - inner  # where each interval's points start in the flat arrays
        owner = np.repeat(np.arange(len(a)), inner)
        idx = a[owner] + 1 + np.arange(len(owner)) - at[owner]
        d = (pts[b] - pts[a])[owner]
        r = pts[idx] - pts[a[owner]]
        t = np.clip((r * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), np.finfo(float).tiny), 0.0, 1.0)
        dist = np.hypot(r[:, 0] - t * d[:, 0], r[:, 1] - t * d[:, 1])
        top = np.maximum.reduceat(dist, at)
        pos = np.minimum.reduceat(np.where(dist == top[owner], np.arange(len(owner)), len(owner)), at)
        split = top > tol
        mid = idx[pos[split]]
        keep[mid] = True
        a, b = np.concatenate([a[split], mid]), np.concatenate([mid, b[split]])
        tol = np.concatenate([tol[split], tol[split]])
    return keep


def to_scene(points: F64, offset: F64 | tuple[float, float] = (0.0, 0.0)) -> F32:
    """Planar points ``(..., 2)`` (mm) plus an offset (mm) -> ``(..., 3)`` scene points (m, z = 0)."""
    p = (np.asarray(points, dtype=np.float64) + np.asarray(offset, dtype=np.float64)) * SCENE_SCALE
    return np.concatenate([p, np.zeros(p.shape[:-1] + (1,))], axis=-1).astype(np.float32)


def bounds(*clouds: F64) -> F64:
    """``(4,)`` ``[x_min, y_min, x_max, y_max]`` over the finite points of several ``(..., 2)`` arrays (mm)."""
    pts = np.concatenate([np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in clouds])
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        return np.array([0.0, 0.0, 1.0, 1.0])
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


@dataclass(frozen=True)
class Layout:
    """Where the two views sit in the scene (mm, before ``SCENE_SCALE``).

    Attributes:
        design: ``(4,)`` bounds of the mechanism view (design frame, drawn at its own coordinates).
        leg: ``(4,)`` bounds of the leg-frame view, in leg-frame coordinates.
        leg_offset: ``(2,)`` shift that places the leg-frame view to the right of the mechanism.
        scene: ``(4,)`` bounds of both views together, in scene coordinates (mm).
    """

    design: F64
    leg: F64
    leg_offset: F64
    scene: F64


def layout(design_points: F64, leg_points: F64, gap: float = 60.0) -> Layout:
    """Place the leg-frame view ``gap`` mm right of the mechanism view, centred on it vertically.

    Args:
        design_points: ``(..., 2)`` everything drawn in the design frame (joints over the cycle,
            path, target) (mm).
        leg_points: ``(..., 2)`` everything drawn in the leg frame (mm).
        gap: horizontal space between the views (mm).
    """
    d, g = bounds(design_points), bounds(leg_points)
    dy = 0.5 * (d[1] + d[3]) - 0.5 * (g[1] + g[3])
    offset = np.array([d[2] + gap - g[0], dy])
    moved = g + np.concatenate([offset, offset])
    scene = np.concatenate([np.minimum(d[:2], moved[:2]), np.maximum(d[2:], moved[2:])])
    return Layout(d, g, offset, scene)


def camera_pose(scene_bounds: F64, fov_y: float, aspect: float, margin: float = 1.15) -> tuple[F64, F64]:
    """Camera on the +z axis looking straight down at the xy plane, fitting the bounds.

    Args:
        scene_bounds: ``(4,)`` ``[x_min, y_min, x_max, y_max]`` (mm).
        fov_y: vertical field of view (rad).
        aspect: canvas width / height.
        margin: extra room around the bounds (ratio).

    Returns:
        ``(position (3,), look_at (3,))`` in scene units (m).
    """
    cx, cy = 0.5 * (scene_bounds[0] + scene_bounds[2]), 0.5 * (scene_bounds[1] + scene_bounds[3])
    half_w = 0.5 * (scene_bounds[2] - scene_bounds[0]) * margin
    half_h = 0.5 * (scene_bounds[3] - scene_bounds[1]) * margin
    t = math.tan(0.5 * fov_y)
    dist = max(half_h / t, half_w / (t * aspect), 1.0)
    look = np.array([cx, cy, 0.0]) * SCENE_SCALE
    return look + np.array([0.0, 0.0, dist * SCENE_SCALE]), look


def hold_last_valid(valid: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """For each sample, the latest valid sample at or before it, cyclically; None if none is valid.

    Drawing sample ``i`` as sample ``hold[i]`` freezes a mechanism at its last assembled pose
    while the crank passes through angles where it does not assemble.

    Args:
        valid: ``(n_samples,)`` True where every joint is placed.
    """
    valid = np.asarray(valid, dtype=bool)
    n = len(valid)
    if not valid.any():
        return None
    k = int(np.argmax(valid))  # start the scan on a valid sample so every sample has one before it
    rolled = np.roll(valid, -k)
    last = np.maximum.accumulate(np.where(rolled, np.arange(n), 0))
    return np.roll((last + k) % n, k).astype(np.int64)


def frame_index(angle: float, n_samples: int) -> int:
    """Sample nearest to an input crank angle (rad), wrapped to ``[0, n_samples)``."""
    return int(round(angle / (2.0 * math.pi) * n_samples)) % n_samples


@dataclass(frozen=True)
class Composition:
    """Where the walking view and the candidates inset sit around the two top views (mm, scene coordinates).

    Attributes:
        walk_offset: ``(2,)`` shift placing the walking view (world frame) below the top views, left-aligned.
        inset: ``(4,)`` the candidates inset's square, right of the leg view.
        bounds: ``(4,)`` everything together (for the camera).
    """

    walk_offset: F64
    inset: F64
    bounds: F64


def compose(lay: Layout, walk_bounds: F64 | None, gap: float = 60.0, walk_gap: float | None = None) -> Composition:
    """Place the walking view (if any) below the top views and the inset, and a square inset right of the leg view
    (as high as the leg view, or as 0.6 of its width, and at least half the top views' height).

    Args:
        lay: the two top views.
        walk_bounds: ``(4,)`` bounds of the walking view in its own frame (mm), or None.
        gap: space between views (mm).
        walk_gap: vertical space above the walking view (mm; default ``1.5 gap``): room for the labels under
            the top views and the walking view's own title lines.
    """
    s = lay.scene
    leg = lay.leg + np.concatenate([lay.leg_offset, lay.leg_offset])
    # At least half the top views' height: the RTCLM's 97 mm bench view beside its large linkage made a ~50 px
    # square whose spheres could not be clicked (rehearsal 5).
    side = max(leg[3] - leg[1], 0.6 * (leg[2] - leg[0]), 0.5 * (s[3] - s[1]), 1.0)
    cy = 0.5 * (leg[1] + leg[3])
    inset = np.array([leg[2] + gap, cy - 0.5 * side, leg[2] + gap + side, cy + 0.5 * side])
    parts = [s, inset]
    offset = np.zeros(2)
    if walk_bounds is not None:
        w = np.asarray(walk_bounds, dtype=np.float64)
        below = 1.5 * gap if walk_gap is None else walk_gap
        offset = np.array([s[0] - w[0], min(s[1], inset[1]) - below - w[3]])
        parts.append(w + np.concatenate([offset, offset]))
    stack = np.stack(parts)
    bounds = np.concatenate([stack[:, :2].min(axis=0), stack[:, 2:].max(axis=0)])
    return Composition(offset, inset, bounds)


def nice_step(span: float, lines: int = 40) -> float:
    """A round grid spacing (1, 2 or 5 x 10^k mm) giving about ``lines`` lines over ``span`` mm."""
    raw = max(float(span), 1e-9) / lines
    base = 10.0 ** math.floor(math.log10(raw))
    return next(m * base for m in (1.0, 2.0, 5.0, 10.0) if m * base >= raw)


def grid_lines(box: F64, lines: int = 40, margin: float = 0.1) -> tuple[F64, float]:
    """A square grid of ``(k, 2, 2)`` segments (mm) covering ``box`` plus ``margin`` of its size on every side,
    on multiples of a round step (mm; returned): the scene's millimetre paper, drawn as a few hundred lines
    (a full-screen shader grid costs ~150 ms a frame under software WebGL)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    pad = margin * max(x1 - x0, y1 - y0, 1e-6)
    x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    step = nice_step(max(x1 - x0, y1 - y0), lines)
    xs = np.arange(math.ceil(x0 / step), math.floor(x1 / step) + 1) * step
    ys = np.arange(math.ceil(y0 / step), math.floor(y1 / step) + 1) * step
    vertical = np.stack([np.stack([xs, np.full_like(xs, y0)], 1), np.stack([xs, np.full_like(xs, y1)], 1)], 1)
    horizontal = np.stack([np.stack([np.full_like(ys, x0), ys], 1), np.stack([np.full_like(ys, x1), ys], 1)], 1)
    return np.concatenate([vertical, horizontal]).reshape(-1, 2, 2), step


def inset_positions(values: F64, box: F64, margin: float = 0.1) -> F64:
    """Points ``(n, 2)`` (two objectives, any units) scaled into a square ``(4,)`` box (mm), min-max per axis.

    Non-finite rows go to the box's lower-left corner; a constant axis sits in the middle.
    """
    v = np.asarray(values, dtype=np.float64).reshape(-1, 2)
    ok = np.isfinite(v).all(axis=1)
    out = np.empty_like(v)
    inner = box + np.array([1.0, 1.0, -1.0, -1.0]) * margin * (box[2] - box[0])
    for k in range(2):
        col = v[ok, k]
        lo, hi = (float(col.min()), float(col.max())) if len(col) else (0.0, 1.0)
        u = np.where(ok, (v[:, k] - lo) / (hi - lo), 0.0) if hi > lo else np.full(len(v), 0.5)
        out[:, k] = inner[k] + np.clip(u, 0.0, 1.0) * (inner[k + 2] - inner[k])
    out[~ok] = box[:2]
    return out
