"""What the scene draws, as arrays: the linkage and its paths per animation frame, and the walking view.

Pure functions of a DesignView (no viser): ``build_frames`` and ``build_walk_scene`` are tested without a browser.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Ground
from studio import palette
from studio.geometry import (
    EDGE_CRANK,
    EDGE_GROUND,
    F64,
    SCENE_SCALE,
    Composition,
    Layout,
    bounds,
    closed_polyline,
    compose,
    grid_lines,
    hold_last_valid,
    layout,
    link_edges,
    link_segments,
    nice_step,
    simplified,
    to_scene,
)
from studio.spots import as_segments, clusters, crosses_box, first_clear, length_under
from studio.state import DesignView
from studio.walking import WalkFrames

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

FOV = math.radians(40.0)  # the camera's vertical field of view
DEFAULT_ASPECT = 1.3
FPS = 40.0
# Lines and markers sit slightly above the grid so they never z-fight with it.
Z_LINES, Z_MARKERS = 0.0005, 0.001

DESIGN_TITLE = "Mechanism (design frame)"
LEG_TITLE = "Bench trajectory (leg frame)"
INSET_TITLE = "Candidates (click to pick)"
INSET_EXPORT_TITLE = "Candidates"  # the scene's HTML recording: nothing can be picked in it
INSET_NOTE = "after a run: its knee candidates\n(K1 ...) and best members"
# The room the layout keeps under the inset for its note or its axes caption (``inset_caption``): three lines of
# this many characters. The caption was one line of up to 60 and ran past the canvas on a 1024-pixel screen.
NOTE_CHARS = 34
NOTE_ROOM = "\n".join(["x" * NOTE_CHARS] * 3)


def inset_caption(x: str, y: str) -> str:
    """The inset's axes caption ``x: <x> · y: <y> (scaled)`` in at most three lines of ``NOTE_CHARS`` (what does
    not fit is cut with an ellipsis; the Pareto chart's axes carry the whole titles)."""
    lines = textwrap.wrap(f"x: {x}", NOTE_CHARS) + textwrap.wrap(f"y: {y} (scaled)", NOTE_CHARS)
    if len(lines) > 3:
        lines = lines[:2] + [textwrap.shorten(" ".join(lines[2:]), NOTE_CHARS, placeholder=" …")]
    return "\n".join(lines)
WALK_TITLE = "Walking (world frame): trunk, feet, obstacle a × b"
# Labels are sized in the scene (mm), so the layout can keep every view's text clear of the others at any
# zoom and window size: their height is the composition's size over TEXT_SCALE (about 12 px once framed).
TEXT_SCALE = 50.0
CHAR_WIDTH = 0.52  # a character's advance as a share of the label height (viser draws the system sans-serif)
FEATURE_TEXT, SMALL_TEXT = 0.8, 0.85  # feature-point / pivot labels, scale-bar and note labels (share of h)
LABEL_GAP = 0.3  # of a label's height: the least room between two labels side by side


LINE = 1.2  # line height as a share of the label height


def text_width(text: str, height: float) -> float:
    """Estimated width (mm) of a label ``height`` mm high (its longest line)."""
    return CHAR_WIDTH * height * max(len(line) for line in text.split("\n"))


def text_height(text: str, height: float) -> float:
    """Estimated height (mm) of a label ``height`` mm high, all its lines."""
    return LINE * height * (text.count("\n") + 1)


@dataclass(frozen=True)
class SceneText:
    """A label the layout placed: its node key, text, anchor point (m, scene or its view's frame), anchor and
    height (m); ``box`` is the area it covers (mm, scene coordinates)."""

    key: str
    text: str
    position: tuple[float, float, float]
    anchor: str
    height: float
    box: tuple[float, float, float, float]


def _text(key: str, text: str, x: float, y: float, anchor: str, h: float,
          offset: F64 | tuple[float, float] = (0.0, 0.0)) -> SceneText:
    """A label at (x, y) mm in a view's frame (``offset`` places that frame in the scene)."""
    w, th = text_width(text, h), text_height(text, h)
    vert, horiz = anchor.split("-")
    x0 = x if horiz == "left" else x - w if horiz == "right" else x - 0.5 * w
    y0 = y if vert == "bottom" else y - th if vert == "top" else y - 0.5 * th
    ox, oy = float(offset[0]), float(offset[1])
    return SceneText(key, text, (x * SCENE_SCALE, y * SCENE_SCALE, 0.0), anchor, h * SCENE_SCALE,
                     (x0 + ox, y0 + oy, x0 + w + ox, y0 + th + oy))


