"""Pick panel: choose among the knee shortlist and the whole front of the shown stage; pass it on.

viser sends no plotly click events, so candidates are chosen with a dropdown (knees, best per
objective, then the front), a slider over the front, or the clickable spheres in the scene.
Picking animates the candidate at once (it becomes the editor's design) and compares its metrics
with the design the stage started from. "Use for next stage" commits the pick; the Stages panel
then shows the next stage's search box.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from studio.candidates import (
    Candidate,
    candidates,
    compared_metrics,
    comparison,
    front_order,
    objective_text,
    start_design,
)
from studio.panels._confirm import confirm
from studio.panels._inputs import set_value
from studio.study_view import StudyView
from studio.tables import (
    compare_html,
    dead_point_html,
    next_verdict_html,
    off_screen_html,
    one_design_html,
    verdict_html,
)

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

NONE = "(no candidates yet)"
# Report metrics where less is better (the others, such as width or y_min, are neither).
LOWER_BETTER = ("mse", "h_s", "S", "I", "violation")


# Front members listed in the dropdown at most (evenly spaced; the slider reaches every one): with 227 entries
# (pop 400) the dropdown took 0.9 s to open on software rendering, with 60 0.05 s.
FRONT_LISTED = 60


def listed(cands: tuple[Candidate, ...], shown: int | None) -> tuple[Candidate, ...]:
    """The knees and best members, and at most ``FRONT_LISTED`` front members spread along the front (the shown one
    always), in the candidates' order."""
    front = [c for c in cands if c.kind == "front"]
    if len(front) <= FRONT_LISTED:
        return cands
    keep = {front[j].member for j in np.linspace(0, len(front) - 1, FRONT_LISTED).round().astype(int)}
    return tuple(c for c in cands if c.kind != "front" or c.member in keep or c.member == shown)


