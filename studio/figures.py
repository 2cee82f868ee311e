"""Pure plotly figure builders: arrays in, ``go.Figure`` out; no server, no state.

Tests call them directly; the panels hand the result to ``GuiPlotlyHandle.figure``.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from studio import palette
from studio.spots import Box, covers, first_clear, spill

F64 = NDArray[np.float64]

# Tick labels are drawn as they are ("allow"): plotly's default for numeric axes ("hide past div") measures every
# label's box after each redraw, which forces a layout of the whole page; in software rendering that was the
# largest script cost of a run's first second (66 of ~100 ms of forced layouts, the page's worst lag; session 35).
# automargin keeps the labels inside the chart.
KEEP_TICKS = "allow"


def _axis_range(values: F64, focus: F64) -> list[float] | None:
    """A range covering the focus values (the feasible ones) with a margin, and the rest within one span of them."""
    focus = focus[np.isfinite(focus)]
    if len(focus) == 0:
        return None
    lo, hi = float(focus.min()), float(focus.max())
    span = hi - lo if hi > lo else max(abs(hi), 1.0) * 0.1
    near = values[np.isfinite(values) & (values >= lo - span) & (values <= hi + span)]
    lo, hi = min(lo, float(near.min(initial=lo))), max(hi, float(near.max(initial=hi)))
    pad = 0.06 * (hi - lo if hi > lo else span)
    return [lo - pad, hi + pad]


# Label placement on a 2-D chart (px of the side panel's plot area, where space is scarcest; the large chart has
# more room): the positions tried in order, a label's size, and the marker it sits beside.
PLOT_PX = (225.0, 165.0)  # a 320 px panel's chart at ASPECT_2D, less its margins, title and legend (the narrowest seen)
CHAR_PX, LINE_PX, MARKER_PX = 6.5, 13.0, 7.0
LEGEND_ROOM = 95  # px under the plot: the axis title and a legend of three rows
RING_PX = 12.0  # a picked or passed-on member's ring: plotly sets its label off by the ring's size
NEAR = ("top center", "bottom center", "middle right", "middle left", "top right", "top left", "bottom right",
        "bottom left")
# A step further out, past a neighbour's marker: plotly has no offset, so the text is padded toward its marker
# (no-break spaces beside it, an empty line above or below it). Tried after every near position.
FAR = ("far top center", "far bottom center", "far middle right", "far middle left")
POSITIONS = NEAR + FAR
PAD_SPACES = 4  # no-break spaces of a far label: ~3.3 px each in plotly's 12 px type
NO_LABEL = " "
"""The text of a candidate whose label is left to the hover. Not "": plotly.js's Plotly.react (how viser updates a
chart) never draws a point's label again once it has been drawn empty, so K1 stayed blank on a live chart after
a redraw that had hidden it or moved it onto the pick's ring."""
FAR_PX = 13.0
DOT_PX = 4.5  # half a front or dominated member's marker (9 px)
FAR_COST = 25.0  # px² of dots a label may hide rather than stand a step off its marker (a dot is ~81 px²)


Y_TITLE_CHARS = 18  # a vertical axis title longer than this ran past a side panel's ~165 px plot ("idth penalty")


def _two_lines(title: str) -> str:
    """A long vertical axis title broken before its unit (or at the space nearest its middle): "f2 = width penalty
    (mm^2)" was cut at both ends beside a side panel's plot."""
    if len(title) <= Y_TITLE_CHARS or " " not in title:
        return title
    cut = title.rfind(" (")
    if cut <= 0:
        spaces = [i for i, c in enumerate(title) if c == " "]
        cut = min(spaces, key=lambda i: abs(i - len(title) / 2))
    return f"{title[:cut]}<br>{title[cut + 1:]}"


SHARED = 1e-6  # values spread less than this share of their size are one value on an axis


def _one_tick(values: F64) -> dict[str, object]:
    """A single tick at the value every drawn member shares (subtask 1's f2 = 0 read "-0.006 ... 0.006": a scale
    for a spread there is not), or all but shares: within ``SHARED`` of it (a collapsed population's I read
    "51.00152, 51.001525, 51.00153"), saying how close; {} when the values vary or nothing is drawn."""
    v = values[np.isfinite(values)]
    if len(v) == 0:
        return {}
    spread, mid = float(np.ptp(v)), float(np.median(v))
    if spread == 0:
        return {"tickmode": "array", "tickvals": [float(v[0])], "ticktext": [f"{float(v[0]):.4g}"]}
    if spread <= SHARED * abs(mid):
        return {"tickmode": "array", "tickvals": [mid], "ticktext": [f"{mid:.6g} (all within {spread:.1g})"]}
    return {}


