"""Stages panel: choose a stage of the chain, its start, problem and algorithm settings; Run, Stop, progress.

The stage and problem lists follow the editor's mechanism (``studio.chains``: a problem that cannot optimize
it, as the RTCLM's on a six-bar, is not offered). Only one run at a time: the Run button is disabled while a
stage runs, and the runner refuses a second start (a double click starts one run). Settings are kept per stage.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import viser

from core.optimize.algorithms import ALGORITHMS
from studio.chains import MAX_GEN, MAX_POP, RunSettings, find
from studio.panels._confirm import confirm
from studio.panels._inputs import NumberField, NumberFields, NumberForm, set_value
from studio.study_view import StudyView, next_stage
from studio.tables import box_html

# NSGA-II and the six constrained MOEAs the paper compares (docs/algorithms.md).
PAPER_ALGORITHMS = ("nsga2", "cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "mccmo", "moead_cmt")


def algorithm_label(name: str) -> str:
    """How the dropdown names an algorithm: its published name, not our identifier (``IMTCMO (paper)``)."""
    title = ALGORITHMS[name].title
    if name == "nsga2":
        return f"{title} (paper, default)"
    return f"{title} (paper)" if name in PAPER_ALGORITHMS else title


# The paper's seven first: on a 720 px screen the list ran past the bottom edge, three of them below it.
LISTED = sorted(ALGORITHMS, key=lambda k: (k not in PAPER_ALGORITHMS, list(ALGORITHMS).index(k)))
LABELS = {k: algorithm_label(k) for k in LISTED}
BY_LABEL = {v: k for k, v in LABELS.items()}

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


def algorithm_hint(key: str) -> str:
    """The Algorithm dropdown's hint: what it offers and the chosen one's name in a config. (Every label's name, 480
    characters, covered Population, Generations, Run and Stop while the pointer rested on the panel; QA session 38.)"""
    return (f"NSGA-II and the six constrained MOEAs the paper compares, then pymoo's; in a config or `clm design`: "
            f"algorithm = \"{key}\" (docs/algorithms.md)")


FROM_EDITOR = "the design in the editor"
FROM_PICK = "the previous stage's pick"


class StagesPanel:
    """Stage, start, problem, algorithm, population, generations, seed, min transmission angle; Run / Stop; progress
    and status."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._titles: dict[str, str] = {}
        self.folder = gui.add_folder("Stages", order=order)
        with self.folder:
            self.stage = gui.add_dropdown("Stage", ("-",), hint="the stage to run (paper §3.1-3.2, §4.2)")
            self.start = gui.add_dropdown("Start from", (FROM_EDITOR, FROM_PICK), initial_value=FROM_EDITOR,
                                          hint="the editor's design starts a new pipeline at this stage; the previous "
                                               "stage's pick continues the current one")
            self.problem = gui.add_dropdown("Problem", ("-",),
                                            hint="any registered problem that fits the mechanism can run in this "
                                                 "stage's place")
            self.algorithm = gui.add_dropdown("Algorithm", tuple(LABELS.values()), initial_value=LABELS["nsga2"],
                                              hint=algorithm_hint("nsga2"))
            self._numbers = NumberFields(studio)
            self.pop_size = self._number("pop_size", "Population", 40, 2, MAX_POP, "members per generation")
            self.n_gen = self._number("n_gen", "Generations", 30, 1, MAX_GEN,
                                      "generations (the first evaluates the initial population)")
            self.seed = self._number("seed", "Seed", 1, 0, 2**31 - 1, "seed of the algorithm and the initial sample")
            self.transmission_min = self._number(
                "transmission_min", "Min transmission μ [deg]", 0, 0, 89,
                "a constraint: every member's worst transmission angle at least this (0: none, the paper's; 40 is the "
                "usual rule): keeps the search off dead points")
            self.constraints = gui.add_html("")
            with gui.add_folder("Search box", expand_by_default=False):
                self.box = gui.add_html("")
            self.run = gui.add_button("Run", color="green", icon=viser.Icon.PLAYER_PLAY,
                                      hint="run the stage; one run at a time")
            self.stop = gui.add_button("Stop", color="red", icon=viser.Icon.PLAYER_STOP, disabled=True,
                                       hint="stop after the current generation (the partial result is kept)")
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.status = gui.add_markdown("Idle.")
        self.stage.on_update(self._on_stage)
        self.start.on_update(self._on_start)
        self.problem.on_update(self._on_choice)
        self.algorithm.on_update(self._on_choice)
        self.run.on_click(self._on_run)
        self.stop.on_click(self._on_stop)

    # Mirror ----------------------------------------------------------------------------------

    def show(self, sv: StudyView) -> None:
        self._titles = {c.title: c.name for c in sv.chain}
        titles = tuple(self._titles) or ("(no stage for this mechanism)",)
        if tuple(self.stage.options) != titles:
            self.stage.options = titles
        current = next((c.title for c in sv.chain if c.name == sv.next_stage), titles[0])
        set_value(self.stage, current)
        set_value(self.start, FROM_PICK if sv.from_pick else FROM_EDITOR)
        s = sv.settings
        if s is not None:
            names = sv.problems  # the problems that fit the editor's mechanism
            if s.problem not in names:  # a session's own choice stays shown (Run says why it does not fit)
                names = (*names, s.problem)
            if tuple(self.problem.options) != names:
                self.problem.options = names
            set_value(self.problem, s.problem)
            set_value(self.algorithm, LABELS.get(s.algorithm, s.algorithm))
            if self.algorithm.hint != (hint := algorithm_hint(s.algorithm)):
                self.algorithm.hint = hint
            self.pop_size.show(s.pop_size)
            self.n_gen.show(s.n_gen)
            self.seed.show(s.seed)
            self.transmission_min.show(s.transmission_min)
        running = sv.status.running
        for h in (self.stage, self.start, self.problem, self.algorithm, self.pop_size, self.n_gen, self.seed,
                  self.transmission_min):
            h.disabled = running or not sv.chain
        self.run.disabled = running or not sv.chain
        self.stop.disabled = not running or sv.status.state == "stopping"
        set_value(self.progress, float(min(100.0, 100.0 * sv.status.fraction)))
        self.progress.animated = running
        self.status.content = self._status(sv)
        self.constraints.content = (f'<div style="font-size:0.8em;padding:0 0.75em">Constraints of {sv.next_stage}: '
                                    f'{" · ".join(html.escape(c) for c in sv.constraints)}</div>'
                                    if sv.constraints else "")
        if sv.box is None:
            self.box.content = f'<div style="font-size:0.8em;padding:0 0.75em">{sv.box_note}</div>'
        else:
            view = self.studio.session.view
            units = {p.name: p.unit for p in view.design.mechanism.params}
            self.box.content = box_html(sv.box, units, f"{sv.next_stage}: {sv.box_note}", near=view.values)

    @staticmethod
    def _status(sv: StudyView) -> str:
        st = sv.status
        # Compiling counts once it is a noticeable part (a fresh install's first run of a kind: ~30 s).
        compiled = (f", {seconds(min(st.compiled, st.elapsed))} of it compiling the numeric kernels, kept for later "
                    "runs" if st.compiled >= 0.5 else "")
        if st.state == "running" and st.generation == 0 and st.compiled >= 0.5:  # before any generation is in
            return (f"**Running** {st.stage}: compiling the numeric kernels, {seconds(st.compiled)} so far (the first "
                    "run of this kind only: numba keeps them for later runs; `clm-studio --warm-up` does it ahead)")
        if st.state == "running":
            return (f"**Running** {st.stage}: generation {st.generation}/{st.n_gen} ({seconds(st.elapsed)} compute"
                    f"{compiled})")
        if st.state == "stopping":
            return f"**Stopping** {st.stage} after generation {st.generation}…"
        if st.stage is None:
            # Lab rehearsal: a first-time student read only this line; it now says what a run gives and where.
            return "Idle. Choose a stage and press Run; its front grows below: click a candidate to take it."
        mark = "" if st.ok else "⚠ "
        return f"{mark}Last run: {st.stage} {st.message} ({seconds(st.elapsed)} compute{compiled})."

    # Callbacks -------------------------------------------------------------------------------

    def _stage_name(self) -> str | None:
        return self._titles.get(self.stage.value)

    def _on_stage(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        name = self._stage_name()
        if name is None:
            return
        session = self.studio.session
        with session.lock:
            study = session.study
            study.next_stage = name
            # Continue the pipeline when it can (the previous stage has a result), else start fresh.
            study.from_pick = study.next_box(name, session.view.target) is not None
            study.touch()
        self.studio.refresh()

    def _on_start(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        session = self.studio.session
        with session.lock:
            session.study.from_pick = self.start.value == FROM_PICK
            session.study.touch()
        self.studio.refresh()

    def _shown_stage(self) -> str | None:
        """The stage whose settings the fields show (call with the session's lock held). Not the Stage dropdown's
        value on the server: a refresh begun before a stage change sets it back to the old stage until the next."""
        return next_stage(self.studio.session.study, self.studio.chain())

    def _change(self, **values: object) -> RunSettings:
        """Change the selected stage's settings; ValueError (nothing changed) if invalid."""
        session = self.studio.session
        with session.lock:
            name = self._shown_stage()
            if name is None:
                raise ValueError("no stage selected")
            if session.study.status.running:
                raise ValueError("a stage is running")
            stage = find(self.studio.chain(), name)
            new = replace(session.study.settings_for(stage), **values)  # type: ignore[arg-type]
            session.study.settings[name] = new
            session.study.touch()
            return new

    def _number(self, key: str, label: str, value: int, lo: int, hi: int, hint: str) -> NumberField:
        """A whole-number field of the selected stage's settings."""
        return self._numbers.add(key, label, value, form=NumberForm(whole=True, lo=lo, hi=hi), hint=hint,
                                 apply=self._setter(key), current=self._getter(key))

    def _setter(self, key: str) -> Callable[[int], object]:
        return lambda v: self._change(**{key: int(v)})

    def _getter(self, key: str) -> Callable[[], float]:
        def get() -> float:
            session = self.studio.session
            with session.lock:
                name = self._shown_stage()
                if name is None:
                    return float(getattr(RunSettings(problem="-"), key))
                return float(getattr(session.study.settings_for(find(self.studio.chain(), name)), key))

        return get

    def _on_choice(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        try:
            label = str(self.algorithm.value)
            self._change(problem=str(self.problem.value), algorithm=BY_LABEL.get(label, label))
        except ValueError as exc:
            self.studio.notify(event.client, "Setting not applied", str(exc))
        self.studio.refresh()

    def close(self) -> None:
        self._numbers.cancel_all()

    def _on_run(self, event: viser.GuiEvent[Any]) -> None:
        note = self._units_note()
        if note and event.client is not None and not self.studio.session.study.status.running:
            # Rehearsal 4: a file in m became a 0.12 mm target; the upload's notification went by, and Run sized the
            # whole search to it and replaced the design with a 0.11 mm leg. The run asks first.
            client = event.client
            confirm(client, "Run against this target?", f"{note}\n\nThe run sizes its search to the target (its "
                    "lengths follow the target's width), and its pick replaces the editor's design (Undo brings it "
                    "back).", "Run anyway", lambda: self._start(client))
            return
        self._start(event.client)

    def _units_note(self) -> str:
        """What is odd about the target's size, when the selected stage optimizes against an uploaded curve whose
        numbers look like another unit than mm (``core.analysis.targets.scale_note``); "" otherwise."""
        from studio.chains import takes_target

        curve = self.studio.session.view.target.curve
        if curve is None:
            return ""
        note = curve.scale_note()
        with self.studio.session.lock:
            name = self._shown_stage()
            stage = find(self.studio.chain(), name) if name is not None else None
            problem = self.studio.session.study.settings_for(stage).problem if stage is not None else None
        if not note or problem is None or not takes_target(problem):
            return ""
        return f"The target curve {curve.name}: {note}."

    def _start(self, client: viser.ClientHandle | None) -> None:
        try:
            self.studio.start_run()
        except ValueError as exc:
            if "already running" in str(exc):
                return  # a second click of a double click: the first one started the run
            if client is not None:
                self.studio.notify(client, "Stage not started", str(exc))
        self.studio.refresh()

    def _on_stop(self, event: viser.GuiEvent[Any]) -> None:
        self.studio.runner.stop()
        self.studio.refresh()


def seconds(t: float) -> str:
    """A run's compute time as a designer reads it: ``12.3 s``, ``0.08 s`` (a short run is not "0.0 s"). The status
    says "compute": the page's redraws come on top, and a presenter read "(4.9 s)" after 10.5 s of waiting."""
    if t >= 1.0:
        return f"{t:.1f} s"
    return f"{t:.2f} s" if t >= 0.005 else "< 0.01 s"
