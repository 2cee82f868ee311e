"""Drawings for fabrication: a design at one crank angle as DXF (one layer per link, pivot holes, ground marks,
link lengths and the frame's pivot spacings dimensioned in mm, and a parts sheet: each link as a plate outline with
its holes, laid flat side by side, ready to cut) and as SVG (the linkage and the foot path).

Coordinates are the design frame in mm, y up (SVG flips y for the screen). The crank angle is measured from the
crank phase, counter-clockwise; the pose is drawn at exactly that angle where the crank phase is a design
parameter (every topology but the RTCLM, whose phase is derived: there, at the nearest tenth of a degree).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from core.kinematics.design import Design
from core.kinematics.model import Crank, Ground, Mechanism

F64 = NDArray[np.float64]
HOLE = 5.0  # mm: pivot hole diameter, by default (clm export --hole)
PLATE = 3.0  # a link plate's width in hole diameters, by default (clm export --width)
PART_GAP = 5.0  # mm between two parts on the sheet
N_SAMPLES = 360
N_FINE = 3600  # a derived crank phase: the pose at the nearest of these samples
LABEL_HEIGHT = 3.5  # mm: point names


@dataclass(frozen=True)
class Drawing:
    """One design at one crank angle (rad, the one drawn): joints ``(n_joints, 2)`` mm, the moving links (point
    names), the ground pivots a link turns about, and the tracked point's path ``(n_samples, 2)`` mm."""

    mechanism: str
    names: tuple[str, ...]
    joints: F64
    links: tuple[tuple[str, ...], ...]
    ground: tuple[str, ...]
    path: F64
    angle: float

    def point(self, name: str) -> F64:
        return self.joints[self.names.index(name)]

    def edges(self) -> list[tuple[str, str, float]]:
        """Every pair of points of every moving link, with its length (mm)."""
        out = []
        for body in self.links:
            for a, b in combinations(body, 2):
                out.append((a, b, float(np.linalg.norm(self.point(a) - self.point(b)))))
        return out

    def pivots(self) -> set[str]:
        """The points that are joints: shared by two links, or a link's and the frame's. A point of one link
        alone (the foot, a coupler point) is no hole: it is marked with a cross."""
        count = {n: sum(n in b for b in self.links) + (n in self.ground) for n in self.names}
        return {n for n, c in count.items() if c >= 2}

    def frame(self) -> list[tuple[str, str, float]]:
        """Every pair of ground pivots, with its spacing (mm): the holes the frame is drilled with."""
        return [(a, b, float(np.linalg.norm(self.point(a) - self.point(b)))) for a, b in combinations(self.ground, 2)]


MAX_PLATE = 1e4  # mm: a hole or plate width past 10 m is a unit mistake


@dataclass(frozen=True)
class Plates:
    """How the links are made: pivot holes of diameter ``hole`` (mm) in plates ``width`` mm wide (3 holes by
    default), rounded around each point they carry."""

    hole: float = HOLE
    width: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hole) and 0 < self.hole <= MAX_PLATE):  # 1e300 mm wrote a DXF (rehearsal 8)
            raise ValueError(f"the hole diameter must be a positive number of mm up to {MAX_PLATE:g}, got {self.hole}")
        w = self.width
        if w is not None and math.isfinite(w) and w > MAX_PLATE:
            raise ValueError(f"the plate width must be at most {MAX_PLATE:g} mm (a plate past 10 m is a unit mistake), "
                             f"got {w}")
        if w is not None and not (math.isfinite(w) and w > self.hole):
            raise ValueError(f"the plate width must be more than the hole diameter ({self.hole:g} mm) for a plate to "
                             f"hold its holes, got {w}")

    @property
    def plate(self) -> float:
        """The plate width (mm)."""
        return PLATE * self.hole if self.width is None else float(self.width)

    @property
    def web(self) -> float:
        """The material beside a hole (mm): half the plate width less the hole's radius."""
        return (self.plate - self.hole) / 2


