"""Mechanism panel: topology, preset, and every parameter of the current design.

Built from the registries (``core.kinematics.mechanisms.MECHANISMS``, ``core.kinematics.presets.PRESETS``) so new
topologies and presets appear without touching the studio. The parameter inputs are
rebuilt when the topology changes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from core.kinematics import mechanisms, presets
from core.kinematics.model import Mechanism
from core.kinematics.params import Param
from studio.panels._inputs import NumberField, NumberFields, NumberForm, set_value
from studio.state import (
    DesignView,
    assembly_reason,
    bounds_text,
    leg_scale,
    paper_bounds,
    preset_label,
    presets_for,
)

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

NO_PRESET = "(none)"
UNDO_HINT = "take back the last change of the design, target or walking view (a parameter, preset, topology, pick)"
REDO_HINT = "make again the change Undo took back"
STEP_LABEL = 34  # characters of "Undo r4, r5 · target": the side panel's width at 1100 px


def step_label(verb: str, what: str) -> str:
    """The Undo or Redo button's label: the verb and what it would change, shortened to fit."""
    text = f"{verb} {what}" if what else verb
    return text if len(text) <= STEP_LABEL else text[: STEP_LABEL - 1].rstrip() + "…"


def param_label(name: str, unit: str) -> str:
    """Input label of a parameter, e.g. ``r4 [mm]``; tests find inputs by it."""
    return f"{name} [{unit}]"


def param_form(p: Param, k: float = 1.0, paper: bool = True) -> NumberForm:
    """What a parameter's field takes on a leg of scale ``k``; the model checks the bounds
    (``studio.state.check_value``) and assembly. Shown to 0.01 mm and 0.0001 rad (0.006 deg), as the paper's
    tables give them: a run's picks read "100.609144" beside a preset's "128.33". Exports keep every digit."""
    if p.kind == "angle":
        return NumberForm(text=f"an angle in {p.unit} (any number within ±1e6; angles are periodic)", decimals=4)
    what = "a length" if p.kind == "length" else "a number"
    return NumberForm(text=f"{what} in {p.unit} within its bounds {bounds_text(p, k, paper)} that keeps the design "
                      "assembled", decimals=2 if p.unit == "mm" else 4)