def scale_bar(x0: float, y: float, span: float, h: float, key: str) -> tuple[F64, SceneText]:
    """A millimetre scale bar under a view: a round length (about a fifth of ``span`` mm) from ``x0`` at height
    ``y`` with end ticks, and its label (``50 mm``) right of it. Segments ``(3, 2, 2)`` mm, scene coordinates."""
    length = nice_step(span, 5)
    t = 0.35 * h
    seg = np.array([[[x0, y], [x0 + length, y]], [[x0, y - t], [x0, y + t]],
                    [[x0 + length, y - t], [x0 + length, y + t]]])
    return seg, _text(key, f"{length:g} mm", x0 + length + 0.5 * h, y, "center-left", SMALL_TEXT * h)


# What a feature label's spot costs (feature_texts): covering a label, coming within a narrow letter's width of one,
# leaving the leg view's frame (and the room the layout keeps above the path), and per label height of foot path or
# target, then of frame edge or ground line, under it. Measured over the 113 presets against the rule before
# session 38 (the first spot clear of labels): labels over the path or target 130 -> 79 of 207, the curves' length
# under labels 202 -> 103 label heights, labels partly outside their view 68 -> 37.
COVER_COST, NEAR_COST, OUTSIDE_COST, LINE_COST, RULE_COST = 100.0, 50.0, 3.0, 1.0, 0.3


def feature_texts(features: tuple[tuple[str, tuple[float, float]], ...], h: float, offset: F64,
                  lines: tuple[F64, ...] = (), rules: tuple[F64, ...] = (),
                  frame: tuple[float, float, float, float] | None = None) -> tuple[SceneText, ...]:
    """Feature-point labels in the leg view (``h`` mm high): points closer than a label's height print as one
    (``t1,t4``; :func:`group_text`); each label goes above its point, or below, right or left of it: the first of
    the spots that cost least (``COVER_COST`` ...): another label covered or too near, the view left (``frame``:
    x0, y0, x1, y1 in leg-view mm, the room above the path included), the length of ``lines`` under it (``(k, 2,
    2)`` segments each, leg-view mm: the foot path, the target; a curve rising past a point ran through its label,
    QA session 37), then of ``rules`` (the frame's edges, the ground line)."""
    names = [n for n, _ in features]
    xy = [(float(q[0]), float(q[1])) for _, q in features]
    groups: list[tuple[list[str], tuple[float, float]]] = []
    for g in clusters(xy, h):
        # Labels of one spot are one point's names: t6, t7 and t8 given apart at one place print as one "=" run.
        spot = [[names[g[j]] for j in s] for s in clusters([xy[k] for k in g], 0.0)]
        groups.append(([",".join(v) if any("," in n for n in v) else "=".join(sorted(
            "=".join(v).split("="), key=_first_number)) for v in spot], xy[g[0]]))
    ox, oy = float(offset[0]), float(offset[1])

    crossed, ruled = as_segments(*lines, offset=(ox, oy)), as_segments(*rules, offset=(ox, oy))
    box = None if frame is None else (frame[0] + ox, frame[1] + oy, frame[2] + ox, frame[3] + oy)
    out: list[SceneText] = []
    near: list[tuple[float, float, float, float]] = []

    def cost(t: SceneText) -> float:
        b = t.box
        c = COVER_COST * (first_clear([b], [o.box for o in out]) is None) + NEAR_COST * (first_clear([b], near) is None)
        c += (LINE_COST * length_under(crossed, b) + RULE_COST * length_under(ruled, b)) / h
        if box is not None and not (b[0] >= box[0] and b[1] >= box[1] and b[2] <= box[2] and b[3] <= box[3]):
            c += OUTSIDE_COST
        return c

    for k, (names, (x, y)) in enumerate(groups):
        text = group_text(names)
        spots = [(x, y + 0.4 * h, "bottom-center"), (x, y - 0.4 * h, "top-center"),
                 (x + 0.6 * h, y, "center-left"), (x - 0.6 * h, y, "center-right")]
        tries = [_text(f"feature_{k}", text, sx, sy, a, h, offset) for sx, sy, a in spots]
        got = tries[int(np.argmin([cost(t) for t in tries]))]  # the first of the cheapest
        out.append(got)
        x0, y0, x1, y1 = got.box
        near.append((x0 - LABEL_GAP * h, y0, x1 + LABEL_GAP * h, y1))
    return tuple(out)


LABEL_CLASH = 1000.0  # a joint's label over another label: worse than any number of links under it
PIVOT_SPOTS = ((1.0, -1.0, "top-left"), (1.0, 1.0, "bottom-left"), (-1.0, -1.0, "top-right"),
               (-1.0, 1.0, "bottom-right"))  # (x, y) sides of the pivot, and the anchor that puts the label there


