"""Pure plotly figure builders: arrays in, ``go.Figure`` out; no server, no state.

Tests call them directly; the panels hand the result to ``GuiPlotlyHandle.figure``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from studio import palette

F64 = NDArray[np.float64]


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


def objective_label(name: str, labels: Mapping[str, str]) -> str:
    """Axis title of an objective: its problem label with unit (``f1 = MSE (mm)``), else its name."""
    return labels.get(name, name)


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

    def add(name: str, idx: NDArray[np.intp] | list[int], marker: dict[str, object], text: list[str] | None = None,
            show_in_legend: bool = True) -> None:
        idx = np.asarray(idx, dtype=np.intp)
        idx = idx[np.asarray(drawable)[idx]] if len(idx) else idx
        hover = [f"member #{i}" + ("" if feasible[i] else f", violation {cv[i]:.3g}") for i in idx]
        common: dict[str, object] = {"name": name, "customdata": idx.tolist(), "hovertext": hover,
                                     "showlegend": show_in_legend, "marker": marker}
        if text is not None:
            common.update(text=text, mode="markers+text", textposition="top center")
        else:
            common["mode"] = "markers"
        pts = coords[idx]
        if three:
            fig.add_trace(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], **common))
        else:  # markers and labels at the edge are drawn whole, not cut by the plot area
            fig.add_trace(go.Scatter(x=pts[:, 0], y=pts[:, 1], cliponaxis=False, **common))

    size = 4 if three else 7
    add("infeasible", np.flatnonzero(drawable & ~feasible),
        {"color": palette.css(palette.INFEASIBLE, 0.6), "size": size, "symbol": "x"})
    add("dominated", np.flatnonzero(feasible & ~on_front), {"color": palette.css(palette.FEASIBLE, 0.8), "size": size})
    add("Pareto front", np.flatnonzero(on_front), {"color": palette.css(palette.PATH), "size": size + 2,
                                                   "line": {"color": "white", "width": 0.5}})
    if knees:
        add("knee candidates", list(knees), {"color": palette.css(palette.KNEE), "size": size + 5,
                                             "symbol": "diamond", "line": {"color": "black", "width": 1}},
            text=[f"K{j + 1}" for j in range(len(knees))])
    extra = [b for b in dict.fromkeys(best) if b not in knees]
    if extra:
        names = [f"best {objectives[best.index(b)]}" for b in extra]
        add("best per objective", extra, {"color": palette.css(palette.BEST), "size": size + 4, "symbol": "square",
                                          "line": {"color": "black", "width": 1}}, text=names)
    if passed is not None and passed != shown and 0 <= passed < len(F):
        add("passed on", [passed], {"color": "rgba(0,0,0,0)", "size": size + 12,
                                    "line": {"color": palette.css(palette.PASSED), "width": 3}})
    if shown is not None and 0 <= shown < len(F):
        add("picked", [shown], {"color": "rgba(0,0,0,0)", "size": size + 14,
                                "line": {"color": palette.css(palette.FOOT), "width": 3}})
    fig.update_layout(
        title={"text": title, "font": {"size": 13}, "x": 0.0, "xanchor": "left"},
        margin={"l": 55, "r": 40, "t": 45 if title else 10, "b": 10},
        modebar={"orientation": "v"},
        # Below the axis title, outside the plot (legend items wrap on a narrow panel).
        legend={"orientation": "h", "yanchor": "top", "y": -0.22, "x": 0.0, "font": {"size": 10}},
        plot_bgcolor="white",
        showlegend=True,
    )
    if three:
        fig.update_layout(scene={"xaxis": {"title": {"text": titles[0]}}, "yaxis": {"title": {"text": titles[1]}},
                                 "zaxis": {"title": {"text": titles[2]}}}, margin={"l": 0, "r": 0, "b": 0})
    else:
        for axis, k in (("xaxis", 0), ("yaxis", 1)):
            rng = _axis_range(coords[:, k], coords[feasible, k])
            fig.update_layout({axis: {"title": {"text": titles[k], "standoff": 4}, "showgrid": True,
                                      "gridcolor": "#e5e5e5", "zeroline": False, "nticks": 7, "automargin": True,
                                      **({"range": rng} if rng else {})}})
    return fig


TRACE_RATIOS = {"feasible_ratio": "feasible", "feasible_ratio_P1": "feasible (main)",
                "feasible_ratio_P2": "feasible (auxiliary)", "feasible_ratio_archive": "feasible (archive)",
                "p1": "P(task 1)"}


def make_trace_figure(trace: Sequence[Mapping[str, float]], title: str = "") -> go.Figure | None:
    """Feasible ratios (and task probabilities) over evaluations, and the epsilon level on a log axis
    when the algorithm has one (where it is 0 it is not drawn, and a note says so); None for an empty trace."""
    if not trace:
        return None
    x = [row.get("n_eval", i) for i, row in enumerate(trace)]
    fig = go.Figure()
    for key, name in TRACE_RATIOS.items():
        if any(key in row for row in trace):
            fig.add_scatter(x=x, y=[row.get(key) for row in trace], mode="lines", name=name)
    eps = [row["eps"] if row.get("eps", 0.0) > 0 else None for row in trace]  # a log axis shows no 0
    if any(v is not None for v in eps):
        fig.add_scatter(x=x, y=eps, mode="lines", name="epsilon", yaxis="y2", line={"dash": "dot"})
        fig.update_layout(yaxis2={"title": {"text": "epsilon"}, "type": "log", "overlaying": "y", "side": "right",
                                  "exponentformat": "power", "automargin": True, "showgrid": False})
    if any("eps" in row for row in trace) and any(v is None for v in eps):
        fig.add_annotation(text="epsilon 0 where not drawn", xref="paper", yref="paper", x=1.0, y=1.0,
                           xanchor="right", yanchor="bottom", showarrow=False, font={"size": 10, "color": "#666"})
    fig.update_layout(title={"text": title, "font": {"size": 12}}, font={"size": 11}, height=250,
                      margin={"l": 45, "r": 10, "t": 30,
                      "b": 10}, xaxis={"title": {"text": "evaluations", "standoff": 4}, "automargin": True},
                      yaxis={"range": [0, 1.02], "title": {"text": "ratio"}, "automargin": True},
                      # Below the axis title, outside the plot, as the Pareto chart's (items wrap on a narrow panel).
                      legend={"orientation": "h", "yanchor": "top", "y": -0.3, "x": 0.0, "font": {"size": 10}})
    return fig
