"""Target panel: L, H and T of the compound-cycloid target (spec §3)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from studio.panels._inputs import ValidatedNumbers, set_value
from studio.state import DesignView

if TYPE_CHECKING:
    from studio.app import Studio

FIELDS = (("length", "L [mm]", "step length of the arch"), ("height", "H [mm]", "height of the arch"),
          ("period", "T [s]", "period of one step cycle (one crank revolution)"))


class TargetPanel:
    """Number inputs for the target; invalid values are refused like parameter edits."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        target = studio.session.view.target
        self._numbers = ValidatedNumbers(studio)
        self.inputs: dict[str, viser.GuiNumberHandle[Any]] = {}
        self.folder = gui.add_folder("Target: compound cycloid", order=order, expand_by_default=False)
        with self.folder:
            for key, label, hint in FIELDS:
                h = gui.add_number(label, float(getattr(target, key)), step=0.01 if key == "period" else 1.0,
                                   hint=hint)
                self.inputs[key] = h
                self._numbers.bind(key, h, apply=self._setter(key), current=self._getter(key), what=f"target {label}")

    def _setter(self, key: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_target(**{key: v})

    def _getter(self, key: str) -> Callable[[], float]:
        return lambda: float(getattr(self.studio.session.view.target, key))

    def close(self) -> None:
        """Drop pending rejections of invalid entries (the server is going away)."""
        self._numbers.cancel_all()

    def show(self, view: DesignView) -> None:
        for key, h in self.inputs.items():
            set_value(h, float(getattr(view.target, key)))
