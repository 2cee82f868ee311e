"""Metrics panel: the live table of the current design (rows from ``studio.metrics``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from studio.metrics import metrics_html
from studio.state import DesignView

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class MetricsPanel:
    """An HTML table, one row per metric; hover a row for its definition or the reason it fails."""

    def __init__(self, studio: Studio, order: float) -> None:
        gui = studio.server.gui
        self.folder = gui.add_folder("Metrics", order=order)
        with self.folder:
            self.table = gui.add_html("")
        self.show(studio.session.view)

    def show(self, view: DesignView) -> None:
        self.table.content = metrics_html(view.rows)
