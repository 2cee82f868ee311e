"""The bench-trajectory chart as an inline SVG, drawn on the server: arrays in, markup out.

The side panel's one chart that every page shows at once. As a plotly chart it made each page load and
evaluate plotly.js (4.8 MB, ~1.5 s of a software-rendered page) before anything else of the studio
appeared; as SVG it costs a few kB and draws with the page. Equal scales in mm, a minimum height for flat
paths (``equal_aspect_ranges``), stance and swing in their colours, the target dashed,
feature points labelled. Curves are drawn in mm under one transform (their ``points`` are mm), so a test
or a person reading the markup sees the data, not pixels.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from html import escape

import numpy as np
from numpy.typing import NDArray

from studio import palette
from studio.spots import Box, as_segments, cover, length_under, spill

F64 = NDArray[np.float64]
WIDTH = 320.0  # viewBox width (px); the chart scales to the panel's width
LEFT, RIGHT, TOP, BOTTOM = 46.0, 10.0, 30.0, 36.0
MAX_ASPECT = 1.1  # a tall path is drawn narrower rather than taller than this (height / width)
FONT = "font-family:sans-serif;font-size:11px;fill:#444"


def _closed(points: F64) -> F64:
    """Append the first point so a closed curve draws closed."""
    return np.concatenate([points, points[:1]], axis=0)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Maximal cyclic runs of True as ``(start, stop)`` index ranges (stop exclusive, may exceed n)."""
    n = len(mask)
    if mask.all():
        return [(0, n)]
    if not mask.any():
        return []
    starts = [i for i in range(n) if mask[i] and not mask[i - 1]]
    runs = []
    for s in starts:
        e = s
        while mask[e % n]:
            e += 1
        runs.append((s, e))
    return runs


def _arc(points: F64, start: int, stop: int) -> F64:
    """Samples start..stop (inclusive of the joint to the next sample), cyclic."""
    idx = np.arange(start, stop + 1) % len(points)
    return points[idx]


MIN_ASPECT = 0.3  # height / width of the bench chart's axes at least, however flat the path


def equal_aspect_ranges(clouds: list[F64], pad: float = 0.06) -> tuple[list[float] | None, list[float] | None]:
    """x and y ranges (mm) around the finite points of ``(n, 2)`` clouds, the shorter axis widened to at least
    ``MIN_ASPECT`` of the longer one (a nearly flat RTCLM path would otherwise get a chart of zero height)."""
    pts = np.concatenate([np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in clouds])
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        return None, None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1e-6)
    big = float(span.max())
    span = np.maximum(span, MIN_ASPECT * big) * (1.0 + 2.0 * pad)
    mid = 0.5 * (lo + hi)
    return [float(mid[0] - span[0] / 2), float(mid[0] + span[0] / 2)], \
        [float(mid[1] - span[1] / 2), float(mid[1] + span[1] / 2)]


def ticks(lo: float, hi: float, count: int = 5) -> list[float]:
    """Round values (1, 2 or 5 x 10^k apart) inside [lo, hi], about ``count`` of them."""
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return []
    raw = span / count
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 5.0, 10.0) if m * mag >= raw)
    first = math.ceil(lo / step) * step
    out = [round(first + k * step, 10) for k in range(int((hi - first) / step + 1e-9) + 1)]
    return out if len(out) >= 2 or count > 20 else ticks(lo, hi, count + 1)  # two at least: a scale


def _label(v: float) -> str:
    return f"{v:g}" if abs(v) >= 1 or v == 0 else f"{v:.2g}"


def _points(arc: F64) -> list[str]:
    """``points`` attributes of the finite stretches of an ``(n, 2)`` polyline (mm)."""
    out, cur = [], []
    for x, y in arc:
        if np.isfinite(x) and np.isfinite(y):
            cur.append(f"{x:.3f},{y:.3f}")
        elif cur:
            out.append(" ".join(cur))
            cur = []
    if cur:
        out.append(" ".join(cur))
    return [p for p in out if " " in p]


