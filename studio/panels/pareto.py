"""Pareto panel: the shown stage's population in objective space, redrawn every generation (throttled).

Feasible, infeasible and front members are told apart, knee candidates and the best member per
objective are labelled, the picked member is ringed; axis titles carry units (the problem's
labels). The chart's camera button saves it as PNG (plotly.js in the browser: offline).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
import plotly.graph_objects as go
import viser

from studio.charts import chart_title, target_text
from studio.figures import (
    compact_3d,
    flat_axes,
    make_pareto_figure,
    make_trace_figure,
    objective_label,
    same_for_all,
    with_title_wrapped,
)
from studio.panels._inputs import set_value
from studio.panels._lazy import LazyPlotly, write
from studio.study import algorithm_name, population_note, status_text
from studio.study_view import StudyView
from studio.target import curve_path

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

# The chart's mode bar: "download as PNG" (rendered by plotly.js in the browser), zoom, pan, reset;
# nothing that talks to a network service. Shown while the pointer is on the chart: always shown, it covered the
# end of the title's lines in the 279 px chart of a 1280 px window (QA session 38).
CONFIG = {
    "displaylogo": False,
    "displayModeBar": "hover",
    "showSendToCloud": False,
    "modeBarButtonsToRemove": ["sendDataToCloud", "select2d", "lasso2d", "autoScale2d", "toggleSpikelines",
                               "hoverClosestCartesian", "hoverCompareCartesian", "zoomIn2d", "zoomOut2d"],
    "toImageButtonOptions": {"format": "png", "filename": "pareto", "scale": 2},
}
# While a stage runs the chart is redrawn at most this often (s): 2-D and 3-D (WebGL, heavier).
REDRAW_2D, REDRAW_3D = 0.5, 1.0
ASPECT_2D, ASPECT_3D = 1.15, 1.55  # the side panel's chart: height over width (a three-line title, the legend)
# The large chart's window: the chart's height over width, and the window's padding and the tab bar and Close
# button above the chart (px).
LARGE_ASPECT, LARGE_PAD, LARGE_CHROME = 0.72, 32, 120
PANEL_TITLE_CHARS = 42  # a title line the side panel's chart shows whole (13 px type, the mode bar beside it)
PX_PER_TITLE_CHAR = 10.0  # the large chart's title: characters per line = its window's width / this


def pareto_figure(sv: StudyView, axes: tuple[int, int] | None = None) -> go.Figure | None:
    """The chart of the shown stage (projected onto two objectives with ``axes``), or None if it has no result
    yet. The title names the mechanism, the stage, its state and the target (a saved chart reads on its own)."""
    r = sv.result(sv.viewing)
    if r is None or sv.viewing is None:
        return None
    spec = sv.specs.get(sv.viewing)
    labels = dict(spec.problem.labels) if spec is not None else {}
    running = sv.status.running and sv.status.stage == sv.viewing
    state = f"generation {r.generation}/{r.n_gen}" if running else status_text(r)
    t = sv.run_target  # its upload's name, by its path (computed: drawing a chart writes nothing)
    target = target_text(r.settings, {str(curve_path(t.curve)): f"curve {t.curve.name}"}
                         if t is not None and t.curve is not None else None)
    title = chart_title(r, state, target)
    return make_pareto_figure(r.F, r.cv, objectives=r.objectives, labels=labels, front=r.front,
                              knees=r.shortlist.knees, best=r.shortlist.best, shown=sv.shown,
                              passed=passed_on(sv), title=title, axes=axes if len(r.objectives) >= 3 else None)


def large_size(client: viser.ClientHandle) -> dict[str, float]:
    """The large chart's window: 960 x 760 px, or less on a canvas too small for it (a 1024 x 768 screen's is
    636 px wide beside the side panel): a fixed size covered the side panel, Stop included, and ran off the
    screen's bottom edge. The page reports its canvas in device pixels, so on a high-DPI screen the window can
    still be too large (it can be resized and moved)."""
    try:
        w, h = client.camera.image_width, client.camera.image_height
    except (AssertionError, AttributeError):  # no camera report from this client yet
        w, h = 1200, 900
    tall = min(760, max(400, h - 48))
    # No wider than a chart the window's height holds whole (its legend was cut at 1280 x 720 and even 1920 x 1080:
    # a 960 px chart is 668 px high, under 120 px of tab and Close button).
    width = float(min(960, max(480, w - 48), max(480, int((tall - LARGE_CHROME) / LARGE_ASPECT + LARGE_PAD))))
    # No taller than its chart (LARGE_ASPECT of the window's inner width) and the tab and Close button above it:
    # a 480 px window on a 900 x 700 page had a 200 px empty band under the chart.
    fit = round(LARGE_ASPECT * (width - LARGE_PAD)) + LARGE_CHROME
    return {"width": width, "height": float(min(tall, fit))}


def trace_aspect(lines: int) -> float:
    """The trace chart's height over width: 0.8 for up to two lines, 0.07 more per line beyond (in the side panel a
    long legend name takes a row of its own; CMOEMT's lines and epsilon shrank its plot to ~100 px)."""
    return 0.8 + 0.07 * max(0, lines - 2)


