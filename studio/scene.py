"""The 3-D scene: the mechanism (design frame) and its bench trajectory (leg frame), side by side.

Nodes are created once and redrawn by assigning to their handles. All links of the
mechanism are one line-segment node; joints, pivots and the foot are point clouds. The
per-sample geometry of a design is precomputed once (:func:`build_frames`, pure) so the
animation thread only indexes arrays and assigns them.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import viser

from studio import palette
from studio.frames import (
    DEFAULT_ASPECT,
    F32,
    FOV,
    U8,
    WALK_TITLE,
    SceneFrames,
    SceneText,
    build_frames,
    joint_label_spots,
    label_box,
    paint,
    pivot_label_spots,
)
from studio.geometry import (
    F64,
    SCENE_SCALE,
    camera_pose,
)
from studio.state import DesignView

FAR = 1000.0  # viser's far clipping plane (scene units, m); raised for a scene too large for it


def _set_segments(node: viser.LineSegmentsHandle, segments: F32, colors: U8 | tuple[int, int, int]) -> None:
    """Assign segments and their colours (per vertex, or one for all: painted per vertex); hide the node when
    there is nothing to draw."""
    node.visible = len(segments) > 0
    if len(segments):
        node.colors = paint(segments, colors) if isinstance(colors, tuple) else colors
        node.points = segments


def _set_points(node: viser.PointCloudHandle | viser.LineSegmentsHandle, points: F32,
                rgb: tuple[int, int, int]) -> None:
    node.colors = paint(points, rgb)
    node.points = points


__all__ = ["WALK_TITLE", "MechanismScene"]


class MechanismScene:
    """Owns the scene nodes; ``show`` a design view, then ``draw`` crank samples of it.

    Both calls may come from different threads (GUI callbacks, the animator): a lock keeps
    the frames and the nodes consistent, and each redraw is one short ``atomic`` block.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._lock = threading.Lock()
        self._frames: SceneFrames | None = None
        self._index = -1
        self._labels: list[viser.LabelHandle] = []
        # The moving joints are named only while the animation is paused (lab rehearsal: the tooltips say "BC"
        # and the scene named only A and D); moving labels every frame would cost lag on software rendering.
        self._joint_labels: list[viser.LabelHandle] = []
        self._named = False
        self._label_height = 0.0
        self._pivot_boxes: tuple[tuple[float, float, float, float], ...] = ()
        self.frames_pushed = 0
        scene = server.scene
        scene.set_up_direction("+y")
        empty_seg = np.zeros((1, 2, 3), dtype=np.float32)
        one = np.zeros((1, 3), dtype=np.float32)

        def lines(name: str, rgb: tuple[int, int, int], thickness: float) -> viser.LineSegmentsHandle:
            return scene.add_line_segments(name, empty_seg, paint(empty_seg, rgb), thickness=thickness,
                                           thickness_units="screen")

        def points(name: str, rgb: tuple[int, int, int], shape: Any) -> viser.PointCloudHandle:
            return scene.add_point_cloud(name, one, paint(one, rgb), point_shape=shape, precision="float32",
                                         point_shading="flat")

        # Millimetre paper: plain lines sized to the views (viser's shader grid costs ~150 ms a frame under
        # software WebGL), with its spacing written in a corner as the scale.
        self.grid = lines("/grid", palette.GRID, 1.0)
        self.grid_label = scene.add_label("/grid_label", "", anchor="top-left", font_size_mode="scene")
        # Every view's title, the walking metrics and the scale bars' labels, placed by the layout (in the scene's
        # units, so they keep clear of each other at any zoom); one millimetre scale bar under each view.
        self._texts: dict[str, viser.LabelHandle] = {}
        self.scale_bars = lines("/scale_bars", palette.PIVOT, 2.0)
        self.path = lines("/design/path", palette.PATH, 2.0)
        self.target = lines("/design/target", palette.TARGET, 1.5)
        self.links = lines("/design/links", palette.LINK, 4.0)
        self.pivots = points("/design/pivots", palette.PIVOT, "diamond")
        self.joints = points("/design/joints", palette.JOINT, "circle")
        self.foot = points("/design/foot", palette.FOOT, "circle")
        self.leg = scene.add_frame("/leg", show_axes=False)
        self.leg_axes = lines("/leg/axes", palette.FRAME, 1.0)
        self.leg_target = lines("/leg/target", palette.TARGET, 2.0)
        self.leg_path = lines("/leg/path", palette.PATH, 3.0)
        self.leg_features = points("/leg/features", palette.PIVOT, "circle")
        self.leg_foot = points("/leg/foot", palette.FOOT, "circle")
        self.walk = scene.add_frame("/walk", show_axes=False)
        self.walk_ground = lines("/walk/ground", palette.FRAME, 1.5)
        self.walk_trails = lines("/walk/trails", palette.FRAME, 1.0)
        self.walk_obstacle = lines("/walk/obstacle", palette.OBSTACLE_CLEAR, 3.0)
        self.walk_body = lines("/walk/body", palette.TRUNK, 4.0)
        self.walk_feet = points("/walk/feet", palette.FOOT, "circle")

    @property
    def frames(self) -> SceneFrames | None:
        return self._frames

    def show(self, view: DesignView, index: int = 0, show_target: bool = True) -> SceneFrames:
        """Redraw the static geometry of a new design view (with its target if a stage optimizes it), then its
        crank sample ``index``."""
        frames = build_frames(view, show_target)
        lay = frames.layout
        with self._lock, self.server.atomic():
            self._frames = frames
            self._index = -1
            _set_segments(self.grid, frames.grid, palette.GRID)
            b = frames.composition.bounds * SCENE_SCALE  # in the views' lower-left corner, inside the frame
            self.grid_label.position = (float(b[0]), float(b[1]), 0.0)
            self.grid_label.text = f"grid {frames.grid_step:g} mm"
            self.grid_label.font_scene_height = 0.7 * frames.text_height
            _set_segments(self.scale_bars, frames.scale_bars, palette.PIVOT)
            self._show_texts(frames.texts)
            _set_segments(self.path, frames.path, palette.PATH)
            _set_segments(self.target, frames.target, palette.TARGET)
            self.links.colors = frames.link_colors
            self.links.points = frames.links[index % frames.n_samples]
            for node, size in ((self.pivots, 1.3), (self.joints, 0.8), (self.foot, 1.1), (self.leg_foot, 1.1),
                               (self.leg_features, 0.5)):
                node.point_size = frames.marker * size
            _set_points(self.pivots, frames.pivots, palette.PIVOT)
            for node, rgb, moving in ((self.joints, palette.JOINT, frames.joints),
                                      (self.foot, palette.FOOT, frames.foot),
                                      (self.leg_foot, palette.FOOT, frames.leg_foot)):
                node.colors = paint(moving[0], rgb)  # as many as the design has: _draw sets the points only
            self.foot.visible = self.leg_foot.visible = frames.posed  # no foot where it never assembles
            self.leg.position = (lay.leg_offset[0] * SCENE_SCALE, lay.leg_offset[1] * SCENE_SCALE, 0.0)
            _set_points(self.leg_axes, frames.leg_axes, palette.FRAME)
            _set_segments(self.leg_target, frames.leg_target, palette.TARGET)
            _set_segments(self.leg_path, frames.leg_path, frames.leg_path_colors)
            self.leg_features.visible = len(frames.features) > 0
            if len(frames.features):
                _set_points(self.leg_features, frames.features, palette.PIVOT)
            self._show_walk(frames)
            self._show_labels(frames)
            self._draw(index)
        return frames

    def _show_walk(self, frames: SceneFrames) -> None:
        w = frames.walk
        for node in (self.walk_ground, self.walk_trails, self.walk_obstacle, self.walk_body, self.walk_feet):
            node.visible = w is not None
        if w is None:
            return
        off = frames.composition.walk_offset
        self.walk.position = (off[0] * SCENE_SCALE, off[1] * SCENE_SCALE, 0.0)
        _set_points(self.walk_ground, w.ground, palette.FRAME)
        self.walk_trails.colors = w.trail_colors
        self.walk_trails.points = w.trails
        _set_points(self.walk_obstacle, w.obstacle,
                    palette.OBSTACLE_HIT if w.hit else palette.OBSTACLE_CLEAR)
        self.walk_body.colors = w.body_colors
        self.walk_feet.point_size = frames.marker * 1.1
        self.walk_feet.colors = w.feet_colors

    def _show_texts(self, texts: tuple[SceneText, ...]) -> None:
        """Place the layout's labels: existing nodes are moved, missing ones made, unused ones hidden."""
        used = set()
        for t in texts:
            if t.key.startswith("inset_"):  # the candidates inset draws its own title and note (the layout's room)
                continue
            used.add(t.key)
            node = self._texts.get(t.key)
            if node is None:
                self._texts[t.key] = self.server.scene.add_label(
                    f"/texts/{t.key}", t.text, position=t.position, anchor=t.anchor,  # type: ignore[arg-type]
                    font_size_mode="scene", font_scene_height=t.height)
                continue
            node.text, node.position, node.font_scene_height, node.visible = t.text, t.position, t.height, True
        for key, node in self._texts.items():
            if key not in used:
                node.visible = False

    def _show_labels(self, frames: SceneFrames) -> None:
        """Static labels: ground pivots (design view) and feature points (leg view); the moving joints' labels,
        shown while paused."""
        for label in (*self._labels, *self._joint_labels):
            label.remove()
        off = 0.6 * frames.marker
        scene = self.server.scene
        small = 0.8 * frames.text_height
        spots = pivot_label_spots(frames.pivot_names, frames.pivots, frames.links, small, off)
        self._label_height = small
        self._pivot_boxes = tuple(label_box(name, xyz, anchor, small)
                                  for name, (xyz, anchor) in zip(frames.pivot_names, spots, strict=True))
        self._labels = [
            scene.add_label(f"/design/pivot_labels/{name}", name, anchor=anchor,  # type: ignore[arg-type]
                            font_size_mode="scene", font_scene_height=small, position=(x, y, 0.0))
            for name, ((x, y, _), anchor) in zip(frames.pivot_names, spots, strict=True)
        ] + [
            scene.add_label(f"/leg/feature_labels/{k}", t.text, anchor=t.anchor,  # type: ignore[arg-type]
                            font_size_mode="scene", font_scene_height=t.height, position=t.position)
            for k, t in enumerate(frames.feature_labels)
        ]
        self._joint_labels = [
            scene.add_label(f"/design/joint_labels/{name}", name, anchor="bottom-left", font_size_mode="scene",
                            font_scene_height=small, visible=self._named)
            for name in frames.joint_names
        ]

    def _place_joint_labels(self, i: int) -> None:
        f = self._frames
        if f is None or not self._named or not self._joint_labels:
            return
        spots = joint_label_spots(f.joint_names, f.joints[i], f.links[i], self._label_height, 0.6 * f.marker,
                                  self._pivot_boxes)
        for label, (position, anchor) in zip(self._joint_labels, spots, strict=True):
            label.position, label.anchor = position, anchor  # type: ignore[assignment]

    def name_joints(self, on: bool) -> None:
        """Show the moving joints' names at the current pose (the animation paused), or hide them (playing)."""
        with self._lock:
            if on == self._named:
                return
            self._named = on
            with self.server.atomic():
                for label in self._joint_labels:
                    label.visible = on
                if self._index >= 0:
                    self._place_joint_labels(self._index)

    def _draw(self, index: int) -> None:
        f = self._frames
        if f is None:
            return
        i = index % f.n_samples
        self.links.points = f.links[i]
        self.joints.points = f.joints[i]
        self.foot.points = f.foot[i]
        self.leg_foot.points = f.leg_foot[i]
        self._place_joint_labels(i)
        if f.walk is not None:
            self.walk_body.points = f.walk.body[i]
            self.walk_feet.points = f.walk.feet[i]
        self._index = i
        self.frames_pushed += 1

    def draw(self, index: int) -> bool:
        """Pose the mechanism at crank sample ``index``; False if nothing had to change."""
        with self._lock:
            f = self._frames
            if f is None or index % f.n_samples == self._index:
                return False
            with self.server.atomic():
                self._draw(index)
            return True

    def record_html(self, period: float, fps: float = 30.0) -> str:
        """A self-contained HTML page replaying one crank revolution of the current design (viser's
        scene serializer with its bundled client: works offline).

        Args:
            period: seconds per revolution in the recording.
            fps: recorded frames per second.
        """
        with self._lock:
            f = self._frames
            if f is None:
                raise ValueError("nothing to record yet")
            n_frames = max(2, min(f.n_samples, int(round(period * fps))))
            serializer = self.server.get_scene_serializer()
            index = self._index
            try:
                for k in range(n_frames):
                    with self.server.atomic():
                        self._draw(int(round(k * f.n_samples / n_frames)))
                    serializer.insert_sleep(period / n_frames)
            except BaseException:
                serializer.serialize()  # stop recording
                raise
            finally:
                with self.server.atomic():
                    self._draw(index)
            return serializer.as_html()

    def fit_camera(self, client: viser.ClientHandle | None = None,
                   aspect: float = DEFAULT_ASPECT) -> F64 | None:
        """Frame both views: the server's initial camera, or one client's camera; the camera position set."""
        f = self._frames
        if f is None:
            return None
        pos, look = camera_pose(f.composition.bounds, FOV, aspect)
        # Past viser's default far plane (1000 m) nothing is drawn: a 300 m target (a file in um) blanked the page.
        far = max(FAR, 4.0 * float(np.linalg.norm(np.asarray(pos) - np.asarray(look))))
        if client is None:
            cam = self.server.initial_camera
            cam.fov = FOV
            cam.up = (0.0, 1.0, 0.0)
            cam.look_at = look
            cam.position = pos
            if cam.far != far:  # each assignment is a message to every page
                cam.far = far
            return pos
        # Up direction and field of view come from the initial camera; only move the view.
        with client.atomic():
            client.camera.position = pos
            client.camera.look_at = look
            client.camera.far = far
        return pos