# A feature label's box (px, 11 px sans-serif): a character's mean width, the height above and below the baseline.
CHAR_W, ASCENT, DESCENT = 6.2, 9.0, 2.5
DOT = 3.5  # a feature point's radius (px)
CURVE = 0.1  # a label's cost per px of curve under it: 80 px of it weigh as one px of label reaching off the plot
# Where a label may go, tried in this order: (dx, dy) of its baseline anchor from the point, and the anchor.
SPOTS = ((0.0, -7.0, "middle"), (0.0, 15.0, "middle"), (6.0, 4.0, "start"), (-6.0, 4.0, "end"),
         (5.0, -6.0, "start"), (-5.0, -6.0, "end"), (5.0, 14.0, "start"), (-5.0, 14.0, "end"),
         (0.0, -18.0, "middle"), (0.0, 26.0, "middle"))



def label_box(x: float, y: float, anchor: str, text: str) -> Box:
    """The box (x0, y0, x1, y1) a label with its baseline anchor at (x, y) covers (px, y down)."""
    w = CHAR_W * len(text)
    x0 = x - w / 2 if anchor == "middle" else x if anchor == "start" else x - w
    return x0, y - ASCENT, x0 + w, y + DESCENT


def label_spots(points: list[tuple[float, float]], texts: list[str], bounds: Box,
                lines: F64 | None = None) -> list[tuple[float, float, str]]:
    """Each feature label's baseline anchor (x, y, text-anchor), in the points' order: above its point where that
    covers no other label or point, stays inside ``bounds`` (x0, y0, x1, y1: the plot, so no label covers a
    tick's) and is nearer its own point than any other; else the first of ``SPOTS`` that does, or failing that
    the one that does least harm. Placed in order, then each placed again against all the others (a few rounds):
    placed only in order, Jansen's t1=t4 took the spot under t3 that t3 needed. Labels centred above their points
    printed over each other where points sit close (Jansen's t1=t4 and t3 on a 70 mm stance, Klann's t2=t3 and
    t5). ``lines``: ``(k, 2, 2)`` the curves' segments (px); the length of them under a label costs ``CURVE`` a px
    (session 39: the bench chart's labels sat on the swing curve the scene's had left in session 38)."""
    dots = [(x - DOT, y - DOT, x + DOT, y + DOT) for x, y in points]
    curves = as_segments(*(() if lines is None else (lines,)))
    under: dict[tuple[int, tuple[float, float, str]], float] = {}  # curve px under label k at a spot, once each

    def curve_cost(k: int, spot: tuple[float, float, str], box: Box) -> float:
        if (k, spot) not in under:
            under[k, spot] = CURVE * length_under(curves, box)
        return under[k, spot]

    def cost(k: int, spot: tuple[float, float, str], others: list[Box]) -> float:
        box = label_box(*spot, texts[k])
        c = 10.0 * sum(cover(box, o) for o in others) + 8.0 * spill(box, bounds) + curve_cost(k, spot, box)
        # Nearer another point than its own, a label reads as that point's.
        cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        x, y = points[k]
        own = math.hypot(cx - x, cy - y)
        return c + 40.0 * sum(1 for j, (qx, qy) in enumerate(points) if j != k and math.hypot(cx - qx, cy - qy) < own)

    def best(k: int, others: list[Box]) -> tuple[tuple[float, float, str], float]:
        x, y = points[k]
        found, least = (x, y - 7.0, "middle"), math.inf
        for dx, dy, anchor in SPOTS:
            spot = (x + dx, y + dy, anchor)
            c = cost(k, spot, others)
            if c < least:
                found, least = spot, c
            if c == 0.0:
                break
        return found, least

    def others(k: int, spots: dict[int, tuple[float, float, str]]) -> list[Box]:
        return [label_box(*s, texts[j]) for j, s in spots.items() if j != k] + dots[:k] + dots[k + 1:]

    def arrange(order: list[int]) -> tuple[list[tuple[float, float, str]], float]:
        spots: dict[int, tuple[float, float, str]] = {}
        for k in order:
            spots[k] = best(k, others(k, spots))[0]
        for _ in range(3):
            moved = False
            for k in order:
                spot, c = best(k, others(k, spots))
                if c < cost(k, spots[k], others(k, spots)):
                    spots[k], moved = spot, True
            if not moved:
                break
        return [spots[k] for k in range(len(points))], sum(cost(k, spots[k], others(k, spots)) for k in spots)

    n = len(points)
    near = [sum(math.hypot(x - qx, y - qy) < 30.0 for qx, qy in points) for x, y in points]
    # The points' order, then the most crowded first (it has the fewest free spots), then backwards.
    tried: list[tuple[list[tuple[float, float, str]], float]] = []
    for order in (list(range(n)), sorted(range(n), key=lambda k: -near[k]), list(range(n))[::-1]):
        tried.append(arrange(order))
        if tried[-1][1] == 0.0:
            break
    return min(tried, key=lambda t: t[1])[0]