class PickPanel:
    """Candidate dropdown, front slider, "Use for next stage", and the comparison table."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._cands: tuple[Candidate, ...] = ()
        self._front: tuple[int, ...] = ()
        self._stage: str | None = None
        self._start_of: object = None  # the result whose start design's metrics are cached (held, not its id)
        self._start: dict[str, float] = {}
        self._key: object = None
        self._member: int | None = None
        self._drawn: object = None  # the result the panel shows
        self.folder = gui.add_folder("Pick", order=order)
        with self.folder:
            self.candidate = gui.add_dropdown("Candidate", (NONE,), disabled=True,
                                              hint="knee candidates (K1 best), best per objective, then the front "
                                                   "(up to 60 of it; the Along the front slider reaches every member)")
            # "Front member 11" beside "best f1 · #1" read as two numbers for one member (rehearsal 3): the slider
            # counts places along the front, "#" names members.
            self.slider = gui.add_slider("Along the front", 1, 2, 1, 1, disabled=True, visible=False,
                                         hint="place along the front sorted by its first objective (1: the smallest); "
                                              "a member's own number is its #")
            self.use = gui.add_button("Use for next stage", icon=viser.Icon.ARROW_RIGHT, disabled=True,
                                      hint="pass this candidate on: the next stage searches around it")
            # After Undo (or an edit) the editor shows another design while this panel still describes the member
            # "Use for next stage" would pass on (rehearsal 7): said, with a way back.
            self.reshow = gui.add_button("Show this member again", icon=viser.Icon.ARROW_BACK_UP, visible=False,
                                         hint="put the member this panel describes back in the editor")
            self.table = gui.add_html("")
        self.candidate.on_update(self._on_candidate)
        self.reshow.on_click(self._on_reshow)
        self.slider.on_update(self._on_slider)
        self.use.on_click(self._on_use)

    def show(self, sv: StudyView) -> None:
        r = sv.result(sv.viewing)
        running = sv.status.running
        key = (sv.shown, running, sv.viewing, self._on_screen(r, sv.shown))
        # The result itself, by identity (not its id: a freed live result's id went to a later generation's, whose
        # labels then never replaced the older ones while the Pareto chart showed the later front).
        if r is self._drawn and key == self._key:
            return
        self._key, self._drawn = key, r
        # One batch: the page drew the table's new member up to 100 ms before the dropdown's (whose options,
        # replaced every live generation, first reset its value to the first of them).
        with self.studio.server.atomic():
            self._show(sv, r, running)

    def _on_screen(self, r: Any, i: int | None) -> bool:
        """Whether the editor shows member i of r (its parameters; either RTCLM mode), or there is none."""
        if r is None or i is None or not 0 <= i < r.pop:
            return True
        p = self.studio.session.view.design.params[0]
        return p.shape == r.X[i].shape and bool(np.array_equal(p, r.X[i]))

    def _show(self, sv: StudyView, r: Any, running: bool) -> None:
        self._stage, self._member = sv.viewing, sv.shown
        off = not self._on_screen(r, sv.shown)
        self.reshow.visible = off and not running
        if r is None or r.pop == 0:
            self._cands, self._front = (), ()
            self.candidate.options = (NONE,)
            self.candidate.disabled = self.slider.disabled = self.use.disabled = True
            self.slider.visible = False  # no front to slide over yet (it spanned 1-2)
            self.table.content = ""
            return
        self._cands = listed(candidates(r), sv.shown)
        self._front = front_order(r)
        labels = tuple(c.label for c in self._cands) or (NONE,)
        if tuple(self.candidate.options) != labels:
            self.candidate.options = labels
        current = next((c.label for c in self._cands if c.member == sv.shown), None)
        if current is None and sv.shown is not None:  # a member off the list (e.g. infeasible): add it
            extra = f"#{sv.shown} · {objective_text(r, sv.shown)}"
            self.candidate.options = (*labels, extra)
            current = extra
        if current is not None:
            set_value(self.candidate, current)
        n = len(self._front)
        self.slider.max = max(n, 2)
        self.slider.disabled = running or n < 2
        self.slider.visible = n >= 2  # a one-member front has nothing to slide over
        if sv.shown in self._front:
            set_value(self.slider, self._front.index(sv.shown) + 1)
        self.candidate.disabled = running
        k = sv.names.index(sv.viewing) if sv.viewing in sv.names else -1
        self.use.disabled = running or sv.shown is None or k < 0 or k + 1 >= len(sv.names)
        self.table.content = self._table(sv, r)

    def _table(self, sv: StudyView, r: Any) -> str:
        if sv.shown is None:
            return ""
        spec = sv.specs.get(sv.viewing or "")
        labels = dict(spec.problem.labels) if spec is not None else {}
        cons = tuple(c.metric for c in spec.problem.constraints) if spec is not None else ()
        start = self._start if self._start_of is r else None  # the start design's metrics, once per result
        if start is None:
            start = {}
            if spec is not None:
                try:
                    m = spec.problem.evaluate_metrics(start_design(r))
                    start = {k: float(np.asarray(v)[0]) for k, v in m.items()}
                except ValueError:
                    start = {}
            self._start, self._start_of = start, r
        names = compared_metrics(r, cons)
        rows = comparison(r, sv.shown, start, names, labels)
        upper = {c.metric for c in spec.problem.constraints if c.upper is not None} if spec is not None else set()
        lower = {labels.get(n, n) for n in names if n in r.objectives or n in upper or n in LOWER_BETTER}
        one = len(self._cands) == 1 and self._cands[0].kind != "fallback" and self._cands[0].member == sv.shown
        nxt, missed, avoidable = (self.studio.next_unmet(sv.viewing) if sv.viewing is not None and r.cv[sv.shown] <= 0
                                  else ("", [], False))
        kept_to = self.studio.pick_limits(sv.viewing) if missed and avoidable and sv.viewing is not None else None
        off = "" if sv.status.running or self._on_screen(r, sv.shown) else off_screen_html(sv.shown)
        return (off + verdict_html(r, sv.shown, sv.viewing or "", labels=labels) + dead_point_html(r, sv.shown)
                + next_verdict_html(sv.shown, nxt, missed, sv.viewing or "", avoidable, kept_to)
                + (one_design_html(sv.viewing or "") if one else "")
                + compare_html(rows, "start", f"#{sv.shown}", lower))

    # Callbacks -------------------------------------------------------------------------------

    def _on_candidate(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None or self._stage is None:
            return
        member = next((c.member for c in self._cands if c.label == self.candidate.value), None)
        if member is not None:
            self.studio.pick(self._stage, member, event.client)

    def _on_reshow(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None or self._stage is None or self._member is None:
            return
        self.studio.pick(self._stage, self._member, event.client)

    def _on_slider(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None or self._stage is None or not self._front:
            return
        j = int(round(float(self.slider.value))) - 1
        if 0 <= j < len(self._front):
            self.studio.pick(self._stage, self._front[j], event.client)

    def _on_use(self, event: viser.GuiEvent[Any]) -> None:
        stage, client = self._stage, event.client
        if stage is None:
            return
        with self.studio.session.lock:
            r = self.studio.session.study.result(stage)
            i = self.studio.session.study.shown_member(stage)
        unmet = r.unmet(i) if r is not None and i is not None and r.cv[i] > 0 else []
        if unmet and client is not None:
            confirm(client, f"Pass on an infeasible member of {stage}?",
                    f"#{i} does not meet {stage}'s constraints: **{'; '.join(unmet)}**.\n\nThe next stage will "
                    "search around it anyway.", "Pass it on", lambda: self.studio.use_for_next(stage, client))
            return
        # A member that meets this stage's constraints may miss the next one's (subtask 2's K3 with I = 30.2 passed
        # to subtask 3, I <= 20): its run then starts with no feasible member. The automatic pick avoids that.
        # Not asked when no member here meets them: then the next stage is there to (rtclm1 -> rtclm2, whose
        # auxiliary mode rtclm1 never models, asked at every pass in a demo rehearsal).
        nxt, missed, avoidable = self.studio.next_unmet(stage)
        if missed and avoidable and client is not None:
            confirm(client, f"Pass on a member that misses {nxt}'s constraints?",
                    f"#{i} meets {stage}'s constraints but not {nxt}'s: **{'; '.join(missed)}**.\n\n{nxt} will "
                    "search around it; its first generations may have no feasible member.", "Pass it on",
                    lambda: self.studio.use_for_next(stage, client))
            return
        self.studio.use_for_next(stage, client)
