"""Pure plotly figure builders: arrays in, ``go.Figure`` out; no server, no state.

Tests call them directly; the panels hand the result to ``GuiPlotlyHandle.figure``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from studio import palette

F64 = NDArray[np.float64]


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


def make_bench_figure(
    leg: F64,
    target_leg: F64 | None = None,
    *,
    stance: NDArray[np.bool_] | None = None,
    features: Mapping[str, tuple[float, float]] | None = None,
    foot: tuple[float, float] | None = None,
) -> go.Figure:
    """The bench trajectory in the leg frame, with the target overlaid.

    Args:
        leg: ``(n_samples, 2)`` foot path in the leg frame (mm); NaN samples leave gaps.
        target_leg: ``(n_target, 2)`` target in the leg frame (mm), or None.
        stance: ``(n_samples,)`` True on the stance half-cycle; stance and swing are then drawn
            in two colours (None: the whole path in one colour).
        features: feature points by label (``{"t1": (x, y), ...}``, mm), drawn as labelled markers.
        foot: current foot position (mm), drawn as a marker.

    Returns:
        A figure with equal axis scales and axis titles in mm.
    """
    leg = np.asarray(leg, dtype=np.float64)
    fig = go.Figure()
    if target_leg is not None:
        t = _closed(np.asarray(target_leg, dtype=np.float64))
        fig.add_trace(go.Scatter(x=t[:, 0], y=t[:, 1], mode="lines", name="target",
                                 line={"color": palette.css(palette.TARGET), "width": 2, "dash": "dash"}))
    if stance is None:
        p = _closed(leg)
        fig.add_trace(go.Scatter(x=p[:, 0], y=p[:, 1], mode="lines", name="bench trajectory",
                                 line={"color": palette.css(palette.PATH), "width": 2.5}))
    else:
        stance = np.asarray(stance, dtype=bool)
        for name, mask, colour in (("stance", stance, palette.STANCE), ("swing", ~stance, palette.SWING)):
            xs: list[float | None] = []
            ys: list[float | None] = []
            for s, e in _runs(mask):
                arc = _arc(leg, s, e)
                xs += [*arc[:, 0], None]
                ys += [*arc[:, 1], None]
            fig.add_trace(go.Scatter(x=xs, y=ys, mode="lines", name=name,
                                     line={"color": palette.css(colour), "width": 2.5}))
    if features:
        labels = list(features)
        fx = [features[k][0] for k in labels]
        fy = [features[k][1] for k in labels]
        fig.add_trace(go.Scatter(x=fx, y=fy, mode="markers+text", name="feature points", text=labels,
                                 textposition="top center", marker={"color": "black", "size": 7}))
    if foot is not None:
        fig.add_trace(go.Scatter(x=[foot[0]], y=[foot[1]], mode="markers", name="foot",
                                 marker={"color": palette.css(palette.FOOT), "size": 10}))
    fig.update_layout(
        margin={"l": 50, "r": 10, "t": 10, "b": 40},
        legend={"orientation": "h", "yanchor": "bottom", "y": 1.0, "x": 0.0},
        plot_bgcolor="white",
        showlegend=True,
    )
    fig.update_xaxes(title_text="x, leg frame (mm)", showgrid=True, gridcolor="#e5e5e5", zeroline=False,
                     constrain="domain")
    # Equal scales, fitted by shrinking the plot area rather than padding the y range.
    fig.update_yaxes(title_text="y (mm)", showgrid=True, gridcolor="#e5e5e5", zeroline=False,
                     scaleanchor="x", scaleratio=1, constrain="domain")
    return fig