def pivot_label_spots(names: tuple[str, ...], pivots: np.ndarray, links: np.ndarray, h: float,
                      off: float) -> tuple[tuple[tuple[float, float, float], str], ...]:
    """Each ground pivot's label position (scene units) and anchor: the corner of the pivot, ``off`` away, that the
    links cross in the fewest crank samples (the first, lower right, among equals). Always lower right, Jansen's
    "Q" sat on a link at most angles and read as a second "O".

    Args:
        pivots: ``(k, 3)`` pivots; links: ``(n_samples, n_edges, 2, 3)`` link segments (scene units).
        h: the labels' height.
    """
    seg = np.asarray(links, dtype=np.float64)[..., :2]
    a, d = seg[:, :, 0, :], seg[:, :, 1, :] - seg[:, :, 0, :]  # (n_s, n_e, 2): start and direction
    out: list[tuple[tuple[float, float, float], str]] = []
    for name, p in zip(names, np.asarray(pivots, dtype=np.float64), strict=True):
        best: tuple[tuple[float, float, float], str] = ((float(p[0]), float(p[1]), float(p[2])), "top-left")
        least = np.inf
        for sx, sy, anchor in PIVOT_SPOTS:
            spot = (float(p[0] + sx * off), float(p[1] + sy * off), float(p[2]))
            box = label_box(name, spot, anchor, h)
            crossed = int(crosses_box(a, d, box).any(axis=1).sum())  # samples a link crosses it in
            if crossed < least:
                best, least = (spot, anchor), crossed
        out.append(best)
    return tuple(out)


def label_box(text: str, position: tuple[float, float, float], anchor: str, h: float
              ) -> tuple[float, float, float, float]:
    """The box ``(x0, y0, x1, y1)`` a corner-anchored label covers (PIVOT_SPOTS' anchors)."""
    x, y, w, th = position[0], position[1], text_width(text, h), text_height(text, h)
    xs = (x, x + w) if anchor.endswith("left") else (x - w, x)
    ys = (y - th, y) if anchor.startswith("top") else (y, y + th)
    return (xs[0], ys[0], xs[1], ys[1])


def joint_label_spots(names: tuple[str, ...], joints: np.ndarray, links: np.ndarray, h: float, off: float,
                      taken: tuple[tuple[float, float, float, float], ...] = ()
                      ) -> tuple[tuple[tuple[float, float, float], str], ...]:
    """The moving joints' label positions and anchors at one pose: each joint in turn takes the corner, ``off``
    away, that the fewest links cross, clear of the labels placed before it (``taken``: boxes ``(x0, y0, x1,
    y1)``, e.g. the pivots') and of the other joints (B and F of the Stephenson-I overlapped as "BF").

    Args:
        joints: ``(k, 3)`` joints; links: ``(n_edges, 2, 3)`` the link segments at that pose (scene units).
    """
    seg = np.asarray(links, dtype=np.float64)[None, :, :, :2]
    a, d = seg[:, :, 0, :], seg[:, :, 1, :] - seg[:, :, 0, :]
    pts = np.asarray(joints, dtype=np.float64)
    boxes = list(taken)
    out: list[tuple[tuple[float, float, float], str]] = []
    for k, (name, p) in enumerate(zip(names, pts, strict=True)):
        others = np.delete(pts[:, :2], k, axis=0)
        best, least = ((float(p[0]) + off, float(p[1]) - off, float(p[2])), "top-left"), np.inf
        box = (0.0, 0.0, 0.0, 0.0)
        for sx, sy, anchor in PIVOT_SPOTS:
            spot = (float(p[0] + sx * off), float(p[1] + sy * off), float(p[2]))
            xa, ya, xb, yb = here = label_box(name, spot, anchor, h)
            cost = float(crosses_box(a, d, here).sum())
            cost += 3.0 * sum(xa < c and c < xb and ya < e and e < yb for c, e in others)
            cost += LABEL_CLASH * sum(xa < b[2] and b[0] < xb and ya < b[3] and b[1] < yb for b in boxes)
            if cost < least:
                best, least, box = (spot, anchor), cost, here
        boxes.append(box)
        out.append(best)
    return tuple(out)


def _first_number(name: str) -> int:
    head = name.split(",")[0].split("=")[0]
    return int(head[1:]) if head[1:].isdigit() else 0


def group_text(labels: list[str]) -> str:
    """One label for feature labels printed together (their points closer than a label's height): the labels listed
    in the order of their first point (``t1=t4,t6``); a single label of one spot's names (``=`` only) with a run
    compressed as :func:`joined_names` does. Coinciding points stay joined by ``=``,
    points merely near each other by ``,`` (a ``=`` between them claimed they coincide; QA, session 38)."""
    if len(labels) == 1 and "," not in labels[0]:
        return joined_names(labels[0].split("="))
    return ",".join(sorted(labels, key=_first_number))


