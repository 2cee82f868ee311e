"""Pareto panel: the shown stage's population in objective space, redrawn every generation (throttled).

Feasible, infeasible and front members are told apart, knee candidates and the best member per
objective are labelled, the picked member is ringed; axis titles carry units (the problem's
labels). The chart's camera button saves it as PNG (plotly.js in the browser: offline).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

import plotly.graph_objects as go

from studio.figures import make_pareto_figure, make_trace_figure
from studio.study import status_text
from studio.study_view import StudyView

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

# The chart's mode bar: "download as PNG" (rendered by plotly.js in the browser), zoom, pan, reset;
# nothing that talks to a network service.
CONFIG = {
    "displaylogo": False,
    "displayModeBar": True,
    "showSendToCloud": False,
    "modeBarButtonsToRemove": ["sendDataToCloud", "select2d", "lasso2d", "autoScale2d", "toggleSpikelines",
                               "hoverClosestCartesian", "hoverCompareCartesian", "zoomIn2d", "zoomOut2d"],
    "toImageButtonOptions": {"format": "png", "filename": "pareto", "scale": 2},
}
# While a stage runs the chart is redrawn at most this often (s): 2-D and 3-D (WebGL, heavier).
REDRAW_2D, REDRAW_3D = 0.5, 1.0


def pareto_figure(sv: StudyView) -> go.Figure | None:
    """The chart of the shown stage, or None if it has no result yet."""
    r = sv.result(sv.viewing)
    if r is None or sv.viewing is None:
        return None
    spec = sv.specs.get(sv.viewing)
    labels = dict(spec.problem.labels) if spec is not None else {}
    running = sv.status.running and sv.status.stage == sv.viewing
    state = f"generation {r.generation}/{r.n_gen}" if running else status_text(r)
    title = (f"{sv.viewing} · {state} · {int(r.feasible.sum())} feasible of {r.pop} · "
             f"front {len(set(r.front))}")
    return make_pareto_figure(r.F, r.cv, objectives=r.objectives, labels=labels, front=r.front,
                              knees=r.shortlist.knees, best=r.shortlist.best, shown=sv.shown, passed=r.picked,
                              title=title)


class ParetoPanel:
    """A plotly chart of the shown stage, and a caption."""

    def __init__(self, studio: Studio, order: float) -> None:
        gui = studio.server.gui
        self._key: object = None
        self._drawn_at = 0.0
        self.folder = gui.add_folder("Pareto front", order=order)
        with self.folder:
            self.caption = gui.add_markdown("No stage has run yet.")
            # viser 1.1.1 draws the chart ``width * aspect`` tall.
            self.plot = gui.add_plotly(go.Figure(), aspect=0.85, config=CONFIG, visible=False)
            # The algorithm's own log: feasible ratios (and epsilon, task odds) over evaluations.
            self.trace = gui.add_plotly(go.Figure(), aspect=0.5, config=CONFIG, visible=False)

    def show(self, sv: StudyView) -> None:
        r = sv.result(sv.viewing)
        key = (id(r), sv.shown, sv.viewing, None if r is None else r.picked)
        if key == self._key:
            return
        if r is not None and sv.status.running and sv.status.stage == sv.viewing:
            period = REDRAW_3D if len(r.objectives) >= 3 else REDRAW_2D
            if time.monotonic() - self._drawn_at < period:
                return  # a later generation (or the end of the run) redraws it
        self._key = key
        self._drawn_at = time.monotonic()
        fig = pareto_figure(sv)
        if fig is None:
            self.plot.visible = False
            self.caption.content = ("No stage has run yet." if not sv.names else
                                    f"{sv.viewing or 'This stage'} has no result yet: run it.")
            return
        self.plot.figure = fig
        self.plot.visible = True
        tfig = None if r is None else make_trace_figure(r.trace, f"{algorithm_name(r.settings)} trace")
        if tfig is not None:
            self.trace.figure = tfig
        self.trace.visible = tfig is not None
        n = len(r.objectives) if r is not None else 0
        what = ("objective against violation" if n == 1 else "2-D" if n == 2 else
                "3-D (first three objectives)" if n >= 3 else "")
        self.caption.content = f"**{sv.viewing}** ({what}). Camera icon: save as PNG."


def algorithm_name(settings: object) -> str:
    """The algorithm's name in a stage result's settings, or "" (a loaded session's settings are free-form)."""
    algorithm = settings.get("algorithm") if isinstance(settings, Mapping) else None
    name = algorithm.get("name") if isinstance(algorithm, Mapping) else None
    return name if isinstance(name, str) else ""