def _label_box(x: float, y: float, text: str, position: str, r: float = MARKER_PX) -> Box:
    """(x0, y0, x1, y1) in px (y up) of ``text`` beside a marker of radius ``r`` at (x, y), as plotly's
    ``textposition`` puts it (a ``far`` position one step further out, as :func:`label_text` pads it)."""
    far = position.startswith("far ")
    vert, horiz = position.removeprefix("far ").split(" ")
    x0, y0, x1, y1 = _near_box(x, y, text, f"{vert} {horiz}", r)
    if not far:
        return x0, y0, x1, y1
    dx = FAR_PX if horiz == "right" else -FAR_PX if horiz == "left" else 0.0
    dy = LINE_PX if vert == "top" else -LINE_PX if vert == "bottom" else 0.0
    return x0 + dx, y0 + dy, x1 + dx, y1 + dy


def label_text(text: str, position: str) -> str:
    """The text plotly draws for a label at ``position`` (from :func:`place_labels`): a far one padded toward its
    marker."""
    if not position.startswith("far "):
        return text
    vert, horiz = position.removeprefix("far ").split(" ")
    pad = "\u00a0" * PAD_SPACES
    return {"right": pad + text, "left": text + pad}.get(horiz) or (text + "<br>\u00a0" if vert == "top"
                                                                     else "\u00a0<br>" + text)


def _near_box(x: float, y: float, text: str, position: str, r: float) -> Box:
    w, h = CHAR_PX * len(text) + 2.0, LINE_PX
    vert, horiz = position.split(" ")
    cx = x if horiz == "center" else (x + r + w / 2 if horiz == "right" else x - r - w / 2)
    cy = y if vert == "middle" else (y + r + h / 2 if vert == "top" else y - r - h / 2)
    if vert != "middle" and horiz != "center":  # a corner: diagonal from the marker, closer in
        sx, sy = (1 if horiz == "right" else -1), (1 if vert == "top" else -1)
        cx, cy = x + sx * (w / 2 + r / 2), y + sy * (h / 2 + r / 2)
    return cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2


def place_labels(xy: F64, texts: Sequence[str], ranges: tuple[list[float], list[float]],
                 points: F64 | None = None, radii: Sequence[float] | None = None) -> list[str | None]:
    """A ``textposition`` for each labelled point ``(n, 2)`` (in priority order), or None where every position
    would cover a label placed before it (hover still names it). Among the positions inside the plot area and clear
    of the labels placed before it, the one of least :func:`label_cost`: over another candidate's marker only if
    every one is, then over as few of the other drawn ``points`` ``(m, 2)`` as it can, beside its marker rather
    than a step further out (the first free one printed "best I" across K5's diamond, and labels sat on the
    front's dots). With none inside, the first clear of labels (a label past the edge is cut). ``radii``: each
    labelled marker's (px; ``MARKER_PX``, a ring's ``RING_PX``). Draw it with :func:`label_text`."""
    (x0, x1), (y0, y1) = ranges

    def to_px(v: F64) -> F64:
        return np.column_stack([(v[:, 0] - x0) / max(x1 - x0, 1e-300) * PLOT_PX[0],
                                (v[:, 1] - y0) / max(y1 - y0, 1e-300) * PLOT_PX[1]])

    px = to_px(xy)
    rs = [MARKER_PX] * len(px) if radii is None else [float(v) for v in radii]
    d = DOT_PX
    plot: Box = (0.0, 0.0, PLOT_PX[0], PLOT_PX[1])
    markers = [(x - r, y - r, x + r, y + r) for (x, y), r in zip(px, rs, strict=True)
               if np.isfinite(x) and np.isfinite(y)]
    pts = to_px(points) if points is not None and len(points) else np.zeros((0, 2))
    dots = [(x - d, y - d, x + d, y + d) for x, y in pts
            if np.isfinite(x) and np.isfinite(y) and -d < x < PLOT_PX[0] + d and -d < y < PLOT_PX[1] + d]
    labels: list[Box] = []
    out: list[str | None] = []
    for (x, y), text, r in zip(px, texts, rs, strict=True):
        chosen = None
        if np.isfinite(x) and np.isfinite(y):
            own = (x - r, y - r, x + r, y + r)
            others = [m for m in markers if m != own]
            boxes = {pos: _label_box(x, y, text, pos, r) for pos in POSITIONS}
            free = [pos for pos in POSITIONS if first_clear([boxes[pos]], labels) is not None]
            inside = [pos for pos in free if spill(boxes[pos], plot) == 0.0]
            if inside:
                costs = label_costs([boxes[pos] for pos in inside], inside, others, dots)
                chosen = inside[int(np.argmin(costs))]  # the first of equals
            elif free:
                chosen = free[0]
            if chosen is not None:
                labels.append(boxes[chosen])
        out.append(chosen)
    return out


