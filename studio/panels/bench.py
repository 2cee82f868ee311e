"""Bench-trajectory chart: the leg-frame foot path against the target, with axes in mm (inline SVG)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from studio.bench_svg import bench_svg
from studio.state import DesignView

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class BenchPanel:
    """The bench trajectory drawn on the server as SVG, redrawn when the design or target changes."""

    def __init__(self, studio: Studio, order: float) -> None:
        gui = studio.server.gui
        view = studio.session.view
        self.folder = gui.add_folder("Bench trajectory (leg frame)", order=order)
        with self.folder:
            self.plot = gui.add_html(self._svg(view))

    @staticmethod
    def _svg(view: DesignView, show_target: bool = True) -> str:
        return bench_svg(view.solution.leg[0], view.target_leg if show_target else None, stance=view.stance,
                         features=dict(view.features))

    def show(self, view: DesignView, show_target: bool = True) -> None:
        """Redraw the chart; the target only when a stage of the mechanism optimizes it."""
        svg = self._svg(view, show_target)
        if svg != self.plot.content:
            self.plot.content = svg
