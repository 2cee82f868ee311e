"""Bench-trajectory chart: the leg-frame foot path against the target, with axes in mm."""

from __future__ import annotations

from typing import TYPE_CHECKING

import plotly.graph_objects as go

from studio.figures import make_bench_figure
from studio.state import DesignView

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class BenchPanel:
    """A plotly chart of the bench trajectory, redrawn when the design or target changes."""

    def __init__(self, studio: Studio, order: float) -> None:
        gui = studio.server.gui
        view = studio.session.view
        self.folder = gui.add_folder("Bench trajectory (leg frame)", order=order)
        with self.folder:
            # viser 1.1.1 draws the chart ``width * aspect`` tall (height / width, despite its docstring).
            self.plot = gui.add_plotly(self._figure(view), aspect=0.62, config={"displayModeBar": False})

    @staticmethod
    def _figure(view: DesignView, show_target: bool = True) -> go.Figure:
        return make_bench_figure(view.solution.leg[0], view.target_leg if show_target else None, stance=view.stance,
                                 features=dict(view.features))

    def show(self, view: DesignView, show_target: bool = True) -> None:
        """Redraw the chart; the target only when a stage of the mechanism optimizes it."""
        self.plot.figure = self._figure(view, show_target)
