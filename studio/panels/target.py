"""Target panel: L, H and T of the compound-cycloid target (spec §3), or a closed curve uploaded as CSV.

A CSV holds rows ``x,y`` (a curve without a time law, compared at the best cyclic shift) or
``x,y,t`` (uniform in time after resampling), with an optional header (``core.analysis.targets``). A
malformed file is refused with a notification naming the problem; the target stays as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from studio.panels._inputs import ValidatedNumbers, set_value
from studio.state import DesignView
from studio.target import Curve

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

FIELDS = (("length", "L [mm]", "step length of the arch"), ("height", "H [mm]", "height of the arch"),
          ("period", "T [s]", "period of one step cycle (one crank revolution)"))


class TargetPanel:
    """Number inputs for the cycloid (editing one returns to the cycloid), a CSV upload, and a status line."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        target = studio.session.view.target
        self._numbers = ValidatedNumbers(studio)
        self.inputs: dict[str, viser.GuiNumberHandle[Any]] = {}
        self.folder = gui.add_folder("Target", order=order, expand_by_default=False)
        with self.folder:
            self.status = gui.add_markdown("")
            for key, label, hint in FIELDS:
                h = gui.add_number(label, float(getattr(target, key)), step=0.01 if key == "period" else 1.0,
                                   hint=hint + " (compound cycloid; editing returns to it)")
                self.inputs[key] = h
                self._numbers.bind(key, h, apply=self._setter(key), current=self._getter(key), what=f"target {label}")
            self.upload = gui.add_upload_button("Upload CSV curve", icon=viser.Icon.UPLOAD, mime_type=".csv,text/csv",
                                                hint="a closed curve: rows x,y or x,y,t (mm, s), optional header")
            self.cycloid = gui.add_button("Back to the compound cycloid", disabled=True)
        self.upload.on_upload(self._on_upload)
        self.cycloid.on_click(self._on_cycloid)
        self.show(studio.session.view)

    def _setter(self, key: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_target(**{key: v})

    def _getter(self, key: str) -> Callable[[], float]:
        return lambda: float(getattr(self.studio.session.view.target, key))

    def close(self) -> None:
        """Drop pending rejections of invalid entries (the server is going away)."""
        self._numbers.cancel_all()

    def show(self, view: DesignView, optimized_by: tuple[str, ...] | None = None) -> None:
        """Mirror the target; ``optimized_by``: the stages of the mechanism that optimize it (None: not known)."""
        t = view.target
        for key, h in self.inputs.items():
            set_value(h, float(getattr(t, key)))
        self.cycloid.disabled = not t.is_curve
        note = "" if t.has_time else " (no times: compared at the best cyclic shift)"
        line = f"Target: {t.label()}{note}."
        if optimized_by is not None:
            mech = view.design.mechanism.title
            line += (f"  \nOptimized by {', '.join(optimized_by)}." if optimized_by else
                     f"  \nNot shown: no stage of the {mech} optimizes a target (its stages have objectives of their "
                     "own); MSE in Metrics is still measured against it.")
        self.status.content = line

    def _on_upload(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        f = self.upload.value
        try:
            curve = Curve.from_csv(f.content, f.name or "upload.csv")
            self.studio.session.set_curve(curve)
        except ValueError as exc:
            self.studio.notify(event.client, "Target curve not loaded", f"{exc}. The target is unchanged.")
            return
        self.studio.refresh(fit_camera=True)

    def _on_cycloid(self, event: viser.GuiEvent[Any]) -> None:
        self.studio.session.set_curve(None)
        self.studio.refresh(fit_camera=True)