def label_costs(boxes: Sequence[Box], positions: Sequence[str], markers: Sequence[Box],
                dots: Sequence[Box]) -> NDArray[np.float64]:
    """What labels at ``boxes`` hide: the candidates' ``markers`` first (each px² of one outweighs a label over the
    whole front), then the drawn ``dots``, and a little for standing a step off its marker."""
    far = np.array([p.startswith("far ") for p in positions], dtype=np.float64)
    return 1e4 * covers(boxes, markers) + covers(boxes, dots) + FAR_COST * far


def short_label(label: str) -> str:
    """``f3 (mm^2)`` of ``f3 = (y_min + H)^2 (mm^2)``: the name and unit, for a 3-D chart's axes in a side panel
    (its long titles printed over each other); a label without `` = `` as it is."""
    name, sep, rest = label.partition(" = ")
    if not sep:
        return label
    unit = rest[rest.rfind(" ("):] if rest.endswith(")") and " (" in rest else ""
    return name + unit


def objective_label(name: str, labels: Mapping[str, str]) -> str:
    """Axis title of an objective: its problem label with unit (``f1 = MSE (mm)``), else its name."""
    return labels.get(name, name)


def _drawn(F: F64) -> F64:
    """The first three objectives of the members a chart draws (every one finite)."""
    G = F[:, :3]
    return G[np.isfinite(G).all(axis=1)]


def flat_axes(F: F64, objectives: tuple[str, ...]) -> tuple[int, int] | None:
    """The two objective columns to project onto when one of the first three objectives is the same for every drawn
    member (the varying ones first), or None when all three vary, there are fewer than three, or nothing is drawn."""
    G = _drawn(np.asarray(F, dtype=np.float64))
    if len(objectives) < 3 or len(G) == 0:
        return None
    varies = [bool(np.ptp(G[:, k]) > 0) for k in range(3)]
    if all(varies):
        return None
    a = next((k for k in range(3) if varies[k]), 0)
    b = next((k for k in range(3) if k != a and varies[k]), next(k for k in range(3) if k != a))
    lo, hi = sorted((a, b))
    return lo, hi


def same_for_all(F: F64, objectives: tuple[str, ...]) -> str:
    """``f2 = 0 and f3 = 0 for every member``: the first three objectives that do not vary, with their value."""
    G = _drawn(np.asarray(F, dtype=np.float64))
    if len(G) == 0:
        return ""
    flat = [f"{objectives[k]} = {float(G[0, k]):.3g}" for k in range(G.shape[1]) if np.ptp(G[:, k]) == 0]
    return f"{' and '.join(flat)} for every member" if flat else ""