class MechanismPanel:
    """Topology and preset dropdowns, a reset button, a status line and the parameter inputs."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self._titles = {m.title: name for name, m in mechanisms.MECHANISMS.items()}
        view = studio.session.view
        self._numbers = NumberFields(studio)
        self._mechanism: Mechanism | None = None
        self._inputs: dict[str, NumberField] = {}
        self._scale = 1.0  # the leg's size the inputs' bounds were stated for
        self._running = False
        self.folder = gui.add_folder("Mechanism", order=order)
        with self.folder:
            self.topology = gui.add_dropdown("Topology", tuple(self._titles), initial_value=view.design.mechanism.title,
                                             hint="the linkage; its first preset that walks is loaded")
            self.preset = gui.add_dropdown("Preset", self._preset_options(view),
                                           initial_value=self._preset_value(view),
                                           hint="named designs of this topology (paper appendices)")
            self.reset = gui.add_button("Reset to preset", hint="discard parameter edits")
            self.undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP, disabled=True, hint=UNDO_HINT)
            self.redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP, disabled=True, hint=REDO_HINT)
            self.status = gui.add_markdown("")
            self.params_folder = gui.add_folder("Parameters")
        self.topology.on_update(self._on_topology)
        self.preset.on_update(self._on_preset)
        self.reset.on_click(self._on_reset)
        self.undo.on_click(lambda event: self._step(event, "undo"))
        self.redo.on_click(lambda event: self._step(event, "redo"))
        self.show(view)

    # Mirrors ------------------------------------------------------------------------------

    def _preset_options(self, view: DesignView) -> tuple[str, ...]:
        names = tuple(preset_label(n) for n in presets_for(view.design.mechanism.name))
        return names if view.preset is not None and names else (NO_PRESET, *names)

    @staticmethod
    def _preset_value(view: DesignView) -> str:
        return preset_label(view.preset) if view.preset is not None else NO_PRESET

    def _full_preset(self, label: str) -> str | None:
        mech = self.studio.session.view.design.mechanism.name
        for name in presets_for(mech):
            if preset_label(name) == label:
                return name
        return None

    def _build_inputs(self, mech: Mechanism, values: dict[str, float], k: float) -> None:
        self._numbers.clear()
        gui = self.studio.server.gui
        self.params_folder.remove()
        with self.folder:
            self.params_folder = gui.add_folder("Parameters")
        self._inputs = {}
        self._scale = k
        with self.params_folder:
            for p in mech.params:
                self._inputs[p.name] = self._numbers.add(
                    p.name, param_label(p.name, p.unit), float(values[p.name]),
                    form=param_form(p, k, paper_bounds(mech)), hint=p.doc, apply=self._setter(p.name),
                    current=self._getter(p.name), disabled=self._running)
        self._mechanism = mech

    def _setter(self, name: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_param(name, v)

    def _getter(self, name: str) -> Callable[[], float]:
        return lambda: self.studio.session.view.values[name]

    def close(self) -> None:
        """Drop pending rejections of invalid entries (the server is going away)."""
        self._numbers.cancel_all()

    def show(self, view: DesignView) -> None:
        """Mirror a design view into the controls (programmatic updates; callbacks ignore them)."""
        mech = view.design.mechanism
        values = view.values
        k = leg_scale(mech, view.target)
        if mech != self._mechanism or k != self._scale:  # the bounds the inputs' hints state follow the leg's size
            self._build_inputs(mech, values, k)
        set_value(self.topology, mech.title)
        options = self._preset_options(view)
        if tuple(self.preset.options) != options:
            self.preset.options = options
        set_value(self.preset, self._preset_value(view))
        self.reset.disabled = self._running or view.preset is None or not view.edited
        for name, field in self._inputs.items():
            field.show(float(values[name]))
        self.status.content = self._status(view)
        self.show_steps()

    def show_steps(self) -> None:
        """Undo and Redo: enabled when there is something to take back or make again (not during a run), with
        what that is in their labels ("Undo r4"; viser draws no hint on a button) and hints."""
        session = self.studio.session
        for button, which, hint, done in ((self.undo, "undo", UNDO_HINT, "take back"),
                                          (self.redo, "redo", REDO_HINT, "make again")):
            what = session.change_names(which)
            state = (self._running or not what, f"{done}: {what}" if what else hint, step_label(which.capitalize(),
                                                                                                  what))
            if (button.disabled, button.hint, button.label) != state:  # called on every study push of a run
                button.disabled, button.hint, button.label = state

    def hold(self, running: bool) -> None:
        """Disable the design's controls while a stage runs: its pick replaces the design when it ends, so an edit
        would be lost (the session refuses one anyway, ``Session._commit``)."""
        if running == self._running:
            return
        self._running = running
        self.topology.disabled = self.preset.disabled = running
        for field in self._inputs.values():
            field.disabled = running
        view = self.studio.session.view
        self.reset.disabled = running or view.preset is None or not view.edited
        self.show_steps()

    @staticmethod
    def _status(view: DesignView) -> str:
        mech = view.design.mechanism
        if view.preset is None:
            return f"**{mech.title}**, no preset."
        src = presets.get(view.preset).source
        edited = view.edited
        line = f"**{mech.title}** · preset **{preset_label(view.preset)}**" + (f" · {src}" if src else "")
        return line + (f"  \nEdited: {', '.join(edited)}" if edited else "")

    # Callbacks ----------------------------------------------------------------------------

    def _revert(self) -> None:
        view = self.studio.session.view
        set_value(self.topology, view.design.mechanism.title)
        set_value(self.preset, self._preset_value(view))

    def _on_topology(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        name = self._titles.get(self.topology.value)
        try:
            if name is None:
                raise ValueError(f"unknown topology {self.topology.value!r}")
            view = self.studio.session.select_mechanism(name)
        except ValueError as exc:
            self._revert()
            self.studio.notify(event.client, "Topology not changed", str(exc))
            return
        self.studio.refresh(fit_camera=True)
        self._warn_if_broken(event.client, view)

    def _on_preset(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None or self.preset.value == NO_PRESET:
            return
        name = self._full_preset(self.preset.value)
        try:
            if name is None:
                raise ValueError(f"unknown preset {self.preset.value!r}")
            view = self.studio.session.load_preset(name)
        except ValueError as exc:
            self._revert()
            self.studio.notify(event.client, "Preset not loaded", str(exc))
            return
        self.studio.refresh(fit_camera=True)
        self._warn_if_broken(event.client, view)

    def _warn_if_broken(self, client: viser.ClientHandle, view: DesignView) -> None:
        reason = assembly_reason(view)
        if reason is not None:
            self.studio.notify(client, "This design does not assemble",
                               f"{reason}; it is drawn where it does. Edit its parameters to repair it.",
                               color="yellow")

    def _step(self, event: viser.GuiEvent[Any], which: str) -> None:
        session = self.studio.session
        before = session.view.design.mechanism
        try:
            view = session.undo() if which == "undo" else session.redo()
        except ValueError as exc:
            if event.client is not None:
                self.studio.notify(event.client, f"Not {'undone' if which == 'undo' else 'redone'}", str(exc))
            return
        self.studio.refresh(fit_camera=view.design.mechanism != before)

    def _on_reset(self, event: viser.GuiEvent[Any]) -> None:
        try:
            self.studio.session.reset_to_preset()
        except ValueError as exc:
            if event.client is not None:
                self.studio.notify(event.client, "Not reset", str(exc))
            return
        self.studio.refresh()