def large_figure(fig: go.Figure, chars: int) -> go.Figure:
    """The large window's copy of the chart: its title broken into lines of ``chars`` characters (the legend sits at
    the chart's bottom, under the axis title, in a window of any width)."""
    return with_title_wrapped(fig, chars)


def passed_on(sv: StudyView) -> int | None:
    """The member of the stage in view that was passed on: the next stage ran from it, or the designer chose
    "Use for next stage" (not merely the stage's automatic pick)."""
    r = sv.result(sv.viewing)
    if r is None or r.picked is None or sv.viewing not in sv.names:
        return None
    k = sv.names.index(sv.viewing)
    if k + 1 >= len(sv.names):
        return None
    nxt = sv.results[k + 1]
    ran_from_it = nxt is not None and nxt.parent_pick == r.picked
    chosen = sv.from_pick and sv.next_stage == sv.names[k + 1]
    return r.picked if ran_from_it or chosen else None


THREE_D = "3-D (all three)"


def projections(objectives: tuple[str, ...]) -> dict[str, tuple[int, int] | None]:
    """The View options of a chart with three or more objectives: the 3-D cloud and each pair of the first three."""
    names = objectives[:3]
    out: dict[str, tuple[int, int] | None] = {THREE_D: None}
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            out[f"{names[a]} vs {names[b]}"] = (a, b)
    return out


def flat_view(F: np.ndarray, objectives: tuple[str, ...]) -> str | None:
    """The projection to open on when one of the first three objectives is the same for every drawn member (subtask
    1's f2 = f3 = 0: placement meets them exactly), and which: the 3-D cloud was one diamond in an empty box. None
    when all three vary (or nothing is drawn)."""
    axes = flat_axes(F, objectives)
    return None if axes is None else f"{objectives[axes[0]]} vs {objectives[axes[1]]}"


