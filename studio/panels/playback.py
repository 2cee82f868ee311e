"""Playback panel: play/pause, speed, and a crank-angle slider to scrub the cycle."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from core.kinematics.solver import Solution
from studio.geometry import frame_index, hold_last_valid
from studio.panels._inputs import set_value
from studio.state import MAX_SPEED, Playback

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

# While playing, the angle readout follows the animation at this rate (GUI messages are broadcast to every
# client, so not at the frame rate). The slider itself stays still while playing: a value pushed into its
# number box while someone types there overwrote what they typed (issue 13, item 11).
SLIDER_SYNC_PERIOD = 0.25


def held_pose_note(solution: Solution, angle: float) -> str:
    """What the readout adds where the design does not assemble at crank ``angle`` (rad): the scene draws its last
    assembled pose there, which read as the pose at the angle shown (QA, session 38: Klann at 166° drawn at 107°
    in its usual colours, unsaid)."""
    valid = np.asarray(solution.valid[0], dtype=bool)
    i = frame_index(angle, len(valid))
    hold = hold_last_valid(valid)
    if valid[i] or hold is None:
        return ""
    return f" · it does not assemble here: drawn at {math.degrees(float(solution.theta[hold[i]])):.0f}°"


class PlaybackPanel:
    """Play/pause button, speed slider, crank-angle slider (degrees)."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        pb = studio.session.playback
        self._last_sync = 0.0
        self.folder = gui.add_folder("Playback", order=order)
        with self.folder:
            self.play = gui.add_button(self._play_label(pb), hint="start or stop the animation")
            self.speed = gui.add_slider("Speed [x]", 0.1, MAX_SPEED, 0.1, float(pb.speed),
                                        hint="1 = one crank revolution per target period T")
            self.angle = gui.add_slider("Crank angle [deg]", 0.0, 359.0, 1.0, self._degrees(pb),
                                        hint="input crank angle theta; dragging it or typing a value pauses the "
                                             "animation there")
            self.now = gui.add_markdown(self._readout(pb))
        self.play.on_click(self._on_play)
        self.speed.on_update(self._on_speed)
        self.angle.on_update(self._on_angle)

    @staticmethod
    def _play_label(pb: Playback) -> str:
        return "Pause" if pb.playing else "Play"

    @staticmethod
    def _degrees(pb: Playback) -> float:
        return float(round(math.degrees(pb.angle)) % 360)

    def _readout(self, pb: Playback, held: bool = False) -> str:
        state = "held while the stage runs" if held and pb.playing else "playing" if pb.playing else "paused"
        text = f"θ = {self._degrees(pb):.0f}° ({state})"
        return text + held_pose_note(self.studio.session.view.solution, pb.angle)

    def show(self, pb: Playback, held: bool = False) -> None:
        """Mirror the playback state into the controls (the slider only while paused: see SLIDER_SYNC_PERIOD);
        ``held``: the animation holds still while a stage runs (``Studio.held``)."""
        self.play.label = self._play_label(pb)
        set_value(self.speed, float(pb.speed))
        if not pb.playing:
            set_value(self.angle, self._degrees(pb))
        self._show_readout(pb, held)

    def _show_readout(self, pb: Playback, held: bool = False) -> None:
        text = self._readout(pb, held)
        if self.now.content != text:
            self.now.content = text

    def tick(self, pb: Playback) -> None:
        """Called by the animator every frame: keep the readout roughly in step while playing."""
        now = time.monotonic()
        if pb.playing and now - self._last_sync >= SLIDER_SYNC_PERIOD:
            self._last_sync = now
            self._show_readout(pb)

    def _on_play(self, event: viser.GuiEvent[Any]) -> None:
        session = self.studio.session
        with session.lock:
            pb = session.set_playing(not session.playback.playing)
        self.show(pb, self.studio.held())
        self.studio.autosave()

    def _on_speed(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        try:
            self.studio.session.set_speed(float(self.speed.value))
        except ValueError as exc:
            set_value(self.speed, float(self.studio.session.playback.speed))
            # The slider rounds a typed 0.05 to its 0.1 steps and sends 0.0: "got 0.0" alone puzzled.
            self.studio.notify(event.client, "Speed not changed",
                               f"{exc}; the slider takes {self.speed.min:g} to {self.speed.max:g} in steps of "
                               f"{self.speed.step:g}")

    def _on_angle(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        deg = float(self.angle.value)
        pb = self.studio.session.scrub(math.radians(deg))
        self.play.label = self._play_label(pb)
        self._show_readout(pb)
        # The animation may have sent the slider a position after this page's edit left: send the typed angle
        # again (viser sends only changes, and the server already holds it), so every page ends on it.
        set_value(self.angle, deg + 1e-6)
        set_value(self.angle, deg)