def joined_names(names: list[str]) -> str:
    """``t2=t5``; a run of four or more consecutive points as ``t1=…=t8`` (eight names ran past the bench view's
    box when every feature point fell on one spot)."""
    nums = [int(n[1:]) for n in names if n[1:].isdigit()]
    if len(names) >= 4 and len(nums) == len(names) and nums == list(range(nums[0], nums[0] + len(nums))):
        return f"{names[0]}=…={names[-1]}"
    return "=".join(names)


def marker_texts(markers: tuple[tuple[str, tuple[float, float]], ...], h: float,
                 r: float) -> tuple[SceneText | None, ...]:
    """Labels of the candidate spheres (tag, centre in mm; radius ``r`` mm), ``h`` mm high, in the markers' order
    (K1 first): above the sphere, else below, right or left of it, wherever it covers no other label or sphere;
    None where no spot is free (the sphere stays, and the Pick panel lists it)."""
    discs = [(x - r, y - r, x + r, y + r) for _, (x, y) in markers]
    out: list[SceneText | None] = []
    placed: list[tuple[float, float, float, float]] = []
    for k, (tag, (x, y)) in enumerate(markers):
        g = r + 0.15 * h
        spots = [(x, y + g, "bottom-center"), (x, y - g, "top-center"), (x + g, y, "center-left"),
                 (x - g, y, "center-right")]
        tries = [_text(f"tag_{k}", tag, sx, sy, a, h) for sx, sy, a in spots]
        others = placed + [d for j, d in enumerate(discs) if j != k]
        free = first_clear([t.box for t in tries], others)
        got = None if free is None else tries[free]
        out.append(got)
        if got is not None:  # kept a narrow letter's width from the next label: "K4K6" read as one (QA, session 37)
            x0, y0, x1, y1 = got.box
            placed.append((x0 - LABEL_GAP * h, y0, x1 + LABEL_GAP * h, y1))
    return tuple(out)


@dataclass(frozen=True)
class SceneFrames:
    """Scene-ready geometry of one design (metres, float32).

    Attributes:
        links: ``(n_samples, n_edges, 2, 3)`` link segments per crank sample.
        link_colors: ``(n_edges, 2, 3)`` uint8 colour per segment end.
        joints: ``(n_samples, n_moving, 3)`` moving joints per sample.
        pivots: ``(n_pivots, 3)`` ground pivots a link touches (the RTCLM auxiliary mode's locked A..D are not drawn).
        pivot_names: names of the ground pivots.
        joint_names: names of the moving joints, in ``joints``' order (labelled while the animation is paused).
        foot: ``(n_samples, 1, 3)`` tracked point, design frame.
        leg_foot: ``(n_samples, 1, 3)`` tracked point, leg frame (leg-view local coordinates).
        path, target: ``(m, 2, 3)`` design-frame path and target segments (``geometry.simplified``: within 0.05 %
            of their extent of every sample).
        leg_path, leg_target: ``(m, 2, 3)`` leg-frame path and target segments (leg-view local; simplified).
        leg_path_colors: ``(m, 2, 3)`` uint8: stance and swing in two colours (one colour without
            feature points).
        leg_axes: ``(k, 2, 3)`` leg-view frame: a border and the ground line y_g = y(t1).
        features: ``(n_features, 3)`` feature-point markers (leg-view local).
        feature_names: their labels (``t1``, ``t6=t7=t8``).
        layout: where the views sit (mm).
        marker: marker size (m), scaled with the drawing.
        composition: where the walking view and the candidates inset sit (mm).
        walk: the walking view's scene geometry, or None without a walking trajectory.
        grid: ``(k, 2, 3)`` the millimetre grid behind every view; grid_step: its spacing (mm).
        texts: the views' titles, the walking metrics line and the scale bars' labels (scene coordinates).
        feature_labels: the feature points' labels (leg-view local), merged or moved so none covers another.
        scale_bars: ``(k, 2, 3)`` a millimetre scale bar under each view (scene coordinates).
        text_height: the titles' height (m); the inset's labels use it too.
        posed: False when the design assembles nowhere on the cycle: its foot (both views) is not drawn.
    """

    links: F32
    link_colors: U8
    joints: F32
    pivots: F32
    pivot_names: tuple[str, ...]
    foot: F32
    leg_foot: F32
    path: F32
    target: F32
    leg_path: F32
    leg_target: F32
    leg_path_colors: U8
    leg_axes: F32
    features: F32
    feature_names: tuple[str, ...]
    layout: Layout
    marker: float
    composition: Composition
    walk: WalkScene | None = None
    grid: F32 = field(default_factory=lambda: np.zeros((0, 2, 3), dtype=np.float32))
    grid_step: float = 0.0
    texts: tuple[SceneText, ...] = ()
    feature_labels: tuple[SceneText, ...] = ()
    scale_bars: F32 = field(default_factory=lambda: np.zeros((0, 2, 3), dtype=np.float32))
    text_height: float = 0.0
    joint_names: tuple[str, ...] = ()
    posed: bool = True

    @property
    def n_samples(self) -> int:
        return int(self.links.shape[0])


