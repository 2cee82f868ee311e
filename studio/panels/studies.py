"""Studies panel: the studies run with ``clm study`` under a folder, their box plots per case and metric, and
any run's picked design loaded into the editor (running studies stays a CLI job)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import plotly.graph_objects as go
import viser

from core.study.report import LABELS
from studio import palette
from studio.figures import KEEP_TICKS
from studio.panels._inputs import set_value
from studio.panels._lazy import LazyPlotly
from studio.panels.pareto import CONFIG
from studio.studies import StudyRun, find_studies, finished_runs, picked, same_target, study_rows, target_words

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

NONE = "(none)"
FIRST = ("mse", "S", "I", "h_s", "hv", "igd_plus", "feasible_ratio")  # offered first when a study has them


def metric_name(key: str) -> str:
    """A metric as the report names it (``time (s)``, ``IGD+``); a rehearsal read ``wall_time`` in the dropdown."""
    return LABELS.get(key, key)


def box_figure(runs: list[StudyRun], case: str, metric: str) -> go.Figure:
    """One box per algorithm: the metric over the case's seeds (the paper's Fig. 11 / 19 view)."""
    fig = go.Figure()
    # Named as the study file labels them ("NSGA-II"), as its report does; a rehearsal read "nsga2" here.
    algorithms = {r.algorithm: r.named for r in runs if r.case == case}
    for k, (a, named) in enumerate(algorithms.items()):
        ys = [r.metrics.get(metric) for r in runs if r.case == case and r.algorithm == a]
        ys = [y for y in ys if isinstance(y, int | float)]
        colour = palette.LEGS[k % len(palette.LEGS)]
        fig.add_trace(go.Box(y=ys, name=named, boxpoints="all", jitter=0.3, marker={"color": palette.css(colour)},
                             showlegend=False))
    label = LABELS.get(metric, metric)  # with its unit, as the study's report writes it
    fig.update_layout(title={"text": f"{case}: {label}", "font": {"size": 13}, "x": 0.0},
                      margin={"l": 50, "r": 10, "t": 40, "b": 40}, plot_bgcolor="white")
    fig.update_yaxes(showgrid=True, gridcolor="#e5e5e5", title_text=label, ticklabeloverflow=KEEP_TICKS)
    return fig


class StudiesPanel:
    """Folder, study, case and metric choices, a box plot, and runs to load into the editor."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._dirs: dict[str, Path] = {}
        self._runs: list[StudyRun] = []
        self._dir: Path | None = None
        self.folder = gui.add_folder("Studies", order=order, expand_by_default=False)
        with self.folder:
            self.path = gui.add_text("Folder", "runs", hint="where `clm study --out` wrote its studies (this folder "
                                                           "or one level below)")
            self.scan = gui.add_button("Find studies", icon=viser.Icon.SEARCH)
            self.study = gui.add_dropdown("Study", (NONE,), disabled=True)
            self.summary = gui.add_markdown("")
            self.case = gui.add_dropdown("Case", (NONE,), disabled=True)
            self.metric = gui.add_dropdown("Metric", tuple(metric_name(k) for k in FIRST),
                                           initial_value=metric_name("mse"))
            self._metric_key = {metric_name(k): k for k in FIRST}  # the dropdown's names -> the runs' keys
            self.run = gui.add_dropdown("Run", (NONE,), disabled=True, hint="a finished run: its picked design")
            self.load = gui.add_button("Load its design", icon=viser.Icon.ARROW_RIGHT, disabled=True,
                                       hint="the run's picked design goes into the editor (the study is not changed)")
        # The box plot: one per page, once the page has drawn (studio/panels/_lazy.py).
        self.plot = LazyPlotly(studio.server, self.folder, (self.metric.order + self.run.order) / 2, 0.8, CONFIG)
        self.scan.on_click(self._on_scan)
        self.study.on_update(lambda e: self._on_study(e.client))
        self.case.on_update(lambda _: self._draw())
        self.metric.on_update(lambda _: self._draw())
        self.load.on_click(self._on_load)

    def _on_scan(self, event: viser.GuiEvent[Any]) -> None:
        try:
            dirs = find_studies(Path(str(self.path.value)).expanduser())
        except (OSError, ValueError) as exc:
            if event.client is not None:
                self.studio.notify(event.client, "No studies", str(exc))
            return
        self._dirs = {d.name or str(d): d for d in dirs}
        options = tuple(self._dirs) or (NONE,)
        self.study.options = options
        self.study.disabled = not dirs
        if dirs:
            set_value(self.study, options[0])
            self._on_study(event.client)
        elif event.client is not None:
            where = str(self.path.value).strip() or "the current folder"
            self.studio.notify(event.client, "No studies", f"no study.sqlite in {where} or its folders",
                               color="yellow")

    def _on_study(self, client: viser.ClientHandle | None) -> None:
        d = self._dirs.get(str(self.study.value))
        if d is None:
            return
        try:
            name, rows = study_rows(d)
        except ValueError as exc:
            if client is not None:
                self.studio.notify(client, "Study not read", str(exc))
            return
        self._dir, self._runs = d, finished_runs(rows)
        failed = sum(r["status"] == "failed" for r in rows)
        report = d / "report.html"
        said = f"Report: `{report}`." if report.is_file() else f"No report yet: `clm study report {d}` writes one."
        # The first failure's message (rehearsal 6: an all-failed study said only "4 failed", not why).
        first = next((r for r in rows if r["status"] == "failed" and r.get("error")), None)
        why = f" First failure, {first['key']}: {str(first['error'])[:300]}." if first is not None else ""
        self.summary.content = f"**{name}**: {len(self._runs)} runs done, {failed} failed.{why} {said}"
        keys = list(dict.fromkeys(k for r in self._runs for k in r.metrics))
        metrics = tuple(k for k in FIRST if k in keys) + tuple(k for k in keys if k not in FIRST)
        self._metric_key = {metric_name(k): k for k in metrics or FIRST}
        self.metric.options = tuple(self._metric_key)
        set_value(self.metric, next(iter(self._metric_key)))
        cases = tuple(dict.fromkeys(r.case for r in self._runs)) or (NONE,)
        self.case.options = cases
        self.case.disabled = not self._runs
        set_value(self.case, cases[0])
        labels = tuple(r.label for r in self._runs) or (NONE,)
        self.run.options = labels
        self.run.disabled = self.load.disabled = not self._runs
        self._draw()

    def _draw(self) -> None:
        case = str(self.case.value)
        metric = self._metric_key.get(str(self.metric.value), str(self.metric.value))
        if not self._runs or case == NONE:
            self.plot.visible = False
            return
        self.plot.figure = box_figure(self._runs, case, metric)
        self.plot.visible = True

    def _on_load(self, event: viser.GuiEvent[Any]) -> None:
        run = next((r for r in self._runs if r.label == self.run.value), None)
        if run is None or self._dir is None:
            return
        try:
            design, ran = picked(self._dir, run)
            with self.studio.session.lock:
                self.studio.session.set_design(design, by_hand=True, cause="study design")
                current = self.studio.session.view.target
        except ValueError as exc:
            if event.client is not None:
                self.studio.notify(event.client, "Design not loaded", str(exc))
            return
        self.studio.refresh()
        if event.client is None:
            return
        # The editor changes quietly otherwise: say whose design it now shows. Measured against another target
        # than its study's, its MSE in the Metrics panel contradicted the run's in the label (50.67 against 5.04).
        text = f"{run.label} (study in {self._dir.name}) is the editor's design now; Undo takes it back"
        if ran is not None and not same_target(ran, current.option()):
            self.studio.notify(event.client, "Design loaded: its study ran against another target",
                               f"{text}. The study optimized it against the {target_words(ran)}; the Metrics "
                               f"panel measures it against the editor's target, {current.label()}, so its MSE "
                               "there differs from the study's. Set that target to compare.", color="yellow")
        else:
            self.studio.notify(event.client, "Design loaded", text, color="green")
