"""Walking panel: biped module or quadruped, the obstacle's size (a, b) and where it stands, and the
walking metrics h_m, h_bar, psi2, psi4 (their obstacle is this one)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from core.kinematics.checks import MAX_ABS
from studio.frames import walk_text
from studio.panels._inputs import NumberFields, NumberForm, set_value
from studio.state import DesignView, leg_step

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

ROBOTS = {"biped module (ψ₂)": "biped", "quadruped (ψ₄)": "quadruped"}


SIDE = NumberForm(lo=0.0, hi=MAX_ABS, unit="mm")  # an obstacle side, as the model takes it
OUT_OF_SCALE = 10.0  # an obstacle this many times the leg's step (length or height) is a units mistake, not a test


def obstacle_note(key: str, value: float, view: DesignView) -> str | None:
    """A word on an obstacle side ``key`` (``a`` or ``b``, mm) more than ``OUT_OF_SCALE`` times the target's step
    (:func:`studio.state.leg_step`, which sizes the walking view), or None. QA (session 37): b = 5000 mm for a
    300 x 100 mm step went in silently, and the views shrank to specks around it."""
    step = leg_step(view.design.mechanism.name, view.target)
    side, scale = (0, "length") if key == "a" else (1, "height")
    ref = step[side]
    if not (ref > 0.0 and value > OUT_OF_SCALE * ref):
        return None
    what = "no foot steps over it" if key == "b" else "it spans many strides"
    return (f"obstacle {key} = {value:g} mm is {value / ref:.0f} times the target's step {scale} ({ref:g} mm): {what}, "
            "and the views shrink around it. Values are in mm.")


class WalkingPanel:
    """Robot dropdown, obstacle a and b, obstacle place slider, and a status line."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        walk = studio.session.view.walk
        self._numbers = NumberFields(studio)
        self.folder = gui.add_folder("Walking and obstacle", order=order, expand_by_default=False)
        with self.folder:
            self.robot = gui.add_dropdown("Robot", tuple(ROBOTS), initial_value=self._robot_label(walk.layout),
                                          hint="legs drawn in the walking view")
            self.a = self._numbers.add("a", "Obstacle a [mm]", float(walk.a), form=SIDE,
                                       apply=self._setter("a"), current=self._getter("a"), what="obstacle a",
                                       hint="obstacle length", size_note=self._size_note("a"))
            self.b = self._numbers.add("b", "Obstacle b [mm]", float(walk.b), form=SIDE,
                                       apply=self._setter("b"), current=self._getter("b"), what="obstacle b",
                                       hint="obstacle height", size_note=self._size_note("b"))
            self.place = gui.add_slider("Obstacle place [%]", 0.0, 100.0, 1.0, 100.0 * float(walk.place),
                                        hint="where the obstacle stands within one stride")
            self.status = gui.add_markdown("")
        self.robot.on_update(self._on_robot)
        self.place.on_update(self._on_place)
        self.show(studio.session.view)

    @staticmethod
    def _robot_label(layout: str) -> str:
        return next(k for k, v in ROBOTS.items() if v == layout)

    def _setter(self, key: str) -> Callable[[float], object]:
        return lambda v: self.studio.session.set_walk(**{key: float(v)})

    def _getter(self, key: str) -> Callable[[], float]:
        return lambda: float(getattr(self.studio.session.view.walk, key))

    def _size_note(self, key: str) -> Callable[[float], str | None]:
        return lambda v: obstacle_note(key, v, self.studio.session.view)

    def close(self) -> None:
        self._numbers.cancel_all()

    def show(self, view: DesignView) -> None:
        w = view.walk
        set_value(self.robot, self._robot_label(w.layout))
        self.a.show(float(w.a))
        self.b.show(float(w.b))
        set_value(self.place, round(100.0 * float(w.place)))
        if view.walking is None:
            self.status.content = "No walking trajectory: the bench trajectory is not well defined."
            return
        crossed = "**blocked** (a foot path enters it)" if view.walking.hit else "crossed"
        self.status.content = f"{walk_text(view)}  \nObstacle at this place: {crossed}."

    def _on_robot(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        self.studio.session.set_walk(layout=ROBOTS[str(self.robot.value)])
        self.studio.refresh()

    def _on_place(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        self.studio.session.set_walk(place=min(1.0, max(0.0, float(self.place.value) / 100.0)))
        self.studio.refresh()
