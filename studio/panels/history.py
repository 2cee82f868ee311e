"""History panel: the lineage X0 -> X1 -> X2 -> X3 (or the RTCLM stages) with each stage's status,
front size, pick and its objective values; show any stage again, and restore a kept branch.

Revisiting a stage shows its front in the Pareto and Pick panels; picking another member there
and passing it on keeps the current pipeline as a branch first (``studio.study``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import viser

from studio.candidates import history_rows
from studio.panels._confirm import confirm
from studio.panels._inputs import set_value
from studio.study import status_text
from studio.study_view import StudyView
from studio.tables import history_html

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

NO_BRANCH = "(no branches)"


class HistoryPanel:
    """Lineage table, "Show stage" dropdown, branch dropdown, "Restore branch" and "Delete branch"."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._key: object = None
        self.folder = gui.add_folder("History", order=order)
        with self.folder:
            self.table = gui.add_html(history_html([]))
            self.show_stage = gui.add_dropdown("Show stage", ("-",), disabled=True,
                                               hint="show this stage's front and candidates again")
            self.branch = gui.add_dropdown("Branch", (NO_BRANCH,), disabled=True,
                                           hint="pipelines kept when a pick or a new start replaced them")
            self.restore = gui.add_button("Restore branch", disabled=True,
                                          hint="make the branch current (the current pipeline becomes a branch)")
            self.delete = gui.add_button("Delete branch", disabled=True, color="gray",
                                         hint="remove the branch and its results from the session (asks first)")
        self.show_stage.on_update(self._on_show)
        self.restore.on_click(self._on_restore)
        self.delete.on_click(self._on_delete)

    def show(self, sv: StudyView) -> None:
        key = (sv.key, tuple(id(r) for r in sv.results))
        if key == self._key:
            return
        self._key = key
        titles = {c.name: c.title for c in sv.chain}
        running = sv.status.stage if sv.status.running else None
        status = {n: ("running" if n == running else status_text(r)) for n, r in zip(sv.names, sv.results, strict=True)
                  if r is not None}
        self.table.content = history_html(history_rows(list(sv.results), titles, list(sv.names), status))
        done = tuple(n for n, r in zip(sv.names, sv.results, strict=True) if r is not None)
        options = done or ("-",)
        if tuple(self.show_stage.options) != options:
            self.show_stage.options = options
        if sv.viewing in done:
            set_value(self.show_stage, sv.viewing)
        self.show_stage.disabled = not done or sv.status.running
        branches = sv.branches or (NO_BRANCH,)
        if tuple(self.branch.options) != branches:
            self.branch.options = branches
        if sv.branches:
            set_value(self.branch, sv.branches[-1])
        self.branch.disabled = not sv.branches or sv.status.running
        self.restore.disabled = not sv.branches or sv.status.running
        self.delete.disabled = self.restore.disabled

    def _on_show(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        self.studio.view_stage(str(self.show_stage.value), event.client)

    def _on_restore(self, event: viser.GuiEvent[Any]) -> None:
        label = self.branch.value
        labels = [b.label for b in self.studio.session.study.branches]
        if label not in labels:
            return
        self.studio.restore_branch(labels.index(label), event.client)

    def _on_delete(self, event: viser.GuiEvent[Any]) -> None:
        label, client = str(self.branch.value), event.client
        if client is None or label == NO_BRANCH:
            return
        confirm(client, "Delete this branch?", f"**{label}**\n\nIts stage results leave the session (those it "
                "shares with other branches stay). This cannot be undone.", "Delete branch",
                lambda: self.studio.delete_branch(label, client))