def make_pareto_figure(
    F: F64,
    cv: F64,
    *,
    objectives: tuple[str, ...],
    labels: Mapping[str, str] | None = None,
    front: tuple[int, ...] | NDArray[np.intp] = (),
    knees: tuple[int, ...] = (),
    best: tuple[int, ...] = (),
    shown: int | None = None,
    passed: int | None = None,
    title: str = "",
    axes: tuple[int, int] | None = None,
) -> go.Figure:
    """The population of a stage in objective space: 2-D for two objectives, 3-D for three or more (or, with
    ``axes``, the 2-D projection onto those two objectives).

    Args:
        F: ``(pop, n_obj)`` objectives (+inf or NaN where undefined: such members are not drawn).
        cv: ``(pop,)`` total constraint violation (0: feasible).
        objectives: objective names (F's columns).
        labels: axis titles with units by objective name (``ProblemSpec.labels``).
        front: indices of the feasible non-dominated members.
        knees: knee candidates (ranked); drawn as ``K1``, ``K2``, ...
        best: best member per objective (``Shortlist.best``).
        shown: the member the designer picked (animated in the editor), marked.
        passed: the member passed on to the next stage, if different, marked too.
        title: figure title.
        axes: two objective columns to project onto (three or more objectives); None: all (3-D).

    With one objective the chart is objective against constraint violation. Member indices
    are in each point's hover text and ``customdata``.
    """
    F = np.asarray(F, dtype=np.float64).reshape(-1, len(objectives))
    cv = np.asarray(cv, dtype=np.float64).reshape(-1)
    labels = labels or {}
    n_obj = len(objectives)
    drawable = np.isfinite(F).all(axis=1)
    feasible = drawable & (cv <= 0.0)
    on_front = np.zeros(len(F), dtype=bool)
    on_front[np.asarray(front, dtype=np.intp)] = True
    on_front &= feasible
    if n_obj == 1:
        coords = np.stack([F[:, 0], np.where(np.isfinite(cv), cv, np.nan)], axis=1)
        titles = [objective_label(objectives[0], labels), "violation (0 = feasible)"]
    elif axes is not None and n_obj >= 2:
        cols = [int(a) for a in axes]
        coords = F[:, cols]
        titles = [objective_label(objectives[c], labels) for c in cols]
    else:
        coords = F[:, : min(n_obj, 3)]
        titles = [objective_label(o, labels) for o in objectives[:3]]
    three = coords.shape[1] == 3
    fig = go.Figure()

    # The view frames the front and the candidates (the rest within one span of them is shown too; what lies
    # further is off the view until the user zooms out): a front crowded into a corner by far dominated members
    # reads at a glance. With fewer than two such members it frames the feasible ones.
    focus = on_front.copy()
    marked = [i for i in (*knees, *best, shown, passed) if i is not None and 0 <= i < len(F)]
    focus[np.asarray(marked, dtype=np.intp)] = True
    focus &= drawable
    if focus.sum() < 2:
        focus = feasible
    ranges = None if three else tuple(_axis_range(coords[:, k], coords[focus, k]) for k in (0, 1))
    if n_obj == 1 and ranges is not None:  # the violation axis: from 0 (feasible) up to the largest drawn
        v = coords[drawable, 1]
        v = v[np.isfinite(v)]
        if len(v) and v.max() > 1e-9:
            top = float(v.max()) * 1.06
            ranges = (ranges[0], [-0.06 * top, top])
        else:  # every member feasible: their line through the middle under its one tick, 0 (it ran along the bottom
            ranges = (ranges[0], [-1.0, 1.0])  # edge of an empty chart; QA, session 37); no negative tick shows
    placed: dict[int, str | None] = {}  # member -> its label's position on a 2-D chart (None: hover only)
    # Every point's hover names the candidates it is (the front's point under a knee's diamond took the hover,
    # which read "member #14" where the docs promise "K2"), and its objectives with their units.
    extra = [b for b in dict.fromkeys(best) if b not in knees]
    knee_names = [f"K{j + 1}" for j in range(len(knees))]
    names = [f"best {objectives[best.index(b)]}" for b in extra]
    labelled = [int(i) for i in (*knees, *extra)]
    label_of = dict(zip(labelled, knee_names + names, strict=True))  # each candidate's label on the chart
    tags: dict[int, list[str]] = {i: [t] for i, t in label_of.items()}
    for o, b in zip(objectives, best, strict=False):  # a knee that is also best in an objective says so too
        if b in knees:
            tags.setdefault(int(b), []).append(f"best {o}")
    axis_names = "xyz"[: coords.shape[1]]
    template = "%{hovertext}" + "".join(f"<br>{t}: %{{{a}:.4g}}" for a, t in zip(axis_names, titles, strict=True)) \
        + "<extra></extra>"

    def add(name: str, idx: NDArray[np.intp] | list[int], marker: dict[str, object], text: list[str] | None = None,
            show_in_legend: bool = True, clip: bool = False) -> None:
        idx = np.asarray(idx, dtype=np.intp)
        keep: NDArray[np.bool_] = np.asarray(drawable)[idx] if len(idx) else np.zeros(0, dtype=bool)
        idx = idx[keep] if len(idx) else idx
        hover = [(" · ".join(tags[int(i)]) + ": " if int(i) in tags else "") + f"member #{i}"
                 + ("" if feasible[i] else f", violation {cv[i]:.3g}") for i in idx]
        common: dict[str, object] = {"name": name, "customdata": idx.tolist(), "hovertext": hover,
                                     "hovertemplate": template, "showlegend": show_in_legend, "marker": marker}
        if text is not None:
            text = [t for t, k in zip(text, keep, strict=True) if k]
            if three:
                common.update(text=text, mode="markers+text", textposition="top center")
            else:  # labels that would cover another are left to the hover
                where = [placed.get(int(i)) for i in idx]
                common.update(text=[label_text(t, w) if w else NO_LABEL for t, w in zip(text, where, strict=True)],
                              mode="markers+text",
                              textposition=[(w or "top center").removeprefix("far ") for w in where])
        else:
            common["mode"] = "markers"
        pts = coords[idx]
        if three:
            fig.add_trace(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], **common))
        else:  # markers and labels at the edge are drawn whole, not cut by the plot area (the rest off the view: cut)
            fig.add_trace(go.Scatter(x=pts[:, 0], y=pts[:, 1], cliponaxis=clip, **common))

    size = 4 if three else 7
    if not three and ranges is not None and all(r is not None for r in ranges) and labelled:
        ok = [i for i in labelled if bool(np.asarray(drawable)[i])]
        where = place_labels(coords[ok], [label_of[i] for i in ok], ranges,  # type: ignore[arg-type]
                             coords[drawable & ~np.isin(np.arange(len(F)), ok)],
                             [RING_PX if i in (shown, passed) else MARKER_PX for i in ok])
        placed.update(zip(ok, where, strict=True))
    # A ringed candidate (picked, passed on) carries its label on the ring, which plotly sets off by the ring's
    # size: beside its own marker the red ring crossed the label's first letter ("pest f1").
    ringed = {int(m): placed.pop(int(m)) for m in (shown, passed) if m is not None and placed.get(int(m))}
    add("infeasible", np.flatnonzero(drawable & ~feasible),
        {"color": palette.css(palette.INFEASIBLE, 0.6), "size": size, "symbol": "x"}, clip=True)
    add("dominated", np.flatnonzero(feasible & ~on_front), {"color": palette.css(palette.FEASIBLE, 0.8), "size": size},
        clip=True)
    add("Pareto front", np.flatnonzero(on_front), {"color": palette.css(palette.PATH), "size": size + 2,
                                                   "line": {"color": "white", "width": 0.5}})
    if knees:
        add("knees", list(knees), {"color": palette.css(palette.KNEE), "size": size + 5,
                                             "symbol": "diamond", "line": {"color": "black", "width": 1}},
            text=knee_names)
    if extra:
        add("best", extra, {"color": palette.css(palette.BEST), "size": size + 4, "symbol": "square",
                                          "line": {"color": "black", "width": 1}}, text=names)
    placed.update(ringed)

    def ring_text(m: int) -> list[str] | None:
        return [label_of[m]] if m in ringed else None

    if passed is not None and passed != shown and 0 <= passed < len(F):
        add("passed on", [passed], {"color": "rgba(0,0,0,0)", "size": size + 12,
                                    "line": {"color": palette.css(palette.PASSED), "width": 3}},
            text=ring_text(int(passed)))
    if shown is not None and 0 <= shown < len(F):
        add("picked", [shown], {"color": "rgba(0,0,0,0)", "size": size + 14,
                                "line": {"color": palette.css(palette.FOOT), "width": 3}}, text=ring_text(int(shown)))
    fig.update_layout(
        # 8 px in from the edge: at x = 0 the PNG's title touched its left border.
        title={"text": title, "font": {"size": 13}, "x": 0.0, "xanchor": "left", "pad": {"l": 8}},
        margin={"l": 55, "r": 40, "t": 45 if title else 10, "b": LEGEND_ROOM},
        modebar={"orientation": "v"},
        # At the chart's bottom in two columns, under the axis title whatever the plot's height: placed a share of
        # the plot below it, the legend sat on the axis title in the side panel, and five rows ate the plot.
        legend={"orientation": "h", "yref": "container", "yanchor": "bottom", "y": 0.0, "x": 0.0,
                "entrywidth": 0.5, "entrywidthmode": "fraction", "font": {"size": 10}},
        plot_bgcolor="white",
        showlegend=True,
    )
    if three:
        short = [short_label(t) for t in titles]  # the full ones: in the panel's caption and the hover
        # Few small ticks and a camera a little further out: in the side panel the default ones crowded and cut.
        scene: dict[str, object] = {k: {"nticks": 4, "tickfont": {"size": 9},
                                        "title": {"text": t, "font": {"size": 11}}}
                                    for k, t in zip(("xaxis", "yaxis", "zaxis"), short, strict=True)}
        # 10 % further out than first set: the first axis's title was cut at the right edge, under the mode bar.
        scene["camera"] = {"eye": {"x": 1.7, "y": 1.7, "z": 1.2}}
        fig.update_layout(scene=scene, margin={"l": 0, "r": 0, "b": LEGEND_ROOM})
    else:
        assert ranges is not None
        for axis, k in (("xaxis", 0), ("yaxis", 1)):
            rng = ranges[k]
            text = titles[k] if axis == "xaxis" else _two_lines(titles[k])
            fig.update_layout({axis: {"title": {"text": text, "standoff": 4}, "showgrid": True,
                                      "gridcolor": "#e5e5e5", "zeroline": False, "nticks": 7, "automargin": True,
                                      "ticklabeloverflow": KEEP_TICKS,
                                      **({"range": rng} if rng else {}), **_one_tick(coords[drawable, k])}})
    return fig