def bench_svg(
    leg: F64,
    target_leg: F64 | None = None,
    *,
    stance: NDArray[np.bool_] | None = None,
    features: Mapping[str, tuple[float, float]] | None = None,
) -> str:
    """The bench trajectory in the leg frame (mm) with the target overlaid, as ``<svg>`` markup.

    Args:
        leg: ``(n_samples, 2)`` foot path in the leg frame (mm); NaN samples leave gaps.
        target_leg: ``(n_target, 2)`` target in the leg frame (mm), or None.
        stance: ``(n_samples,)`` True on the stance half-cycle (stance and swing in two colours), or None.
        features: feature points by label (``{"t1=t4": (x, y), ...}``, mm).

    The ``<svg class="clm-bench">`` carries ``data-x`` and ``data-y`` (the axis ranges, mm); each curve is a
    ``<polyline data-name=...>`` (``bench trajectory``, ``stance``, ``swing``, ``target``) in mm.
    """
    leg = np.asarray(leg, dtype=np.float64).reshape(-1, 2)
    tgt = None if target_leg is None else np.asarray(target_leg, dtype=np.float64).reshape(-1, 2)
    xr, yr = equal_aspect_ranges([leg, *(() if tgt is None else (tgt,))])
    if xr is None or yr is None:
        xr, yr = [0.0, 1.0], [0.0, 1.0]
    pw = WIDTH - LEFT - RIGHT
    aspect = (yr[1] - yr[0]) / (xr[1] - xr[0])
    ph = pw * min(aspect, MAX_ASPECT)
    k = ph / (yr[1] - yr[0])  # px per mm, the same across and up
    pw_used = k * (xr[1] - xr[0])
    x0 = LEFT + 0.5 * (pw - pw_used)
    height = TOP + ph + BOTTOM

    def px(x: float, y: float) -> tuple[float, float]:
        return x0 + (x - xr[0]) * k, TOP + (yr[1] - y) * k

    out = [f'<svg class="clm-bench" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH:g} {height:.1f}" '
           f'width="100%" data-x="{xr[0]:.6g},{xr[1]:.6g}" data-y="{yr[0]:.6g},{yr[1]:.6g}" '
           'style="display:block">',
           f'<rect class="plot" x="{x0:.2f}" y="{TOP:.2f}" width="{pw_used:.2f}" height="{ph:.2f}" fill="white" '
           'stroke="#ccc"/>']
    for v in ticks(xr[0], xr[1]):
        x, _ = px(v, yr[0])
        out.append(f'<line x1="{x:.2f}" y1="{TOP:.2f}" x2="{x:.2f}" y2="{TOP + ph:.2f}" stroke="#e5e5e5"/>')
        out.append(f'<text class="xtick" x="{x:.2f}" y="{TOP + ph + 13:.2f}" text-anchor="middle" '
                   f'style="{FONT}">{_label(v)}</text>')
    for v in ticks(yr[0], yr[1], count=max(2, min(5, int(ph / 28)))):
        _, y = px(xr[0], v)
        out.append(f'<line x1="{x0:.2f}" y1="{y:.2f}" x2="{x0 + pw_used:.2f}" y2="{y:.2f}" stroke="#e5e5e5"/>')
        out.append(f'<text class="ytick" x="{x0 - 5:.2f}" y="{y + 4:.2f}" text-anchor="end" '
                   f'style="{FONT}">{_label(v)}</text>')
    out.append(f'<text x="{x0 + pw_used / 2:.2f}" y="{height - 6:.2f}" text-anchor="middle" style="{FONT}">'
               'x, leg frame (mm)</text>')
    out.append(f'<text x="12" y="{TOP + ph / 2:.2f}" text-anchor="middle" style="{FONT}" '
               f'transform="rotate(-90 12 {TOP + ph / 2:.2f})">y (mm)</text>')

    curves: list[tuple[str, F64, palette.RGB, str]] = []  # name, polyline (mm), colour, dash
    if tgt is not None:
        curves.append(("target", _closed(tgt), palette.TARGET, "6 4"))
    if stance is None:
        curves.append(("bench trajectory", _closed(leg), palette.PATH, ""))
    else:
        mask = np.asarray(stance, dtype=bool)
        for name, m, colour in (("stance", mask, palette.STANCE), ("swing", ~mask, palette.SWING)):
            for s, e in _runs(m):
                curves.append((name, _arc(leg, s, e), colour, ""))
    # Curves in mm: y up, one scale; strokes and dashes stay in px.
    out.append(f'<g transform="matrix({k:.6g} 0 0 {-k:.6g} {x0 - xr[0] * k:.6g} {TOP + yr[1] * k:.6g})">')
    for name, arc, colour, dash in curves:
        for pts in _points(arc):
            out.append(f'<polyline data-name="{name}" points="{pts}" fill="none" stroke="{palette.css(colour)}" '
                       f'stroke-width="{2 if name == "target" else 2.5}" vector-effect="non-scaling-stroke"'
                       + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")
    out.append("</g>")
    shown = [(name, px(fx, fy)) for name, (fx, fy) in (features or {}).items()
             if np.isfinite(fx) and np.isfinite(fy)]
    for _, (x, y) in shown:
        out.append(f'<circle class="feature" cx="{x:.2f}" cy="{y:.2f}" r="3.5" fill="black"/>')
    names = [n for n, _ in shown]
    # Labels may rise into the top margin, not onto the legend (its text ends at y = 18.5), nor onto the x ticks.
    plot = (x0 - 4.0, TOP - 11.0, x0 + pw_used + 4.0, TOP + ph + 3.0)
    drawn = [np.stack([x0 + (arc[:, 0] - xr[0]) * k, TOP + (yr[1] - arc[:, 1]) * k], axis=1) for _, arc, _, _ in curves]
    lines = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in drawn if len(c) > 1] or [np.zeros((0, 2, 2))])
    lines = lines[np.isfinite(lines).all(axis=(1, 2))]
    for name, (lx, ly, anchor) in zip(names, label_spots([xy for _, xy in shown], names, plot, lines), strict=True):
        out.append(f'<text class="label" x="{lx:.2f}" y="{ly:.2f}" text-anchor="{anchor}" '
                   f'style="{FONT};fill:#222">{escape(name)}</text>')

    kinds: list[tuple[str, palette.RGB | None, str]] = [
        ("target", palette.TARGET, "6 4"), ("stance", palette.STANCE, ""), ("swing", palette.SWING, ""),
        ("bench trajectory", palette.PATH, "")]
    legend = [kind for kind in kinds if any(cn == kind[0] for cn, *_ in curves)]
    if features:
        legend.append(("feature points", None, ""))
    lx = 8.0
    for name, swatch, dash in legend:
        if swatch is None:
            out.append(f'<circle cx="{lx + 9:.1f}" cy="12" r="3.5" fill="black"/>')
        else:
            out.append(f'<line x1="{lx:.1f}" y1="12" x2="{lx + 18:.1f}" y2="12" stroke="{palette.css(swatch)}" '
                       f'stroke-width="2.5"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")
        out.append(f'<text x="{lx + 22:.1f}" y="16" style="{FONT}">{escape(name)}</text>')
        lx += 28 + 6.2 * len(name)
    out.append("</svg>")
    return "".join(out)
