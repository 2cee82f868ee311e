"""The 3-D scene: the mechanism (design frame) and its bench trajectory (leg frame), side by side.

Nodes are created once and redrawn by assigning to their handles. All links of the
mechanism are one line-segment node; joints, pivots and the foot are point clouds. The
per-sample geometry of a design is precomputed once (:func:`build_frames`, pure) so the
animation thread only indexes arrays and assigns them.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import viser
from numpy.typing import NDArray

from core.kinematics.model import Ground
from studio import palette
from studio.geometry import (
    EDGE_CRANK,
    EDGE_GROUND,
    SCENE_SCALE,
    Composition,
    Layout,
    camera_pose,
    closed_polyline,
    compose,
    hold_last_valid,
    layout,
    link_edges,
    link_segments,
    to_scene,
)
from studio.state import DesignView
from studio.walking import WalkFrames

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

FOV = math.radians(40.0)
DEFAULT_ASPECT = 1.3
FPS = 40.0
# Lines and markers sit slightly above the grid so they never z-fight with it.
Z_LINES, Z_MARKERS = 0.0005, 0.001


@dataclass(frozen=True)
class SceneFrames:
    """Scene-ready geometry of one design (metres, float32).

    Attributes:
        links: ``(n_samples, n_edges, 2, 3)`` link segments per crank sample.
        link_colors: ``(n_edges, 2, 3)`` uint8 colour per segment end.
        joints: ``(n_samples, n_moving, 3)`` moving joints per sample.
        pivots: ``(n_ground, 3)`` ground pivots.
        pivot_names: names of the ground pivots.
        foot: ``(n_samples, 1, 3)`` tracked point, design frame.
        leg_foot: ``(n_samples, 1, 3)`` tracked point, leg frame (leg-view local coordinates).
        path, target: ``(m, 2, 3)`` design-frame path and target segments.
        leg_path, leg_target: ``(m, 2, 3)`` leg-frame path and target segments (leg-view local).
        leg_path_colors: ``(m, 2, 3)`` uint8: stance and swing in two colours (one colour without
            feature points).
        leg_axes: ``(k, 2, 3)`` leg-view frame: a border and the ground line y_g = y(t1).
        features: ``(n_features, 3)`` feature-point markers (leg-view local).
        feature_names: their labels (``t1``, ``t6=t7=t8``).
        layout: where the views sit (mm).
        marker: marker size (m), scaled with the drawing.
        composition: where the walking view and the candidates inset sit (mm).
        walk: the walking view's scene geometry, or None without a walking trajectory.
    """

    links: F32
    link_colors: U8
    joints: F32
    pivots: F32
    pivot_names: tuple[str, ...]
    foot: F32
    leg_foot: F32
    path: F32
    target: F32
    leg_path: F32
    leg_target: F32
    leg_path_colors: U8
    leg_axes: F32
    features: F32
    feature_names: tuple[str, ...]
    layout: Layout
    marker: float
    composition: Composition
    walk: WalkScene | None = None

    @property
    def n_samples(self) -> int:
        return int(self.links.shape[0])


@dataclass(frozen=True)
class WalkScene:
    """Scene-ready walking view (walk-local coordinates, metres; the /walk frame carries the offset).

    Attributes:
        body: ``(n_samples, 1 + n_legs, 2, 3)`` trunk and hip-to-foot legs per crank sample.
        body_colors: ``(1 + n_legs, 2, 3)`` uint8.
        feet: ``(n_samples, n_legs, 3)`` feet per crank sample; feet_colors ``(n_legs, 3)``.
        trails: ``(m, 2, 3)`` the feet's paths over one stride; trail_colors ``(m, 2, 3)``.
        ground: ``(1, 2, 3)`` the ground line; obstacle ``(4, 2, 3)`` the obstacle's outline.
        hit: a foot path enters the obstacle where it stands.
        text: h_m, h_bar, psi2, psi4 of the design.
        title_at, text_at: label positions (walk-local, m).
    """

    body: F32
    body_colors: U8
    feet: F32
    feet_colors: U8
    trails: F32
    trail_colors: U8
    ground: F32
    obstacle: F32
    hit: bool
    text: str
    title_at: tuple[float, float, float]
    text_at: tuple[float, float, float]


def walk_text(view: DesignView) -> str:
    """The walking metrics shown beside the walking view."""
    ev, (a, b) = view.evaluation, view.walk.obstacle
    return (f"hₘ {float(ev.h_m[0]):.1f} mm · h̄ {float(ev.h_bar[0]):.1f} mm · "
            f"ψ₂({a:g}, {b:g}) {100.0 * float(ev.psi2[0]):.1f} % · ψ₄({a:g}, {b:g}) {100.0 * float(ev.psi4[0]):.1f} %")


def build_walk_scene(wf: WalkFrames, view: DesignView) -> WalkScene:
    """Scene geometry of a walking view (pure)."""
    n_legs = wf.feet.shape[1]
    leg_rgb = np.array([palette.LEGS[j % len(palette.LEGS)] for j in range(n_legs)])
    body = np.concatenate([wf.trunk[:, None], wf.legs], axis=1)
    body_colors = np.repeat(vertex_colours(np.concatenate([[palette.TRUNK], leg_rgb]))[:, None, :], 2, axis=1)
    seg = np.stack([wf.trails[:, :-1], wf.trails[:, 1:]], axis=2)  # (n_legs, m - 1, 2, 2)
    trail_colors = np.repeat(np.repeat(vertex_colours(leg_rgb)[:, None, None, :], seg.shape[1], 1), 2, 2)
    x0, y0, x1, y1 = wf.bounds
    pad = 0.04 * (x1 - x0)
    ground = np.array([[[x0 - pad, wf.ground], [x1 + pad, wf.ground]]])
    r = wf.obstacle
    outline = np.stack([r, np.roll(r, -1, axis=0)], axis=1)
    return WalkScene(
        body=_lift(to_scene(body), Z_LINES),
        body_colors=body_colors,
        feet=_lift(to_scene(wf.feet), Z_MARKERS),
        feet_colors=vertex_colours(leg_rgb),
        trails=_lift(to_scene(seg.reshape(-1, 2, 2)), 0.5 * Z_LINES),
        trail_colors=trail_colors.reshape(-1, 2, 3),
        ground=to_scene(ground),
        obstacle=_lift(to_scene(outline), Z_LINES),
        hit=wf.hit,
        text=walk_text(view),
        title_at=((x0 - pad) * SCENE_SCALE, (y1 + 0.16 * (y1 - y0)) * SCENE_SCALE, 0.0),
        text_at=((x0 - pad) * SCENE_SCALE, (y1 + 0.02 * (y1 - y0)) * SCENE_SCALE, 0.0),
    )


def _lift(p: F32, z: float) -> F32:
    out = p.copy()
    out[..., 2] = z
    return out


def vertex_colours(rgb: NDArray[np.integer]) -> U8:
    """sRGB colours (0-255) for per-vertex colour arrays.

    viser converts a node's single colour from sRGB but passes per-vertex colours through as
    linear values, which then display lighter; converting here makes both look the same.
    """
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(lin * 255.0).astype(np.uint8)


def build_frames(view: DesignView) -> SceneFrames:
    """Precompute everything the scene draws for a design view (pure; no server)."""
    mech = view.design.mechanism
    sol = view.solution
    assert sol.joints is not None, "the studio solves with joints=True"
    joints = sol.joints[0]
    edges = link_edges(mech)
    colours = vertex_colours(np.array([palette.LINK, palette.CRANK, palette.GROUND]))
    kind_colour = np.where(edges.kinds[:, None] == EDGE_GROUND, 2, np.where(edges.kinds[:, None] == EDGE_CRANK, 1, 0))
    link_colors = np.repeat(colours[kind_colour[:, 0]][:, None, :], 2, axis=1)
    is_ground = np.array([isinstance(s, Ground) for s in mech.steps])
    point, leg = sol.point[0], sol.leg[0]
    lay = layout(np.concatenate([joints.reshape(-1, 2), view.target_design]), np.concatenate([leg, view.target_leg]))
    g = lay.leg
    pad = 0.06 * max(g[2] - g[0], g[3] - g[1])
    x0, y0, x1, y1 = g[0] - pad, g[1] - pad, g[2] + pad, g[3] + pad
    border = np.array([[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]], [[x0, y1], [x0, y0]]])
    # Ground line at the landing height y_g = y(t1) (spec §5); the x axis without feature points.
    y_g = view.features[0][1][1] if view.features else 0.0
    axis = np.array([[[x0, y_g], [x1, y_g]]]) if y0 < y_g < y1 else np.zeros((0, 2, 2))
    # Stance and swing colours per segment i -> i + 1, keeping only segments with finite ends.
    seg = np.stack([leg, np.roll(leg, -1, axis=0)], axis=1)
    keep = np.isfinite(seg).all(axis=(1, 2))
    stance = view.stance if view.stance is not None else np.ones(len(leg), dtype=bool)
    seg_colour = vertex_colours(np.where(stance[:, None], np.array(palette.STANCE), np.array(palette.SWING)))
    if view.stance is None:
        seg_colour[:] = vertex_colours(np.array(palette.PATH))
    feats = np.array([xy for _, xy in view.features], dtype=np.float64).reshape(-1, 2)
    extent = max(lay.scene[2] - lay.scene[0], lay.scene[3] - lay.scene[1])
    # viser needs finite arrays: where the mechanism does not assemble, hold its last assembled
    # pose; if it never assembles, collapse everything onto the first ground pivot.
    hold = hold_last_valid(sol.valid[0])
    if hold is None:
        pivot = np.nan_to_num(joints[0, int(np.argmax(is_ground))])
        pose = np.broadcast_to(pivot, joints.shape).copy()
        foot, leg_foot = pose[:, 0], np.broadcast_to(view.design.output.apply(pivot), leg.shape)
    else:
        pose, foot, leg_foot = joints[hold], point[hold], leg[hold]
    wf = view.walking
    return SceneFrames(
        links=_lift(to_scene(link_segments(pose, edges.pairs)), Z_LINES),
        link_colors=link_colors,
        joints=_lift(to_scene(pose[:, ~is_ground]), Z_MARKERS),
        pivots=_lift(to_scene(pose[0, is_ground]), Z_MARKERS),
        pivot_names=tuple(n for n, gnd in zip(mech.joint_names, is_ground, strict=True) if gnd),
        foot=_lift(to_scene(foot[:, None, :]), 2 * Z_MARKERS),
        leg_foot=_lift(to_scene(leg_foot[:, None, :]), 2 * Z_MARKERS),
        path=_lift(to_scene(closed_polyline(point)), Z_LINES),
        target=_lift(to_scene(closed_polyline(view.target_design)), Z_LINES),
        leg_path=_lift(to_scene(seg[keep]), Z_LINES),
        leg_target=_lift(to_scene(closed_polyline(view.target_leg)), Z_LINES),
        leg_path_colors=np.repeat(seg_colour[keep][:, None, :], 2, axis=1),
        leg_axes=to_scene(np.concatenate([border, axis])),
        features=_lift(to_scene(feats), Z_MARKERS),
        feature_names=tuple(name for name, _ in view.features),
        layout=lay,
        marker=0.01 * extent * SCENE_SCALE,
        composition=compose(lay, None if wf is None else wf.bounds),
        walk=None if wf is None else build_walk_scene(wf, view),
    )


def _set_segments(node: viser.LineSegmentsHandle, segments: F32, colors: U8 | None = None) -> None:
    """Assign segments (and per-segment colours); hide the node when there is nothing to draw."""
    node.visible = len(segments) > 0
    if len(segments):
        if colors is not None:
            node.colors = colors
        node.points = segments


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
        self.grid = scene.add_grid("/grid", width=4.0, height=4.0, plane="xy", cell_size=0.01, section_size=0.05,
                                   cell_color=(240, 240, 240), section_color=(218, 218, 218), shadow_opacity=0.0)
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
        self.design_title = scene.add_label("/design/title", "Mechanism (design frame)", anchor="bottom-left")
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
        self.leg_title = scene.add_label("/leg/title", "Bench trajectory (leg frame): stance, swing, target",
                                         anchor="bottom-left")
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
        self.walk_title = scene.add_label("/walk/title", "Walking (world frame): trunk, feet, obstacle a × b",
                                          anchor="bottom-left")
        self.walk_text = scene.add_label("/walk/metrics", "", anchor="bottom-left", font_screen_scale=0.85)

    @property
    def frames(self) -> SceneFrames | None:
        return self._frames

    def show(self, view: DesignView, index: int = 0) -> SceneFrames:
        """Redraw the static geometry of a new design view, then its crank sample ``index``."""
        frames = build_frames(view)
        lay = frames.layout
        with self._lock, self.server.atomic():
            self._frames = frames
            self._index = -1
            _set_segments(self.path, frames.path)
            _set_segments(self.target, frames.target)
            self.links.colors = frames.link_colors
            self.links.points = frames.links[index % frames.n_samples]
            for node, size in ((self.pivots, 1.3), (self.joints, 0.8), (self.foot, 1.1), (self.leg_foot, 1.1),
                               (self.leg_features, 0.5)):
                node.point_size = frames.marker * size
            self.pivots.points = frames.pivots
            top = lay.design[3] + 0.04 * (lay.scene[3] - lay.scene[1])
            self.design_title.position = (lay.design[0] * SCENE_SCALE, top * SCENE_SCALE, 0.0)
            self.leg.position = (lay.leg_offset[0] * SCENE_SCALE, lay.leg_offset[1] * SCENE_SCALE, 0.0)
            self.leg_axes.points = frames.leg_axes
            _set_segments(self.leg_target, frames.leg_target)
            _set_segments(self.leg_path, frames.leg_path, frames.leg_path_colors)
            self.leg_features.visible = len(frames.features) > 0
            if len(frames.features):
                self.leg_features.points = frames.features
            g = lay.leg
            pad = 0.06 * max(g[2] - g[0], g[3] - g[1])
            self.leg_title.position = ((g[0] - pad) * SCENE_SCALE, (g[3] + 1.4 * pad) * SCENE_SCALE, 0.0)
            self._show_walk(frames)
            self._show_labels(frames)
            self._draw(index)
        return frames

    def _show_walk(self, frames: SceneFrames) -> None:
        w = frames.walk
        for node in (self.walk_ground, self.walk_trails, self.walk_obstacle, self.walk_body, self.walk_feet,
                     self.walk_title, self.walk_text):
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
        self.walk_title.position = w.title_at
        self.walk_text.position = w.text_at
        self.walk_text.text = w.text

    def _show_labels(self, frames: SceneFrames) -> None:
        """Static labels: ground pivots (design view) and feature points (leg view)."""
        for label in self._labels:
            label.remove()
        off = 0.6 * frames.marker
        scene = self.server.scene
        self._labels = [
            scene.add_label(f"/design/pivot_labels/{name}", name, anchor="top-left",
                            position=(float(p[0]) + off, float(p[1]) - off, 0.0))
            for name, p in zip(frames.pivot_names, frames.pivots, strict=True)
        ] + [
            scene.add_label(f"/leg/feature_labels/{k}", name, anchor="bottom-center", font_screen_scale=0.85,
                            position=(float(p[0]), float(p[1]) + 0.5 * off, 0.0))
            for k, (name, p) in enumerate(zip(frames.feature_names, frames.features, strict=True))
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
        self._radius = 0.0
        empty_seg = np.zeros((1, 2, 3), dtype=np.float32)
        scene = server.scene
        self.border = scene.add_line_segments("/candidates/border", empty_seg, palette.FRAME, thickness=1.0,
                                              thickness_units="screen")
        self.front = scene.add_point_cloud("/candidates/front", np.zeros((1, 3), dtype=np.float32), palette.FEASIBLE,
                                           point_shape="circle", precision="float32", point_shading="flat")
        self.title = scene.add_label("/candidates/title", "Candidates: click one to pick it", anchor="bottom-left")
        self.note = scene.add_label("/candidates/note", "", anchor="top-left", font_screen_scale=0.8)

    def place(self, box: NDArray[np.float64], axes: str) -> None:
        """Draw the square ``[x0, y0, x1, y1]`` (mm) with its title and the axes' names."""
        x0, y0, x1, y1 = box
        corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        with self.server.atomic():
            self.border.points = to_scene(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
            self.title.position = (x0 * SCENE_SCALE, (y1 + 0.03 * (y1 - y0)) * SCENE_SCALE, 0.0)
            self.note.position = (x0 * SCENE_SCALE, (y0 - 0.03 * (y1 - y0)) * SCENE_SCALE, 0.0)
            self.note.text = axes
        self._radius = 0.022 * (x1 - x0) * SCENE_SCALE

    def show(self, markers: tuple[InsetMarker, ...], front: NDArray[np.float64], shown: int | None) -> None:
        """Show candidates (rebuilt when they change) and the front; colour the shown member."""
        with self._lock, self.server.atomic():
            if markers != self._markers:
                for h in self._spheres.values():
                    h.remove()
                for label in self._labels:
                    label.remove()
                self._spheres, self._labels = {}, []
                scene = self.server.scene
                for m in markers:
                    pos = (m.xy[0] * SCENE_SCALE, m.xy[1] * SCENE_SCALE, 2 * Z_MARKERS)
                    h = scene.add_icosphere(f"/candidates/pick_{m.member}", radius=self._radius, subdivisions=2,
                                            color=self._colour(m, shown), position=pos)
                    h.on_click(self._clicked(m.member))
                    self._spheres[m.member] = h
                    self._labels.append(scene.add_label(f"/candidates/tag_{m.member}", m.tag, anchor="bottom-center",
                                                        font_screen_scale=0.8,
                                                        position=(pos[0], pos[1] + 1.2 * self._radius, 0.0)))
                self._markers = markers
            else:
                for m in markers:
                    self._spheres[m.member].color = self._colour(m, shown)
            self.front.visible = len(front) > 0
            if len(front):
                self.front.point_size = 0.6 * self._radius
                self.front.points = _lift(to_scene(front), Z_MARKERS)

    @staticmethod
    def _colour(m: InsetMarker, shown: int | None) -> tuple[int, int, int]:
        if m.member == shown:
            return palette.FOOT
        return palette.KNEE if m.kind == "knee" else palette.BEST if m.kind == "best" else palette.PATH

    def _clicked(self, member: int) -> Callable[[viser.SceneNodePointerEvent[viser.IcosphereHandle]], None]:
        def handler(event: viser.SceneNodePointerEvent[viser.IcosphereHandle]) -> None:
            self.on_pick(member, event.client)

        return handler
