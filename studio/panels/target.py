"""Target panel: L, H and T of the compound-cycloid target (spec §3), or a closed curve uploaded as CSV; for an
RTCLM design also its h6 and h4 targets (paper §4.2), which its stages optimize.

A CSV holds rows ``x,y`` (a curve without a time law, compared at the best cyclic shift) or
``x,y,t`` (uniform in time after resampling), with an optional header (``core.analysis.targets``). A
malformed file is refused with a notification naming the problem; the target stays as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from core.kinematics.checks import MAX_ABS
from core.kinematics.model import OutputStage
from core.optimize.rtclm import is_rtclm
from studio.panels._inputs import NumberField, NumberFields, NumberForm
from studio.state import DesignView
from studio.target import Curve

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

FRAMES = ("design frame (mechanism view)", "leg frame (bench view)")
FIELDS = (("length", "L [mm]", "mm", "step length of the arch"), ("height", "H [mm]", "mm", "height of the arch"),
          ("period", "T [s]", "s", "period of one step cycle (one crank revolution)"))
# The RTCLM's targets (paper §4.2), shown for an RTCLM design only: its stages optimize these, not a curve.
HEIGHTS = (("h6", "h6 target [mm]", "the primary mode's step height h6, rtclm1's target (held by rtclm2)"),
           ("h4", "h4 target [mm]", "the auxiliary mode's step height h4, rtclm2's target"))


def field_form(key: str, unit: str) -> NumberForm:
    """What L, H (mm, > 0 up to 1e6) and T (s, 1e-6 to 1e6) take, as the model checks them: the form's own words
    name the whole rule (QA, session 37: "must be at most 1e+06 mm, got 1000000000.0. It takes a number > 0 (mm)";
    T = 1e-9 read "must be between 1e-06 and 1e+06 s ... It takes a number > 0 (s)")."""
    if key == "period":
        return NumberForm(lo=1.0 / MAX_ABS, hi=MAX_ABS, unit=unit)
    return NumberForm(lo=0.0, lo_open=True, hi=MAX_ABS, unit=unit)


class TargetPanel:
    """Number fields for the cycloid (hidden while a curve is the target), a CSV upload, and a status line."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        target = studio.session.view.target
        self._numbers = NumberFields(studio)
        self.inputs: dict[str, NumberField] = {}
        self.folder = gui.add_folder("Target", order=order, expand_by_default=False)
        with self.folder:
            self.status = gui.add_markdown("")
            for key, label, hint in HEIGHTS:
                self.inputs[key] = self._numbers.add(
                    key, label, float(getattr(target, key)), form=field_form(key, "mm"),
                    apply=self._height(key), current=self._getter(key), what=f"RTCLM {label}", hint=hint)
            for key, label, unit, hint in FIELDS:
                self.inputs[key] = self._numbers.add(
                    key, label, float(getattr(target, key)), form=field_form(key, unit),
                    apply=self._setter(key), current=self._getter(key), what=f"target {label}",
                    hint=hint + "; compound cycloid, editing returns to it")
            self.frame = gui.add_dropdown("CSV frame", FRAMES, initial_value=FRAMES[0],
                                          hint="design: the coupler path as the mechanism view draws it (the "
                                               "paper's frame, the cycloid's arch below); leg: the foot path as "
                                               "the bench view draws it (swing above), mapped by the design's "
                                               "output stage")
            self.upload = gui.add_upload_button("Upload CSV curve", icon=viser.Icon.UPLOAD, mime_type=".csv,text/csv",
                                                hint="a closed curve: rows x,y or x,y,t (mm, s), optional header")
            self.cycloid = gui.add_button("Back to the compound cycloid", disabled=True)
        self.upload.on_upload(self._on_upload)
        self.cycloid.on_click(self._on_cycloid)
        self.show(studio.session.view)

    def _setter(self, key: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_target(**{key: v})

    def _height(self, key: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_heights(**{key: v})

    def _getter(self, key: str) -> Callable[[], float]:
        return lambda: float(getattr(self.studio.session.view.target, key))

    def close(self) -> None:
        """Drop pending rejections of invalid entries (the server is going away)."""
        self._numbers.cancel_all()

    def show(self, view: DesignView, optimized_by: tuple[str, ...] | None = None) -> None:
        """Mirror the target; ``optimized_by``: the stages of the mechanism that optimize it (None: not known)."""
        t = view.target
        rtclm = is_rtclm(view.design.mechanism.name)
        for key, field in self.inputs.items():
            field.show(float(getattr(t, key)))
            # The cycloid's L, H and T are hidden while a curve is the target: "L = 300, H = 100" read as the
            # curve's size. The cycloid keeps them; "Back to the compound cycloid" shows them again.
            field.handle.visible = rtclm if key in ("h6", "h4") else not t.is_curve
        self.cycloid.disabled = not t.is_curve
        note = "" if t.has_time else " (no times: compared at the best cyclic shift)"
        line = f"Target: {t.label()}{note}, in the design frame."
        if optimized_by is not None:
            mech = view.design.mechanism.title
            own = "optimize h6 and h4" if rtclm else "have objectives of their own"
            line += (f"  \nOptimized by {', '.join(optimized_by)}." if optimized_by else
                     f"  \nNot shown: no stage of the {mech} optimizes a target curve (its stages {own}); MSE in "
                     "Metrics is still measured against it.")
        if rtclm:
            line = f"RTCLM targets: {t.heights()}.  \n{line}"
        self.status.content = line

    def _on_upload(self, event: viser.GuiEvent[Any]) -> None:
        """Load an uploaded CSV as the target, or say why the file is not one (the target unchanged).

        viser's upload button tells the page "File uploaded successfully." by itself once the
        transfer is complete, whatever the server makes of the file, and the studio cannot take that
        back; so the refusal says the file arrived and what is wrong with it as a curve.
        """
        if event.client is None:
            return
        f = self.upload.value
        name = f.name or "upload.csv"
        leg = self.frame.value == FRAMES[1]
        output = self.studio.session.view.design.output
        before = self.studio.session.view.target
        try:
            curve = Curve.from_csv(f.content, name, leg=output if leg else None)
            self.studio.session.set_curve(curve)
        except ValueError as exc:
            problem = str(exc).removeprefix(f"{name}: ")
            kept = self.studio.session.view.target.label()
            self.studio.notify(event.client, "Target curve not loaded",
                               f"{name} was uploaded but is not a target curve: {problem}. "
                               f"The target is unchanged: {kept}.")
            return
        said = False
        note = curve.scale_note()
        if note:  # loaded (nothing is lost), with a word on its units
            self.studio.notify(event.client, "Target curve loaded: check its units", f"{name}: {note}.",
                               color="yellow")
            said = True
        rtclm = self.studio.session.view.design.mechanism.derive is not None  # its targets are heights
        note = "" if rtclm else curve.path_note(output)
        if note:  # loaded as drawn: a leg matching it would walk backward or stand on its swing
            self.studio.notify(event.client, "Target curve loaded: check its direction", f"{name}: {note}.",
                               color="yellow")
            said = True
        if leg:
            self.studio.notify(event.client, "Target curve read in the leg frame",
                               f"{name}: mapped to the design frame by the design's output stage "
                               f"({output_text(output)}); targets are kept in the design frame.", color="green")
        elif not said:  # QA (session 37): a good file got viser's "File uploaded successfully." alone
            timing = ("with times" if curve.times is not None else
                      "without times: compared with the design's path at the best phase")
            now = ("It was the target already." if self.studio.session.view.target == before else
                   "It is the target now; Undo takes it back.")  # the same file again changes nothing (review)
            self.studio.notify(event.client, "Target curve loaded", f"{name}: {len(curve.points)} points, {timing}. "
                               + now, color="green")
        self.studio.refresh(fit_camera=True)

    def _on_cycloid(self, event: viser.GuiEvent[Any]) -> None:
        self.studio.session.set_curve(None)
        self.studio.refresh(fit_camera=True)


def output_text(o: OutputStage) -> str:
    """The output stage in words: "identity", or its ratio, centre and mirror."""
    if o.is_identity:
        return "identity: the frames are the same"
    return o.describe()