@dataclass(frozen=True)
class WalkScene:
    """Scene-ready walking view (walk-local coordinates, metres; the /walk frame carries the offset).

    Attributes:
        body: ``(n_samples, 1 + n_legs, 2, 3)`` trunk and hip-to-foot legs per crank sample.
        body_colors: ``(1 + n_legs, 2, 3)`` uint8.
        feet: ``(n_samples, n_legs, 3)`` feet per crank sample; feet_colors ``(n_legs, 3)``.
        trails: ``(m, 2, 3)`` the feet's paths over one stride (simplified); trail_colors ``(m, 2, 3)``.
        ground: ``(1, 2, 3)`` the ground line; obstacle ``(4, 2, 3)`` the obstacle's outline.
        hit: a foot path enters the obstacle where it stands.
        text: h_m, h_bar, psi2, psi4 of the design.
    """

    body: F32
    body_colors: U8
    feet: F32
    feet_colors: U8
    trails: F32
    trail_colors: U8
    ground: F32
    obstacle: F32
    hit: bool
    text: str


def walk_text(view: DesignView) -> str:
    """The walking metrics shown beside the walking view."""
    ev, (a, b) = view.evaluation, view.walk.obstacle
    return (f"hₘ {float(ev.h_m[0]):.1f} mm · h̄ {float(ev.h_bar[0]):.1f} mm · "
            f"ψ₂({a:g}, {b:g}) {100.0 * float(ev.psi2[0]):.1f} % · ψ₄({a:g}, {b:g}) {100.0 * float(ev.psi4[0]):.1f} %")


BENCH_SHORT = (("mse", "MSE"), ("S", "S"), ("I", "I"), ("h_s", "hₛ"))  # the stages' figures, as the paper names them


def bench_text(view: DesignView) -> str:
    """The bench trajectory's headline figures over the bench view (its Metrics rows: MSE, S, I, h_s; the RTCLM's
    h6 or h4 first), two a line;
    a figure that is not this leg's (it does not walk; the RTCLM's MSE) is left out, and with none left the line
    says why; a leg without a walking view says so on a last line. The Metrics panel sat below the fold at 1280 x 720:
    these are what a slider is moved for."""
    rows = {r.key: r for r in view.rows}
    figures: tuple[tuple[str, str], ...] = BENCH_SHORT
    if "h_m" in rows and not rows["h_m"].label.startswith("Crossing"):  # the RTCLM's: "h6 (crossing height hₘ)"
        figures = (("h_m", rows["h_m"].label.split()[0]), *BENCH_SHORT)
    shown = [(short, rows[k]) for k, short in figures if k in rows and not rows[k].undefined]
    parts = [f"{short} {r.text()} {r.unit}" for short, r in shown
             if isinstance(r.value, float) and math.isfinite(r.value)]
    # A leg that does not walk has no walking view: said here, last (QA, session 37: the view vanished unsaid).
    gone = ["no walking view"] if view.walking is None else []
    if not parts:  # nothing to measure: why not, as the Metrics panel's "Why not" says it
        why = rows["why"].text() if "why" in rows else "-"
        return "\n".join(([] if why == "-" else textwrap.wrap(why, 32)) + gone)
    return "\n".join([" · ".join(parts[i:i + 2]) for i in range(0, len(parts), 2)] + gone)