def hull(points: F64) -> F64:
    """``(h, 2)`` the convex hull of ``(k, 2)`` points, counter-clockwise, without collinear or repeated points
    (one point: itself)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) <= 2:
        return np.array(pts, dtype=np.float64).reshape(-1, 2)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1], dtype=np.float64)


def outline(points: F64, radius: float) -> list[tuple[float, float, float]]:
    """A plate around ``(k, 2)`` points: the convex hull of circles of ``radius`` about them, as the vertices of
    a closed polyline with DXF bulges ``(x, y, bulge)`` (an arc from a vertex to the next where bulge != 0, a
    line where it is 0). One point: a circle (two half arcs)."""
    h = hull(points)
    if len(h) == 1:
        (x, y), = h
        return [(x - radius, y, 1.0), (x + radius, y, 1.0)]
    out = []
    n = len(h)
    for i in range(n):
        p, prev, nxt = h[i], h[i - 1], h[(i + 1) % n]
        e_in, e_out = p - prev, nxt - p
        n_in = np.array([e_in[1], -e_in[0]]) / np.hypot(*e_in)  # the outward normals (right of a CCW edge)
        n_out = np.array([e_out[1], -e_out[0]]) / np.hypot(*e_out)
        turn = math.atan2(n_in[0] * n_out[1] - n_in[1] * n_out[0], float(n_in @ n_out))
        if turn <= 0:  # two points: a half turn, whichever sign the cross product's zero has
            turn += 2 * math.pi
        a, b = p + radius * n_in, p + radius * n_out
        out.append((float(a[0]), float(a[1]), math.tan(turn / 4)))
        out.append((float(b[0]), float(b[1]), 0.0))
    return out


def part_frame(d: Drawing, body: tuple[str, ...]) -> tuple[F64, F64]:
    """A link laid flat: its points ``(k, 2)`` turned so that its two farthest pivots (points, if it has fewer
    than two pivots) lie on a horizontal line, and the rotation ``(2, 2)`` applied."""
    pts = np.array([d.point(n) for n in body])
    pivots = [i for i, n in enumerate(body) if n in d.pivots()]
    ref = pivots if len(pivots) >= 2 else list(range(len(body)))
    a, b = max(combinations(ref, 2), key=lambda ij: float(np.linalg.norm(pts[ij[0]] - pts[ij[1]])),
               default=(0, 0))
    v = pts[b] - pts[a]
    t = math.atan2(v[1], v[0]) if np.hypot(*v) > 0 else 0.0
    rot = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    return pts @ rot.T, rot


@dataclass(frozen=True)
class CutWarning:
    """One thing that makes a part uncuttable or weak, in words; ``overlap``: two holes overlap, so only smaller pins
    help (each front end names its own control for the hole: ``--hole``, the studio's Pin hole field)."""

    text: str
    overlap: bool


def cutting_warnings(d: Drawing, plates: Plates) -> list[CutWarning]:
    """What would make a part uncuttable or weak: two holes of one link that overlap, or leave less material
    between them than beside each hole (the plate's web)."""
    out = []
    pivots = d.pivots()
    for body in d.links:
        for a, b in combinations([n for n in body if n in pivots], 2):
            dist = float(np.linalg.norm(d.point(a) - d.point(b)))
            left = dist - plates.hole
            where = (f"holes {a} and {b} of link {'-'.join(body)} (centres {dist:.2f} mm apart, "
                     f"{plates.hole:g} mm holes)")
            if left < 0:
                out.append(CutWarning(f"{where} overlap: the part cannot be cut as drawn; use smaller pins", True))
            elif left < plates.web:
                out.append(CutWarning(f"{where} leave {left:.2f} mm of material between them, less than the "
                                      f"{plates.web:.2f} mm beside each hole", False))
    return out


def drawing(design: Design, angle: float = 0.0, member: int = 0) -> Drawing:
    """The drawing of member ``member`` at crank angle ``angle`` (rad, from the design's crank phase g);
    ValueError if it does not assemble there."""
    m = design.mechanism
    one = Design(m, design.params[member : member + 1], design.output)
    phases = {s.phase for s in m.steps if isinstance(s, Crank)}
    (phase,) = phases if len(phases) == 1 else (None,)
    if isinstance(phase, str) and phase in m.param_names:  # turn the crank phase itself: sample 0 is the pose
        params = one.params.copy()
        params[0, m.param_names.index(phase)] += angle
        sol = Design(m, params, one.output).solve(N_SAMPLES, joints=True, derivatives=False)
        i, drawn = 0, float(angle)
    else:  # a derived phase (the RTCLM's switching state): the nearest of N_FINE samples
        sol = one.solve(N_FINE, joints=True, derivatives=False)
        i = int(round((angle % (2 * math.pi)) / (2 * math.pi) * N_FINE)) % N_FINE
        drawn = float(angle) + ((2 * math.pi * i / N_FINE - angle % (2 * math.pi) + math.pi) % (2 * math.pi) - math.pi)
    assert sol.joints is not None
    joints = np.asarray(sol.joints[0, i], dtype=np.float64)
    if not np.isfinite(joints).all() or sol.violation[0] > 0:
        # The shortfall is measured at the samples solved (clm simulate and evaluate take 360; the RTCLM is drawn
        # from N_FINE), so the figures differ a little: say how many.
        raise ValueError(f"the design does not assemble over the whole cycle (violation {sol.violation[0]:.3g} mm "
                         f"over {sol.theta.shape[0]} crank samples): nothing to draw")
    grounds = {s.name for s in m.steps if isinstance(s, Ground)}
    links = tuple(b for b in m.bodies() if not set(b) <= grounds)
    links = _parts_of_locked_cranks(m, links)
    # m.pivots(): the RTCLM's auxiliary mode locks A..D (its primary mode draws them).
    return Drawing(m.name, tuple(m.joint_names), joints, links, m.pivots(), np.asarray(sol.point[0]), drawn)


def _parts_of_locked_cranks(m: Mechanism, links: tuple[tuple[str, ...], ...]) -> tuple[tuple[str, ...], ...]:
    """``links`` with each crank the mechanism holds still (``Mechanism.held_cranks``) taken off the body that holds
    it: the RTCLM's primary mode has one body D-C-H-F, the leg built a rocker D-C-H with a bore at H and the crank
    H-F (rehearsal 5: the parts sheet welded them into one plate, with no hole for the motor)."""
    out = list(links)
    for axis, end in m.held_cranks:
        parts: list[tuple[str, ...]] = []
        for body in out:
            if axis in body and end in body and len(body) > 2:
                parts += [tuple(p for p in body if p != end), (axis, end)]
            else:
                parts.append(body)
        out = parts
    return tuple(out)


def _dimension(msp: object, pa: F64, pb: F64, layer: str) -> None:
    """An aligned dimension in mm, two decimals. ezdxf's default style scales the text by 100 (``DIMLFAC``):
    a 150 mm link read "15000"."""
    dim = msp.add_aligned_dim(p1=tuple(pa), p2=tuple(pb), distance=6.0,  # type: ignore[attr-defined]
                              dxfattribs={"layer": layer}, override={"dimdec": 2, "dimtxt": 3.0, "dimlfac": 1.0})
    dim.render()


def dxf(d: Drawing, plates: Plates = Plates()) -> str:
    """The drawing as DXF R2010 text: layer ``LINK_<points>`` per moving link (bars, pivot holes, aligned
    dimensions), ``GROUND`` (pivot holes and cross marks), ``FRAME`` (dashed lines and dimensions between the
    ground pivots), ``LABELS`` (every point's name; a point of one link alone, as the foot, crossed: no hole),
    ``PATH`` (the foot path), ``TITLE`` (the mechanism and the crank angle drawn); and under it the parts sheet:
    layer ``PART_<points>`` per link (its plate's closed outline and its pivot holes, laid flat, side by side
    ``PART_GAP`` mm apart: what a laser cuts) and ``PART_LABELS`` (each part's name, a cross at a point that is
    no hole)."""
    import ezdxf

    doc = ezdxf.new("R2010", setup=True)
    doc.units = ezdxf.units.MM
    msp = doc.modelspace()
    doc.layers.add("GROUND", color=8)
    doc.layers.add("FRAME", color=8)
    doc.layers.add("PATH", color=5)
    doc.layers.add("LABELS", color=7)
    doc.layers.add("TITLE", color=7)
    pivots, r = d.pivots(), plates.hole / 2
    for k, body in enumerate(d.links):
        layer = "LINK_" + "-".join(body)
        doc.layers.add(layer, color=1 + k % 6)
        for a, b in combinations(body, 2):
            pa, pb = d.point(a), d.point(b)
            msp.add_line(tuple(pa), tuple(pb), dxfattribs={"layer": layer})
            _dimension(msp, pa, pb, layer)
        for name in body:
            if name in pivots:
                msp.add_circle(tuple(d.point(name)), r, dxfattribs={"layer": layer})
    for a, b, _ in d.frame():  # the frame: the spacing of its pivot holes
        _dimension(msp, d.point(a), d.point(b), "FRAME")
        msp.add_line(tuple(d.point(a)), tuple(d.point(b)), dxfattribs={"layer": "FRAME", "linetype": "DASHED"})
    for name in d.ground:
        x, y = d.point(name)
        msp.add_circle((x, y), r * 1.6, dxfattribs={"layer": "GROUND"})
        for dx, dy in ((1, 0), (0, 1)):
            s = 2.5 * r
            msp.add_line((x - s * dx, y - s * dy), (x + s * dx, y + s * dy), dxfattribs={"layer": "GROUND"})
    drawn = set(d.ground).union(*d.links)
    for name in (n for n in d.names if n in drawn):  # every point named on the drawing; a non-pivot crossed
        x, y = d.point(name)
        if name not in pivots:
            s = r
            for dx, dy in ((1, 1), (1, -1)):
                msp.add_line((x - s * dx, y - s * dy), (x + s * dx, y + s * dy), dxfattribs={"layer": "LABELS"})
        msp.add_text(name, height=LABEL_HEIGHT, dxfattribs={"layer": "LABELS"}).set_placement(
            (x + 1.4 * r, y + 1.4 * r))
    finite = d.path[np.isfinite(d.path).all(axis=1)]
    if len(finite) > 1:
        msp.add_lwpolyline([tuple(p) for p in finite], close=True, dxfattribs={"layer": "PATH"})
    # What the drawing shows, under it: the SVG's title said the angle, the DXF did not (the studio draws the
    # animation's angle, clm export 0 unless --angle: two drawings of one design differed without a word).
    pts = np.vstack([d.joints[np.isfinite(d.joints).all(axis=1)], finite])
    msp.add_text(f"{d.mechanism} at crank angle {math.degrees(d.angle):.1f} deg (from the crank phase), mm",
                 height=LABEL_HEIGHT, dxfattribs={"layer": "TITLE"}).set_placement(
        (float(pts[:, 0].min()), float(pts[:, 1].min()) - 4 * LABEL_HEIGHT))
    _parts(doc, msp, d, plates, float(pts[:, 1].min()) - 7 * LABEL_HEIGHT, float(pts[:, 0].min()))
    out = io.StringIO()
    doc.write(out)
    return out.getvalue()


def _parts(doc: object, msp: object, d: Drawing, plates: Plates, top: float, left: float) -> None:
    """The parts sheet: each link's plate laid flat (:func:`part_frame`), its top at ``top``, from ``left`` on."""
    doc.layers.add("PART_LABELS", color=7)  # type: ignore[attr-defined]
    pivots, r, half = d.pivots(), plates.hole / 2, plates.plate / 2
    x = left
    for k, body in enumerate(d.links):
        layer = "PART_" + "-".join(body)
        doc.layers.add(layer, color=1 + k % 6)  # type: ignore[attr-defined]
        pts, _ = part_frame(d, body)
        shift = np.array([x - (pts[:, 0].min() - half), top - (pts[:, 1].max() + half)])
        pts = pts + shift
        msp.add_lwpolyline(outline(pts, half), format="xyb", close=True,  # type: ignore[attr-defined]
                           dxfattribs={"layer": layer})
        for name, p in zip(body, pts, strict=True):
            if name in pivots:
                msp.add_circle(tuple(p), r, dxfattribs={"layer": layer})  # type: ignore[attr-defined]
            else:  # the foot, a coupler point: marked, not drilled
                for dx, dy in ((1, 1), (1, -1)):
                    msp.add_line((p[0] - r * dx, p[1] - r * dy), (p[0] + r * dx, p[1] + r * dy),  # type: ignore[attr-defined]
                                 dxfattribs={"layer": "PART_LABELS"})
        msp.add_text("-".join(body), height=LABEL_HEIGHT, dxfattribs={"layer": "PART_LABELS"}).set_placement(  # type: ignore[attr-defined]
            (x, float(pts[:, 1].min()) - half - 1.5 * LABEL_HEIGHT))
        x += float(np.ptp(pts[:, 0])) + 2 * half + PART_GAP


def svg(d: Drawing, margin: float = 20.0, plates: Plates = Plates()) -> str:
    """The linkage at its angle and the foot path as an SVG document (mm, y up); holes of ``plates.hole``."""
    r = plates.hole / 2
    pts = np.vstack([d.joints, d.path[np.isfinite(d.path).all(axis=1)]])
    lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
    w, h = hi - lo

    def xy(p: F64) -> tuple[float, float]:
        return float(p[0] - lo[0]), float(hi[1] - p[1])

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.2f}mm" height="{h:.2f}mm" '
           f'viewBox="0 0 {w:.3f} {h:.3f}">',
           f"<title>{d.mechanism} at crank angle {math.degrees(d.angle):.1f} deg</title>"]
    path = " ".join(f"{x:.3f},{y:.3f}" for x, y in (xy(p) for p in d.path if np.isfinite(p).all()))
    out.append(f'<polygon points="{path}" fill="none" stroke="#1f77b4" stroke-width="0.6"/>')
    for a, b, _ in d.frame():
        (x1, y1), (x2, y2) = xy(d.point(a)), xy(d.point(b))
        out.append(f'<line x1="{x1:.3f}" y1="{y1:.3f}" x2="{x2:.3f}" y2="{y2:.3f}" stroke="#888" '
                   f'stroke-width="0.5" stroke-dasharray="3 2"/>')
    for a, b, _ in d.edges():
        (x1, y1), (x2, y2) = xy(d.point(a)), xy(d.point(b))
        out.append(f'<line x1="{x1:.3f}" y1="{y1:.3f}" x2="{x2:.3f}" y2="{y2:.3f}" stroke="#333" '
                   f'stroke-width="1.2" stroke-linecap="round"/>')
    drawn, pivots = set(d.ground).union(*d.links), d.pivots()
    for name, p in zip(d.names, d.joints, strict=True):
        if name not in drawn:
            continue
        x, y = xy(p)
        out.append(f'<text x="{x + 1.4 * r:.3f}" y="{y - 1.4 * r:.3f}" font-size="{LABEL_HEIGHT}" '
                   f'font-family="sans-serif">{name}</text>')
        if name not in pivots:  # the foot or a coupler point: a cross, no hole
            s = r
            out.append(f'<path d="M{x - s:.3f},{y - s:.3f} L{x + s:.3f},{y + s:.3f} M{x - s:.3f},{y + s:.3f} '
                       f'L{x + s:.3f},{y - s:.3f}" stroke="#333" stroke-width="0.5"><title>{name}</title></path>')
            continue
        fill = "#888" if name in d.ground else "#fff"
        out.append(f'<circle cx="{x:.3f}" cy="{y:.3f}" r="{r}" fill="{fill}" stroke="#333" '
                   f'stroke-width="0.5"><title>{name}</title></circle>')
    out.append("</svg>")
    return "\n".join(out) + "\n"
