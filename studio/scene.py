"""The 3-D scene: the mechanism (design frame) and its bench trajectory (leg frame), side by side.

Nodes are created once and redrawn by assigning to their handles. All links of the
mechanism are one line-segment node; joints, pivots and the foot are point clouds. The
per-sample geometry of a design is precomputed once (:func:`build_frames`, pure) so the
animation thread only indexes arrays and assigns them.
"""

from __future__ import annotations

import threading

import numpy as np
import viser

from studio import palette
from studio.frames import DEFAULT_ASPECT, F32, FOV, U8, WALK_TITLE, SceneFrames, SceneText, build_frames
from studio.geometry import (
    SCENE_SCALE,
    camera_pose,
)
from studio.state import DesignView


def _set_segments(node: viser.LineSegmentsHandle, segments: F32, colors: U8 | None = None) -> None:
    """Assign segments (and per-segment colours); hide the node when there is nothing to draw."""
    node.visible = len(segments) > 0
    if len(segments):
        if colors is not None:
            node.colors = colors
        node.points = segments


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
        self.frames_pushed = 0
        scene = server.scene
        scene.set_up_direction("+y")
        empty_seg = np.zeros((1, 2, 3), dtype=np.float32)
        one = np.zeros((1, 3), dtype=np.float32)
        # Millimetre paper: plain lines sized to the views (viser's shader grid costs ~150 ms a frame under
        # software WebGL), with its spacing written in a corner as the scale.
        self.grid = scene.add_line_segments("/grid", empty_seg, palette.GRID, thickness=1.0, thickness_units="screen")
        self.grid_label = scene.add_label("/grid_label", "", anchor="top-left", font_size_mode="scene")
        # Every view's title, the walking metrics and the scale bars' labels, placed by the layout (in the scene's
        # units, so they keep clear of each other at any zoom); one millimetre scale bar under each view.
        self._texts: dict[str, viser.LabelHandle] = {}
        self.scale_bars = scene.add_line_segments("/scale_bars", empty_seg, palette.PIVOT, thickness=2.0,
                                                  thickness_units="screen")
        self.path = scene.add_line_segments("/design/path", empty_seg, palette.PATH, thickness=2.0,
                                            thickness_units="screen")
        self.target = scene.add_line_segments("/design/target", empty_seg, palette.TARGET, thickness=1.5,
                                              thickness_units="screen")
        self.links = scene.add_line_segments("/design/links", empty_seg, palette.LINK, thickness=4.0,
                                             thickness_units="screen")
        self.pivots = scene.add_point_cloud("/design/pivots", one, palette.PIVOT, point_shape="diamond",
                                            precision="float32", point_shading="flat")
        self.joints = scene.add_point_cloud("/design/joints", one, palette.JOINT, point_shape="circle",
                                            precision="float32", point_shading="flat")
        self.foot = scene.add_point_cloud("/design/foot", one, palette.FOOT, point_shape="circle",
                                          precision="float32", point_shading="flat")
        self.leg = scene.add_frame("/leg", show_axes=False)
        self.leg_axes = scene.add_line_segments("/leg/axes", empty_seg, palette.FRAME, thickness=1.0,
                                                thickness_units="screen")
        self.leg_target = scene.add_line_segments("/leg/target", empty_seg, palette.TARGET, thickness=2.0,
                                                  thickness_units="screen")
        self.leg_path = scene.add_line_segments("/leg/path", empty_seg, palette.PATH, thickness=3.0,
                                                thickness_units="screen")
        self.leg_features = scene.add_point_cloud("/leg/features", one, palette.PIVOT, point_shape="circle",
                                                  precision="float32", point_shading="flat")
        self.leg_foot = scene.add_point_cloud("/leg/foot", one, palette.FOOT, point_shape="circle",
                                              precision="float32", point_shading="flat")
        self.walk = scene.add_frame("/walk", show_axes=False)
        self.walk_ground = scene.add_line_segments("/walk/ground", empty_seg, palette.FRAME, thickness=1.5,
                                                   thickness_units="screen")
        self.walk_trails = scene.add_line_segments("/walk/trails", empty_seg, palette.FRAME, thickness=1.0,
                                                   thickness_units="screen")
        self.walk_obstacle = scene.add_line_segments("/walk/obstacle", empty_seg, palette.OBSTACLE_CLEAR,
                                                     thickness=3.0, thickness_units="screen")
        self.walk_body = scene.add_line_segments("/walk/body", empty_seg, palette.TRUNK, thickness=4.0,
                                                 thickness_units="screen")
        self.walk_feet = scene.add_point_cloud("/walk/feet", one, palette.FOOT, point_shape="circle",
                                               precision="float32", point_shading="flat")

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
            _set_segments(self.grid, frames.grid)
            b = frames.composition.bounds * SCENE_SCALE  # in the views' lower-left corner, inside the frame
            self.grid_label.position = (float(b[0]), float(b[1]), 0.0)
            self.grid_label.text = f"grid {frames.grid_step:g} mm"
            self.grid_label.font_scene_height = 0.7 * frames.text_height
            _set_segments(self.scale_bars, frames.scale_bars)
            self._show_texts(frames.texts)
            _set_segments(self.path, frames.path)
            _set_segments(self.target, frames.target)
            self.links.colors = frames.link_colors
            self.links.points = frames.links[index % frames.n_samples]
            for node, size in ((self.pivots, 1.3), (self.joints, 0.8), (self.foot, 1.1), (self.leg_foot, 1.1),
                               (self.leg_features, 0.5)):
                node.point_size = frames.marker * size
            self.pivots.points = frames.pivots
            self.leg.position = (lay.leg_offset[0] * SCENE_SCALE, lay.leg_offset[1] * SCENE_SCALE, 0.0)
            self.leg_axes.points = frames.leg_axes
            _set_segments(self.leg_target, frames.leg_target)
            _set_segments(self.leg_path, frames.leg_path, frames.leg_path_colors)
            self.leg_features.visible = len(frames.features) > 0
            if len(frames.features):
                self.leg_features.points = frames.features
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
        self.walk_ground.points = w.ground
        self.walk_trails.colors = w.trail_colors
        self.walk_trails.points = w.trails
        self.walk_obstacle.colors = np.array(palette.OBSTACLE_HIT if w.hit else palette.OBSTACLE_CLEAR, dtype=np.uint8)
        self.walk_obstacle.points = w.obstacle
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
        """Static labels: ground pivots (design view) and feature points (leg view)."""
        for label in self._labels:
            label.remove()
        off = 0.6 * frames.marker
        scene = self.server.scene
        small = 0.8 * frames.text_height
        self._labels = [
            scene.add_label(f"/design/pivot_labels/{name}", name, anchor="top-left", font_size_mode="scene",
                            font_scene_height=small, position=(float(p[0]) + off, float(p[1]) - off, 0.0))
            for name, p in zip(frames.pivot_names, frames.pivots, strict=True)
        ] + [
            scene.add_label(f"/leg/feature_labels/{k}", t.text, anchor=t.anchor,  # type: ignore[arg-type]
                            font_size_mode="scene", font_scene_height=t.height, position=t.position)
            for k, t in enumerate(frames.feature_labels)
        ]

    def _draw(self, index: int) -> None:
        f = self._frames
        if f is None:
            return
        i = index % f.n_samples
        self.links.points = f.links[i]
        self.joints.points = f.joints[i]
        self.foot.points = f.foot[i]
        self.leg_foot.points = f.leg_foot[i]
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

    def fit_camera(self, client: viser.ClientHandle | None = None, aspect: float = DEFAULT_ASPECT) -> None:
        """Frame both views: the server's initial camera, or one client's camera."""
        f = self._frames
        if f is None:
            return
        pos, look = camera_pose(f.composition.bounds, FOV, aspect)
        if client is None:
            cam = self.server.initial_camera
            cam.fov = FOV
            cam.up = (0.0, 1.0, 0.0)
            cam.look_at = look
            cam.position = pos
            return
        # Up direction and field of view come from the initial camera; only move the view.
        with client.atomic():
            client.camera.position = pos
            client.camera.look_at = look