TRACE_RATIOS = {"feasible_ratio": "feasible", "feasible_ratio_P1": "feasible (main)",
                "feasible_ratio_P2": "feasible (auxiliary)", "feasible_ratio_P3": "feasible (second auxiliary)",
                "feasible_ratio_archive": "feasible (archive)", "feasible_ratio_A": "feasible (archive)",
                "feasible_ratio_P0": "feasible (P0, unconstrained)", "p1": "P(task 1)"}
"""Trace columns drawn as ratios, and their legend names; any other ``feasible_ratio_X`` is drawn as
"feasible (X)"."""


def _eps_note(trace: Sequence[Mapping[str, float]]) -> str:
    """What the chart says of epsilon: that the algorithm has none, or where the drawn line is missing."""
    if not any("eps" in row for row in trace):
        return "no epsilon in this algorithm"
    values = [row.get("eps", math.nan) for row in trace]
    where = [w for w, hit in (("0", any(v == 0 for v in values)), ("infinite", any(math.isinf(v) for v in values)),
                              ("not in use", any(math.isnan(v) for v in values))) if hit]
    return f"epsilon not drawn where {' or '.join(where)}" if where else ""


def wrapped(text: str, chars: int) -> list[str]:
    """``text``'s `` · ``-separated parts joined into lines of at most ``chars`` characters; a part longer than
    that (a run's "no feasible member: order_6 0.0448 > 0; or ..." status) is broken at its spaces first."""
    lines: list[str] = []
    for part in text.split(" · "):
        pieces = textwrap.wrap(part, chars, break_on_hyphens=False) if len(part) > chars else [part]
        for k, piece in enumerate(pieces):
            if k == 0 and lines and len(lines[-1]) + 3 + len(piece) <= chars:
                lines[-1] += " · " + piece
            else:
                lines.append(piece)
    return lines