def build_walk_scene(wf: WalkFrames, view: DesignView) -> WalkScene:
    """Scene geometry of a walking view (pure)."""
    n_legs = wf.feet.shape[1]
    leg_rgb = np.array([palette.LEGS[j % len(palette.LEGS)] for j in range(n_legs)])
    body = np.concatenate([wf.trunk[:, None], wf.legs], axis=1)
    body_colors = np.repeat(vertex_colours(np.concatenate([[palette.TRUNK], leg_rgb]))[:, None, :], 2, axis=1)
    seg = np.stack([wf.trails[:, :-1], wf.trails[:, 1:]], axis=2)  # (n_legs, m - 1, 2, 2)
    painted = np.repeat(np.repeat(vertex_colours(leg_rgb)[:, None, None, :], seg.shape[1], 1), 2, 2)
    each = simplified(*zip(seg, painted, strict=True))  # a leg's trail within 0.05 % of its own extent
    trails, trail_colors = np.concatenate([t for t, _ in each]), np.concatenate([c for _, c in each if c is not None])
    x0, y0, x1, y1 = wf.bounds
    pad = 0.04 * (x1 - x0)
    ground = np.array([[[x0 - pad, wf.ground], [x1 + pad, wf.ground]]])
    r = wf.obstacle
    outline = np.stack([r, np.roll(r, -1, axis=0)], axis=1)
    return WalkScene(
        body=_lift(to_scene(body), Z_LINES),
        body_colors=body_colors,
        feet=_lift(to_scene(wf.feet), Z_MARKERS),
        feet_colors=np.asarray(leg_rgb, dtype=np.uint8),  # a point cloud's: sRGB as it is
        trails=_lift(to_scene(trails), 0.5 * Z_LINES),
        trail_colors=trail_colors,
        ground=to_scene(ground),
        obstacle=_lift(to_scene(outline), Z_LINES),
        hit=wf.hit,
        text=walk_text(view),
    )


def _lift(p: F32, z: float) -> F32:
    out = p.copy()
    out[..., 2] = z
    return out


def vertex_colours(rgb: NDArray[np.integer]) -> U8:
    """sRGB colours (0-255) for the per-vertex colours of line segments.

    viser converts a line node's single colour from sRGB but passes per-vertex colours through as
    linear values, which then display lighter; converting here makes both look the same. (A point
    cloud shows its per-point colours as sRGB: :func:`paint`.)
    """
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(lin * 255.0).astype(np.uint8)


def paint(points: NDArray[np.floating], rgb: tuple[int, int, int]) -> U8:
    """One colour for every vertex of a line-segments ``(n, 2, 3)`` or point-cloud ``(n, 3)`` node: ``points``'
    shape with a colour in the last axis. Every such node carries per-vertex colours, so a page compiles one
    line shader and one point shader: a node with a single colour is another shader program, ~0.15 s of a page
    load in software WebGL (docs/studio.md). Lines take per-vertex colours as linear values
    (:func:`vertex_colours`); point clouds as sRGB, as they take a single colour."""
    c = vertex_colours(np.asarray(rgb)) if np.ndim(points) == 3 else np.asarray(rgb, dtype=np.uint8)
    return np.ascontiguousarray(np.broadcast_to(c, (*np.shape(points)[:-1], 3)))