class ParetoPanel:
    """A plotly chart of the shown stage, a View choice (3-D or a projection) for three objectives, a large
    floating copy of the chart, the algorithm's trace, and a caption."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._key: object = None
        self._flat_for: tuple[object, ...] = ()  # the run the View last opened on a projection for (flat_view)
        self._drawn_at = 0.0
        self._sv: StudyView | None = None
        # per page that opened it: its window, chart, and title line length
        self._large: dict[int, tuple[viser.PanelHandle, viser.GuiPlotlyHandle, int]] = {}
        self.folder = gui.add_folder("Pareto front", order=order)
        with self.folder:
            self.caption = gui.add_markdown("No stage has run yet.")
            self.view = gui.add_dropdown("View", (THREE_D,), visible=False,
                                         hint="three objectives: the 3-D cloud, or its projection onto two of them")
            self.open_large = gui.add_button("Open large chart", icon=viser.Icon.ARROWS_MAXIMIZE, visible=False,
                                             hint="the chart in a large window you can move (Close in it)")
        # Created on first use (plotly.js is sent with the first chart): between View and the button, and the
        # algorithm's own log (feasible ratios, epsilon, task odds over evaluations) after it. viser 1.1.1
        # draws a chart ``width * aspect`` tall.
        self.plot = LazyPlotly(studio.server, self.folder, (self.view.order + self.open_large.order) / 2, ASPECT_2D,
                               CONFIG)
        # 0.8: room for the plot, its axis titles and a legend of up to five lines (figures.make_trace_figure)
        self.trace = LazyPlotly(studio.server, self.folder, self.open_large.order + 0.5, 0.8, CONFIG)
        self.view.on_update(lambda _: self._redraw())
        self.open_large.on_click(lambda e: self._open_large(e.client))
        studio.server.on_client_disconnect(self._forget)

    def axes(self) -> tuple[int, int] | None:
        sv = self._sv
        r = None if sv is None else sv.result(sv.viewing)
        if r is None or len(r.objectives) < 3:
            return None
        return projections(r.objectives).get(str(self.view.value))

    def show(self, sv: StudyView) -> None:
        r = sv.result(sv.viewing)
        # The passed-on member too: "Use for next stage" on the shown pick changes only the ring.
        key = (id(r), sv.shown, sv.viewing, None if r is None else r.picked, passed_on(sv))
        if key == self._key:
            return
        if r is not None and sv.status.running and sv.status.stage == sv.viewing:
            period = REDRAW_3D if len(r.objectives) >= 3 and self.axes() is None else REDRAW_2D
            if time.monotonic() - self._drawn_at < period:
                return  # a later generation (or the end of the run) redraws it
        self._key = key
        self._sv = sv
        self._draw(sv)

    def _redraw(self) -> None:
        if self._sv is not None:
            self._draw(self._sv)

    def _draw(self, sv: StudyView) -> None:
        self._drawn_at = time.monotonic()
        r = sv.result(sv.viewing)
        n = len(r.objectives) if r is not None else 0
        options = tuple(projections(r.objectives)) if r is not None and n >= 3 else (THREE_D,)
        if tuple(self.view.options) != options:
            self.view.options = options
        self.view.visible = n >= 3
        flat = None if r is None or n < 3 else flat_view(r.F, r.objectives)
        run = (sv.viewing, id(sv.specs.get(sv.viewing or "")))  # a run's spec: the same through its generations
        if flat is not None and run != self._flat_for and self.axes() is None:
            self._flat_for = run  # once per run: the designer may still choose the 3-D cloud
            set_value(self.view, flat)
        fig = pareto_figure(sv, self.axes())
        if fig is None:
            # The trace goes with its chart: a previous stage's or topology's would sit under "no result".
            self.plot.visible = self.open_large.visible = self.trace.visible = False
            self.caption.content = ("No stage has run yet." if not sv.names else
                                    f"{sv.viewing or 'This stage'} has no result yet: run it.")
            self._close_large()
            return
        for cid, (_, large, chars) in list(self._large.items()):  # a one-line title if it fits (sent now, as JSON)
            if not write(large, "figure", large_figure(fig, chars)):
                self._large.pop(cid, None)
        # Then the side panel's lines, in place: a copy per redraw cost as much as building the chart.
        self.plot.figure = compact_3d(with_title_wrapped(fig, PANEL_TITLE_CHARS, copy=False))
        # A 3-D cloud in a 2-D chart's height left its axes cut (its title and legend take their own lines).
        self.plot.aspect = ASPECT_3D if n >= 3 and self.axes() is None else ASPECT_2D
        self.plot.visible = self.open_large.visible = True
        tfig = None if r is None else make_trace_figure(r.trace, f"{algorithm_name(r.settings)} trace")
        if tfig is not None:
            self.trace.figure = tfig
            self.trace.aspect = trace_aspect(len(tfig.data))
        self.trace.visible = tfig is not None
        what = ("objective against violation" if n == 1 else "2-D" if n == 2 else
                ("3-D" if self.axes() is None else str(self.view.value)) if n >= 3 else "")
        if n >= 3 and self.axes() is None and r is not None:  # the 3-D axes carry short titles: say what they are
            spec = sv.specs.get(sv.viewing) if sv.viewing is not None else None
            labels = dict(spec.problem.labels) if spec is not None else {}
            what += ": " + " · ".join(objective_label(o, labels) for o in r.objectives[:3])
        if n >= 3 and r is not None and (same := same_for_all(r.F, r.objectives)):
            what += f"; {same}"
        if r is not None and (note := population_note(r)):
            what += f"; {note}"
        # viser sends no plotly clicks: a presenter clicked a point and nothing happened (QA, session 37).
        self.caption.content = (f"**{sv.viewing}** ({what}). Hover names a member; to pick a candidate, click its "
                                f"sphere in the scene's Candidates view; any member: Pick below. Camera icon: save "
                                f"as PNG.")

    def charts(self) -> tuple[LazyPlotly, ...]:
        return self.plot, self.trace

    def _open_large(self, client: viser.ClientHandle | None) -> None:
        """A large copy of the chart, floating in the page whose button was pressed (only there)."""
        if client is None or client.client_id in self._large or self._sv is None:
            return
        panel = client.gui.add_panel()
        size = large_size(client)
        # Floated before it holds the chart: floated after, the page drew the chart docked, then again in its window,
        # and plotly's pending margin redraw of the first one threw on its purged node (an uncaught TypeError).
        panel.float(x=-24, y=24, **size)  # right edge by the side panel: never over it
        # A window narrower than the one-line title breaks it into lines, as the side panel does (at 1100 x 760
        # under software rendering the window is ~480 px: the title was cut at "target cyc").
        chars = max(PANEL_TITLE_CHARS, int(size["width"] / PX_PER_TITLE_CHAR))
        with panel.add_tab("Pareto front (large)", viser.Icon.CHART_DOTS):
            # Close first: under the chart it fell past the window's bottom edge on a 1000-pixel-high page.
            close = client.gui.add_button("Close", icon=viser.Icon.X)
            fig = pareto_figure(self._sv, self.axes())
            plot = client.gui.add_plotly(go.Figure() if fig is None else large_figure(fig, chars),
                                         aspect=LARGE_ASPECT, config=CONFIG)
        close.on_click(lambda _: self._close_large(client.client_id))
        self._large[client.client_id] = (panel, plot, chars)

    def _forget(self, client: viser.ClientHandle) -> None:
        self._large.pop(client.client_id, None)

    def _close_large(self, client_id: int | None = None) -> None:
        """Close the large chart of one page, or of every page."""
        for cid in [client_id] if client_id is not None else list(self._large):
            large = self._large.pop(cid, None)
            if large is not None:
                large[0].remove()