def top_title(text: str, pad: int, **extra: Any) -> dict[str, Any]:
    """A title anchored in pixels from the container's top (``pad`` px down): plotly's default placement of a
    title of several lines put its first line above the chart's edge."""
    return {"text": text, "yref": "container", "y": 1.0, "yanchor": "top", "pad": {"t": pad}, **extra}


def compact_3d(fig: go.Figure) -> go.Figure:
    """A 3-D chart made for the side panel (~270 px), changed in place: axis titles without units (``f2``; the
    panel's caption names each) and no "best f1" texts (on hover still). The units' titles were cut at the edge
    ("f2 (mm", "(mm)") and the texts printed over each other ("be… f2"). A 2-D chart is returned unchanged."""
    if fig.layout.scene.xaxis.title.text is None:
        return fig
    for axis in ("xaxis", "yaxis", "zaxis"):
        title = fig.layout.scene[axis].title.text or ""
        fig.layout.scene[axis].title.text = title.split(" (")[0]
    for tr in fig.data:
        if isinstance(tr, go.Scatter3d) and tr.name == "best":
            tr.mode = "markers"
    return fig


def with_title_wrapped(fig: go.Figure, chars: int, copy: bool = True) -> go.Figure:
    """A copy of a chart (``copy=False``: the chart itself, changed) whose one-line title is broken into lines for
    a narrow panel (plotly cuts a title at the chart's edge), with the top margin grown to fit them. A copy costs
    about as much as building the chart (~10 ms at pop 200), the change in place ~1 ms."""
    title = fig.layout.title.text or ""
    lines = wrapped(title, chars)
    if len(lines) <= 1:
        return fig
    out = go.Figure(fig) if copy else fig
    # (The pad is measured to the first line's baseline region: 16 px keeps its glyphs inside the chart.)
    out.update_layout(title=top_title("<br>".join(lines), 16), margin={"t": 24 + 17 * len(lines)})
    return out