def build_frames(view: DesignView, show_target: bool = True) -> SceneFrames:
    """Precompute everything the scene draws for a design view (pure; no server); without the target when no
    stage of the mechanism optimizes it (``show_target`` False)."""
    mech = view.design.mechanism
    sol = view.solution
    assert sol.joints is not None, "the studio solves with joints=True"
    joints = sol.joints[0]
    edges = link_edges(mech)
    colours = vertex_colours(np.array([palette.LINK, palette.CRANK, palette.GROUND]))
    kind_colour = np.where(edges.kinds[:, None] == EDGE_GROUND, 2, np.where(edges.kinds[:, None] == EDGE_CRANK, 1, 0))
    link_colors = np.repeat(colours[kind_colour[:, 0]][:, None, :], 2, axis=1)
    is_ground = np.array([isinstance(s, Ground) for s in mech.steps])
    # A ground point no moving body holds is not drawn (the RTCLM's locked primary linkage in its auxiliary mode:
    # A..D stood as loose pivots, and next to the bench view looked like part of it).
    pivots = np.isin(np.array(mech.joint_names), mech.pivots())
    point, leg = sol.point[0], sol.leg[0]
    none = np.zeros((0, 2))
    target_design = view.target_design if show_target else none
    target_leg = view.target_leg if show_target else none
    held = np.isin(np.array(mech.joint_names), [n for group in mech.locked for n in group])  # drawn as links
    design_pts = np.concatenate([joints[:, ~is_ground | pivots | held].reshape(-1, 2), target_design])
    leg_pts = np.concatenate([leg, target_leg])
    wf = view.walking
    lay, composition, texts, bars, h = _compose_views(design_pts, leg_pts, None if wf is None else wf.bounds,
                                                      walk_text(view) if wf is not None else "", bench_text(view))
    g = lay.leg
    pad = 0.06 * max(g[2] - g[0], g[3] - g[1])
    x0, y0, x1, y1 = g[0] - pad, g[1] - pad, g[2] + pad, g[3] + pad
    border = np.array([[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]], [[x0, y1], [x0, y0]]])
    # Ground line at the landing height y_g = y(t1) (spec §5); the x axis without feature points.
    y_g = view.features[0][1][1] if view.features else 0.0
    axis = np.array([[[x0, y_g], [x1, y_g]]]) if y0 < y_g < y1 else np.zeros((0, 2, 2))
    # Stance and swing colours per segment i -> i + 1, keeping only segments with finite ends.
    seg = np.stack([leg, np.roll(leg, -1, axis=0)], axis=1)
    keep = np.isfinite(seg).all(axis=(1, 2))
    stance = view.stance if view.stance is not None else np.ones(len(leg), dtype=bool)
    seg_colour = vertex_colours(np.where(stance[:, None], np.array(palette.STANCE), np.array(palette.SWING)))
    if view.stance is None:
        seg_colour[:] = vertex_colours(np.array(palette.PATH))
    feats = np.array([xy for _, xy in view.features], dtype=np.float64).reshape(-1, 2)
    extent = max(lay.scene[2] - lay.scene[0], lay.scene[3] - lay.scene[1])
    # viser needs finite arrays: where the mechanism does not assemble, hold its last assembled pose. If it never
    # assembles, the ground pivots stay where they are and what solves (the crank) turns; the other joints and the
    # links that reach them sit on the first ground pivot, and the foot is not drawn (``posed``). QA, session 37:
    # everything, pivots too, sat on one pivot as a red dot, and the bench view's foot fell outside its frame.
    hold = hold_last_valid(sol.valid[0])
    if hold is None:
        pivot = np.nan_to_num(joints[0, int(np.argmax(is_ground))])
        fin = np.isfinite(joints).all(axis=-1)
        pose = np.where(fin[..., None], joints, pivot)
        foot, leg_foot = np.broadcast_to(pivot, point.shape), np.broadcast_to(pivot, leg.shape)
        segments = link_segments(pose, edges.pairs)
        segments[~(fin[:, edges.pairs[:, 0]] & fin[:, edges.pairs[:, 1]])] = pivot
    else:
        pose, foot, leg_foot = joints[hold], point[hold], leg[hold]
        segments = link_segments(pose, edges.pairs)
    grid, step = grid_lines(composition.bounds)
    (path, _), (target, _), (leg_path, leg_colors), (leg_target, _) = simplified(
        (closed_polyline(point), None), (closed_polyline(target_design), None),
        (seg[keep], np.repeat(seg_colour[keep][:, None, :], 2, axis=1)), (closed_polyline(target_leg), None))
    assert leg_colors is not None
    return SceneFrames(
        links=_lift(to_scene(segments), Z_LINES),
        link_colors=link_colors,
        joints=_lift(to_scene(pose[:, ~is_ground]), Z_MARKERS),
        pivots=_lift(to_scene(pose[0, pivots]), Z_MARKERS),
        pivot_names=tuple(n for n, shown in zip(mech.joint_names, pivots, strict=True) if shown),
        # none where it never assembles: every joint sits on one pivot (review of session 33: six names piled on A)
        joint_names=tuple(n for n, g in zip(mech.joint_names, is_ground, strict=True) if not g) if hold is not None
        else (),
        foot=_lift(to_scene(foot[:, None, :]), 2 * Z_MARKERS),
        leg_foot=_lift(to_scene(leg_foot[:, None, :]), 2 * Z_MARKERS),
        path=_lift(to_scene(path), Z_LINES),
        target=_lift(to_scene(target), Z_LINES),
        leg_path=_lift(to_scene(leg_path), Z_LINES),
        leg_target=_lift(to_scene(leg_target), Z_LINES),
        leg_path_colors=leg_colors,
        leg_axes=to_scene(np.concatenate([border, axis])),
        features=_lift(to_scene(feats), Z_MARKERS),
        feature_names=tuple(name for name, _ in view.features),
        layout=lay,
        marker=0.01 * extent * SCENE_SCALE,
        composition=composition,
        walk=None if wf is None else build_walk_scene(wf, view),
        grid=_lift(to_scene(grid), 0.0),
        grid_step=step,
        texts=texts,
        # Within the frame and the room the layout keeps above the path for them (_compose_views' leg_top).
        feature_labels=feature_texts(view.features, FEATURE_TEXT * h, lay.leg_offset,
                                     (seg[keep], closed_polyline(target_leg)), (border, axis),
                                     (x0, y0, x1, max(y1, g[3] + (0.4 + LINE) * FEATURE_TEXT * h))),
        scale_bars=_lift(to_scene(bars), Z_LINES),
        text_height=h * SCENE_SCALE,
        posed=hold is not None,
    )


