"""Metrics panel: the live table of the current design (rows from ``studio.metrics``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from core.optimize.rtclm import is_rtclm
from studio.metrics import metrics_html
from studio.state import DesignView, same_leg
from studio.study_view import StudyView
from studio.tables import verdict_html

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class MetricsPanel:
    """An HTML table, one row per metric; hover a row for its definition or the reason it fails."""

    def __init__(self, studio: Studio, order: float) -> None:
        gui = studio.server.gui
        self.folder = gui.add_folder("Metrics", order=order)
        with self.folder:
            self.stage = gui.add_html("")
            self.table = gui.add_html("")
        self.show(studio.session.view)

    def show(self, view: DesignView) -> None:
        self.table.content = metrics_html(view.rows)

    def show_stage(self, sv: StudyView, view: DesignView) -> None:
        """Above the table: whether the design in the editor, if it is the shown member of the stage in view,
        meets that stage's constraints ("Assembles and walks" below is about assembly and gait only)."""
        r, i = sv.result(sv.viewing), sv.shown
        same = (r is not None and i is not None and 0 <= i < r.pop and same_leg(view.design.mechanism, r.mechanism)
                and np.allclose(view.design.params[0], r.X[i], rtol=0.0, atol=1e-9))
        ran = sv.run_target
        rtclm = is_rtclm(view.design.mechanism.name)
        other = view.target.changed_from(ran, rtclm) if ran is not None else ""  # a target changed since the run
        content = verdict_html(r, i, sv.viewing or "", other) if same and r is not None and i is not None else ""
        if self.stage.content != content:
            self.stage.content = content