def make_trace_figure(trace: Sequence[Mapping[str, float]], title: str = "") -> go.Figure | None:
    """Feasible ratios (and task probabilities) over evaluations, and the epsilon level on a log axis
    when the algorithm has one; the title says where epsilon is not drawn (0 or NaN: not in use, as in CMOES's
    first stage) or that there is none. None for an empty trace."""
    if not trace:
        return None
    x = [row.get("n_eval", i) for i, row in enumerate(trace)]
    fig = go.Figure()
    keys = list(TRACE_RATIOS) + [k for k in dict.fromkeys(k for row in trace for k in row)
                                 if k.startswith("feasible_ratio_") and k not in TRACE_RATIOS]
    for key in keys:
        if any(key in row for row in trace):
            name = TRACE_RATIOS.get(key, f"feasible ({key.removeprefix('feasible_ratio_')})")
            fig.add_scatter(x=x, y=[row.get(key) for row in trace], mode="lines", name=name)
    # A log axis shows no 0 (nor NaN, nor the infinite violation of a member with undefined objectives).
    eps = [v if 0 < (v := row.get("eps", 0.0)) < math.inf else None for row in trace]
    margin_r = 10
    if any(v is not None for v in eps):
        fig.add_scatter(x=x, y=eps, mode="lines", name="epsilon", yaxis="y2", line={"dash": "dot"})
        # "1e-4" rather than a superscript power, which the narrow panel cut to a bare "4".
        # Whole decades (at most ~6 labels) where it spans one, else plotly's ticks.
        drawn = [v for v in eps if v is not None]
        decades = math.log10(max(drawn)) - math.log10(min(drawn))
        step = {"dtick": max(1, math.ceil(decades / 5)), "tick0": 0} if decades >= 1 else {}
        fig.update_layout(yaxis2={"title": {"text": "epsilon", "standoff": 2}, "type": "log", "overlaying": "y",
                                  "side": "right", "exponentformat": "e", "tickformat": ".0e", "automargin": True,
                                  "ticklabeloverflow": KEEP_TICKS,
                                  "showgrid": False, "tickfont": {"size": 10}, **step})
        margin_r = 50
    note = _eps_note(trace)
    # The note on a line of its own under the title: beside it, it ran under the mode bar's icons.
    small = f"<span style='font-size:10px;color:#666'>{note}</span>" if note else ""
    text = "<br>".join(t for t in (title, small) if t)
    fig.update_layout(title=top_title(text, 14, font={"size": 12}),
                      font={"size": 11}, height=250 + (14 if note else 0), showlegend=True,
                      margin={"l": 45, "r": margin_r, "t": 50 if note else 34,
                      "b": 10}, xaxis={"title": {"text": "evaluations", "standoff": 4}, "automargin": True,
                                       "ticklabeloverflow": KEEP_TICKS},
                      yaxis={"range": [0, 1.02], "title": {"text": "ratio"}, "automargin": True,
                             "ticklabeloverflow": KEEP_TICKS},
                      # Below the axis title, outside the plot, as the Pareto chart's (items wrap on a narrow panel).
                      legend={"orientation": "h", "yanchor": "top", "y": -0.3, "x": 0.0, "font": {"size": 10}})
    return fig
