"""The animation clock, and the inset that shows a stage's candidates as spheres the user can click."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import viser
from numpy.typing import NDArray

from studio import palette
from studio.frames import FPS, INSET_TITLE, SMALL_TEXT, Z_MARKERS, _lift, marker_texts, paint
from studio.geometry import (
    SCENE_SCALE,
    to_scene,
)


class Animator:
    """A worker thread that advances playback and redraws at ``fps``; stopped by an event.

    Args:
        tick: called with the elapsed seconds since the previous tick; does the work of a frame.
        fps: target frame rate.
    """

    def __init__(self, tick: Callable[[float], None], fps: float = FPS) -> None:
        self._tick = tick
        self._period = 1.0 / fps
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="clm-studio-animator", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def _run(self) -> None:
        last = time.perf_counter()
        next_at = last
        while not self._stop.is_set():
            now = time.perf_counter()
            try:
                self._tick(now - last)
            except Exception as exc:  # noqa: BLE001 - a bad frame must not kill the animation
                print(f"clm-studio: animation frame failed: {exc!r}")
            last = now
            next_at = max(next_at + self._period, time.perf_counter())
            self._stop.wait(max(0.0, next_at - time.perf_counter()))


@dataclass(frozen=True)
class InsetMarker:
    """A clickable candidate in the scene's inset: member, tag (``K1``), kind, position (mm, scene)."""

    member: int
    tag: str
    kind: str
    xy: tuple[float, float]


class CandidateInset:
    """The candidates of the shown stage as clickable spheres in a square beside the bench trajectory.

    The square is the first two objectives (min-max scaled); grey dots are the rest of the front.
    Clicking a sphere calls ``on_pick(member, client)``.
    """

    def __init__(self, server: viser.ViserServer, on_pick: Callable[[int, viser.ClientHandle], None]) -> None:
        self.server = server
        self.on_pick = on_pick
        self._lock = threading.Lock()
        self._markers: tuple[InsetMarker, ...] = ()
        self._spheres: dict[int, viser.IcosphereHandle] = {}
        self._labels: list[viser.LabelHandle] = []
        self._labelled: tuple[tuple[InsetMarker, ...], int | None, float, float] | None = None  # labels placed for
        self._radius = 0.0
        empty_seg = np.zeros((1, 2, 3), dtype=np.float32)
        scene = server.scene
        # per-vertex colours, as every line and point cloud (studio.frames.paint)
        self.border = scene.add_line_segments("/candidates/border", empty_seg, paint(empty_seg, palette.FRAME),
                                              thickness=1.0, thickness_units="screen")
        one = np.zeros((1, 3), dtype=np.float32)
        self.front = scene.add_point_cloud("/candidates/front", one, paint(one, palette.FEASIBLE), point_shape="circle",
                                           precision="float32", point_shading="flat")
        self.title = scene.add_label("/candidates/title", INSET_TITLE, anchor="bottom-left", font_size_mode="scene")
        self.note = scene.add_label("/candidates/note", "", anchor="top-left", font_size_mode="scene")
        self._text_height = 0.0

    def place(self, box: NDArray[np.float64], axes: str, text_height: float) -> None:
        """Draw the square ``[x0, y0, x1, y1]`` (mm) with its title and the axes' names, in labels
        ``text_height`` m high (where the scene's layout left room for them)."""
        x0, y0, x1, y1 = box
        h = text_height / SCENE_SCALE
        corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        with self.server.atomic():
            border = to_scene(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
            self.border.colors = paint(border, palette.FRAME)
            self.border.points = border
            self.title.position = (x0 * SCENE_SCALE, (y1 + 0.6 * h) * SCENE_SCALE, 0.0)
            self.title.font_scene_height = text_height
            self.note.position = (x0 * SCENE_SCALE, (y0 - 0.6 * SMALL_TEXT * h) * SCENE_SCALE, 0.0)
            self.note.font_scene_height = SMALL_TEXT * text_height
            self.note.text = axes
        self._text_height = text_height
        self._radius = 0.032 * (x1 - x0) * SCENE_SCALE  # ~9 px across in a 1400 x 900 page

    def show(self, markers: tuple[InsetMarker, ...], front: NDArray[np.float64], shown: int | None) -> None:
        """Show candidates (rebuilt when they change) and the front; colour the shown member, whose label is placed
        first (it kept none when its neighbours' labels took every spot around it; QA session 38)."""
        with self._lock, self.server.atomic():
            scene = self.server.scene
            if markers != self._markers:
                for h in self._spheres.values():
                    h.remove()
                self._spheres = {}
                for m in markers:
                    pos = (m.xy[0] * SCENE_SCALE, m.xy[1] * SCENE_SCALE, 2 * Z_MARKERS)
                    # Toon material, no shadows: the standard (PBR) shader takes ~3.5 s to compile under
                    # software WebGL, and the page would freeze the first time candidates appear.
                    h = scene.add_icosphere(f"/candidates/pick_{m.member}", radius=self._radius, subdivisions=2,
                                            color=self._colour(m, shown), position=pos, material="toon3",
                                            cast_shadow=False, receive_shadow=False)
                    h.on_click(self._clicked(m.member))
                    self._spheres[m.member] = h
                self._markers = markers
            else:
                for m in markers:
                    self._spheres[m.member].color = self._colour(m, shown)
            first = shown if any(m.member == shown for m in markers) else None
            key = (markers, first, self._text_height, self._radius)  # place() may change the last two
            if key != self._labelled:
                for label in self._labels:
                    label.remove()
                self._labels = []
                order = sorted(markers, key=lambda m: m.member != first)  # stable: K1 first after the shown one
                tags = marker_texts(tuple((m.tag, m.xy) for m in order), 0.8 * self._text_height / SCENE_SCALE,
                                    self._radius / SCENE_SCALE)
                for m, tag in zip(order, tags, strict=True):
                    if tag is not None:  # no free spot: the sphere alone (the Pick panel lists it)
                        self._labels.append(scene.add_label(f"/candidates/tag_{m.member}", tag.text,
                                                            anchor=tag.anchor,  # type: ignore[arg-type]
                                                            font_size_mode="scene", font_scene_height=tag.height,
                                                            position=tag.position))
                self._labelled = key
            self.front.visible = len(front) > 0
            if len(front):
                self.front.point_size = 0.6 * self._radius
                pts = _lift(to_scene(front), Z_MARKERS)
                self.front.colors = paint(pts, palette.FEASIBLE)
                self.front.points = pts

    @staticmethod
    def _colour(m: InsetMarker, shown: int | None) -> tuple[int, int, int]:
        if m.member == shown:
            return palette.FOOT
        return palette.KNEE if m.kind == "knee" else palette.BEST if m.kind == "best" else palette.PATH

    def _clicked(self, member: int) -> Callable[[viser.SceneNodePointerEvent[viser.IcosphereHandle]], None]:
        def handler(event: viser.SceneNodePointerEvent[viser.IcosphereHandle]) -> None:
            self.on_pick(member, event.client)

        return handler