def _compose_views(design_pts: F64, leg_pts: F64, walk_bounds: F64 | None, walk_line: str, leg_line: str = ""
                   ) -> tuple[Layout, Composition, tuple[SceneText, ...], F64, float]:
    """Lay the views out from their own bounding boxes, titles and scale bars included: gaps wide enough that
    no title, note or scale label reaches into the next view, the walking view low enough for its two title
    lines, and bounds (for the camera) around all of it. The text height follows the composition's size, so
    it is solved by a few fixed-point steps. ``leg_line``: the bench figures, between the bench title and its view.

    Returns:
        the layout, the composition (bounds include every label), the labels, the scale bars ``(k, 2, 2)`` mm
        and the text height (mm).
    """
    parts = walk_line.split(" · ")  # two lines: heights, then obstacle crossing
    walk_line = " · ".join(parts[:2]) + ("\n" + " · ".join(parts[2:]) if len(parts) > 2 else "")
    d, g = bounds(design_pts), bounds(leg_pts)
    dw, lw = d[2] - d[0], g[2] - g[0]
    pad = 0.06 * max(lw, g[3] - g[1])
    h = max(dw, d[3] - d[1], lw, g[3] - g[1], 1.0) / TEXT_SCALE
    for step in range(4):
        small = SMALL_TEXT * h
        bar_w = {k: nice_step(span, 5) + 0.5 * h + text_width(f"{nice_step(span, 5):g} mm", small)
                 for k, span in (("design", dw), ("leg", lw + 2 * pad))}
        gap1 = pad + 2.0 * h + max(0.0, text_width(DESIGN_TITLE, h) - dw, bar_w["design"] - dw)
        gap2 = 2.0 * h + max(pad, text_width(LEG_TITLE, h) - lw - pad, bar_w["leg"] - lw - pad,
                             text_width(leg_line or " ", h) - lw - pad)
        walk_gap = pad + 3.0 * small + text_height(NOTE_ROOM, small) + 5.0 * h
        lay = layout(design_pts, leg_pts, gap1)
        comp = compose(lay, walk_bounds, gap2, walk_gap)
        off = lay.leg_offset
        legbox = np.array([g[0] - pad, g[1] - pad, g[2] + pad, g[3] + pad]) + np.concatenate([off, off])
        inset = comp.inset
        leg_top = max(legbox[3] + 0.6 * h, g[3] + off[1] + (0.4 + LINE) * FEATURE_TEXT * h + 0.4 * h)
        texts = [
            _text("design_title", DESIGN_TITLE, d[0], d[3] + 0.6 * h, "bottom-left", h),
            # Above the feature labels over the path's top too (they stand 0.4 of a feature label's height over it):
            # on the RTCLM's 20 mm foot path the padding is ~1 mm and "t6=t7=t8" printed through the title.
            _text("leg_title", LEG_TITLE, legbox[0],
                  leg_top + (text_height(leg_line, h) + 0.3 * h if leg_line else 0.0), "bottom-left", h),
            *((_text("leg_text", leg_line, legbox[0], leg_top, "bottom-left", h),) if leg_line else ()),
            _text("inset_title", INSET_TITLE, inset[0], inset[3] + 0.6 * h, "bottom-left", h),
            _text("inset_note", NOTE_ROOM, inset[0], inset[1] - 0.6 * small, "top-left", small),
        ]
        bars = []
        for key, x0, y, span in (("design", d[0], d[1] - 1.5 * small, dw),
                                 ("leg", legbox[0], legbox[1] - 1.5 * small, legbox[2] - legbox[0])):
            seg, label = scale_bar(x0, y, span, h, f"{key}_scale")
            bars.append(seg)
            texts.append(label)
        if walk_bounds is not None:
            w = np.asarray(walk_bounds, dtype=np.float64) + np.concatenate([comp.walk_offset, comp.walk_offset])
            wpad = 0.04 * (w[2] - w[0])  # the ground line reaches this far past the feet
            top = w[3] + 0.6 * h + text_height(walk_line, h) + 0.3 * h
            texts += [_text("walk_title", WALK_TITLE, w[0] - wpad, top, "bottom-left", h),
                      _text("walk_text", walk_line, w[0] - wpad, w[3] + 0.6 * h, "bottom-left", h)]
            seg, label = scale_bar(w[0] - wpad, w[1] - 1.5 * small, w[2] - w[0], h, "walk_scale")
            bars.append(seg)
            texts.append(label)
        boxes = np.array([t.box for t in texts] + [comp.bounds.tolist(), legbox.tolist()])
        bars_all = np.concatenate(bars)
        everything = np.concatenate([boxes[:, :2], boxes[:, 2:], bars_all.reshape(-1, 2)])
        full = np.concatenate([everything.min(axis=0), everything.max(axis=0)])
        h_next = max(full[2] - full[0], full[3] - full[1]) / TEXT_SCALE
        if abs(h_next - h) <= 0.02 * h or step == 3:
            break
        h = h_next
    return lay, replace(comp, bounds=full), tuple(texts), bars_all, h
