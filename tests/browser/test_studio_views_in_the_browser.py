"""The scene's views, the per-mechanism targets and the bench chart in the browser (issue 13, items 7, 8, 9, 10).

Item 7: whatever the mechanism, the page's camera shows every view whole (nothing drawn at the canvas edges,
nothing cut by the control panel), no view's title, labels or scale bar runs into another's, and every view has a
millimetre scale bar. Item 8: Klann comes with a target of its own size; RTCLM shows no target unless one of its
stages optimizes one, and the Target panel says which. Item 9: a flat bench path keeps a chart with equal scales,
height, readable ticks and drawn curves. Item 10: coincident feature points share one label; the walking metrics
sit above the trunk.
"""

from __future__ import annotations

import io
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import choose, expand, field, load_session, wait_for

RTCLM = "RTCLM, primary mode (Watt-I six-bar driven at A)"
# Everything drawn in the scene is darker than this (links, paths, text); the grid and frames are lighter.
INK = 150

BENCH_JS = """() => {
  const svg = document.querySelector('svg.clm-bench');
  if (!svg) return null;
  const box = e => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; };
  const plot = svg.querySelector('rect.plot').getBoundingClientRect();
  const traces = {};
  for (const line of svg.querySelectorAll('polyline[data-name]')) {
    const t = traces[line.dataset.name] || (traces[line.dataset.name] = {name: line.dataset.name, x: [], y: []});
    if (t.x.length) { t.x.push(null); t.y.push(null); }
    for (const pt of line.getAttribute('points').trim().split(/\\s+/)) {
      const [x, y] = pt.split(',').map(Number);
      t.x.push(x); t.y.push(y);
    }
  }
  return {
    x: svg.dataset.x.split(',').map(Number), y: svg.dataset.y.split(',').map(Number), w: plot.width, h: plot.height,
    traces: Object.values(traces),
    yticks: [...svg.querySelectorAll('text.ytick')].map(box),
    lines: [...svg.querySelectorAll('polyline[data-name]')].map(box),
    labels: [...svg.querySelectorAll('text.label')].map(t => [t.textContent, ...box(t)]),
  };
}"""


def close_notices(page: Any) -> None:
    """Close the notifications over the canvas (software WebGL, uploads) as a person would."""
    for button in page.locator(".mantine-Notification-root button").all():
        try:
            button.click(timeout=2000)
        except Exception:  # noqa: BLE001 - it closed itself meanwhile
            pass
    expect(page.locator(".mantine-Notification-root")).to_have_count(0)


def open_target_panel(page: Any) -> None:
    """Open the (collapsed by default) Target panel, unless an earlier test left it open (L, H and T are hidden
    while a curve is the target: its upload button says it is open)."""
    upload = page.get_by_role("button", name="Upload CSV curve")
    if not upload.is_visible():
        expand(page, "Target")
    expect(upload).to_be_visible()


def bench(page: Any) -> dict[str, Any]:
    got = page.evaluate(BENCH_JS)
    assert got is not None, "no bench-trajectory chart on the page"
    return got


def page_camera(studio: Any) -> Any:
    (client,) = studio.server.get_clients().values()
    return client.camera


def framed(studio: Any) -> bool:
    """The page's camera is where the studio framed the current views (it reports its pose back)."""
    from studio.frames import FOV
    from studio.geometry import camera_pose

    frames = studio.scene.frames
    cam = page_camera(studio)
    pos, look = camera_pose(frames.composition.bounds, FOV, cam.aspect)
    return bool(np.allclose(cam.position, pos, atol=1e-4) and np.allclose(cam.look_at, look, atol=1e-4))


def show(page: Any, studio: Any, topology: str, mechanism: str) -> None:
    choose(page, "Topology", topology)
    wait_for(lambda: studio.session.view.design.mechanism.name == mechanism, f"{mechanism} in the editor")
    wait_for(lambda: studio.scene.frames is not None and framed(studio), f"the camera to frame {mechanism}")


def ink_at_the_edges(png: bytes, strip: int = 3) -> dict[str, int]:
    """Dark pixels in a strip along each edge of a screenshot: something drawn is cut there."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=np.int32)
    edges = {"left": img[:, :strip], "right": img[:, -strip:], "top": img[:strip, :], "bottom": img[-strip:, :]}
    return {k: int((v < INK).sum()) for k, v in edges.items()}


def overlapping(boxes: dict[str, tuple[float, float, float, float]]) -> list[tuple[str, str]]:
    keys = list(boxes)
    out = []
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            p, q = boxes[a], boxes[b]
            if p[0] < q[2] and q[0] < p[2] and p[1] < q[3] and q[1] < p[3]:
                out.append((a, b))
    return out


def view_boxes(frames: Any) -> dict[str, tuple[float, float, float, float]]:
    """Each view's drawing (mm, scene), each label the layout placed, and the scale bars: what must not overlap."""
    from studio.geometry import SCENE_SCALE

    lay, comp = frames.layout, frames.composition
    off = np.concatenate([lay.leg_offset, lay.leg_offset])
    boxes = {"design view": tuple(lay.design), "leg view": tuple(lay.leg + off), "candidates": tuple(comp.inset)}
    if frames.walk is not None:
        w = frames.walk
        pts = np.concatenate([w.body.reshape(-1, 3), w.trails.reshape(-1, 3), w.ground.reshape(-1, 3)])[:, :2]
        pts = pts / SCENE_SCALE + comp.walk_offset
        boxes["walking view"] = (*pts.min(axis=0), *pts.max(axis=0))
    boxes.update({t.key: t.box for t in frames.texts})
    return boxes


def test_every_mechanism_is_framed_whole_with_views_apart_and_a_scale_bar_each(page: Any, studio: Any) -> None:
    close_notices(page)
    canvas = page.locator("canvas").first
    for topology, mechanism in (("Theo Jansen leg", "jansen"), (RTCLM, "rtclm_primary"), ("Klann leg", "klann"),
                                ("Stephenson-I six-bar", "stephenson1")):
        show(page, studio, topology, mechanism)
        frames = studio.scene.frames
        # The camera the page reports sees everything the layout placed, labels included ...
        from studio.frames import FOV

        cam = page_camera(studio)
        b = frames.composition.bounds * 1e-3
        t = np.tan(FOV / 2) * cam.position[2]
        assert abs(b[0] - cam.position[0]) <= t * cam.aspect and abs(b[2] - cam.position[0]) <= t * cam.aspect
        assert abs(b[1] - cam.position[1]) <= t and abs(b[3] - cam.position[1]) <= t
        # ... and nothing is drawn where the canvas ends (a label or link cut by the panel or the window).
        close_notices(page)
        wait_for(lambda: all(v == 0 for v in ink_at_the_edges(canvas.screenshot()).values()),
                 f"{mechanism}: nothing cut at the canvas edges", timeout=15)
        # No title, note, scale label or drawing of one view runs into another.
        assert overlapping(view_boxes(frames)) == [], mechanism
        # A millimetre scale bar under every view, labelled in round millimetres.
        scales = {t.key: t.text for t in frames.texts if t.key.endswith("_scale")}
        views = {"design_scale", "leg_scale"} | ({"walk_scale"} if frames.walk is not None else set())
        assert set(scales) == views and all(re.fullmatch(r"\d+(\.\d+)? mm", s) for s in scales.values())
        assert len(frames.scale_bars) == 3 * len(views)


def test_a_resized_window_is_framed_again_unless_the_camera_was_moved(page: Any, studio: Any) -> None:
    from conftest import VIEWPORT

    show(page, studio, "Klann leg", "klann")
    canvas = page.locator("canvas").first
    try:
        for size in ({"width": 900, "height": 700}, {"width": 1920, "height": 1080}):
            page.set_viewport_size(size)  # a demo moved to a projector: the views were cut and the inset hidden
            wait_for(lambda: framed(studio) and abs(page_camera(studio).aspect - canvas.bounding_box()["width"]
                                                    / canvas.bounding_box()["height"]) < 0.01,
                     f"the views framed again at {size}")
            close_notices(page)
            wait_for(lambda: all(v == 0 for v in ink_at_the_edges(canvas.screenshot()).values()),
                     f"nothing cut at the canvas edges at {size}", timeout=15)
        before = np.asarray(page_camera(studio).position)
        box = canvas.bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.wheel(0, -400)  # the designer zooms in
        wait_for(lambda: not np.allclose(page_camera(studio).position, before, atol=1e-3),
                 "the page to report the zoom")
        page.wait_for_timeout(500)  # the zoom eases in
        moved = np.asarray(page_camera(studio).position)
        page.set_viewport_size({"width": 1000, "height": 800})
        box = canvas.bounding_box()
        wait_for(lambda: abs(page_camera(studio).aspect - box["width"] / box["height"]) < 0.01,
                 "the page to report its new shape")
        page.wait_for_timeout(500)
        assert np.allclose(page_camera(studio).position, moved, atol=1e-4)  # the designer's camera stays
    finally:
        page.set_viewport_size(VIEWPORT)
        studio.scene.fit_camera()
        for client in studio.server.get_clients().values():
            studio._fit_client(client)
        wait_for(lambda: framed(studio), "the views framed back at the tests' size")


def test_klann_comes_with_a_target_of_its_own_size(page: Any, studio: Any) -> None:
    show(page, studio, "Klann leg", "klann")
    open_target_panel(page)
    expect(page.get_by_text(re.compile(r"Target: curve cycloid (\d+) x (\d+) mm on klann"))).to_be_visible()
    text = page.get_by_text(re.compile(r"Target: curve cycloid")).first.text_content() or ""
    length, height = (float(v) for v in re.search(r"cycloid (\d+) x (\d+) mm", text).groups())  # type: ignore[union-attr]
    # The chart's target is as long and as high as the foot path it is drawn against (not 300 x 100 mm).
    chart = bench(page)
    traces = {tr["name"]: tr for tr in chart["traces"]}
    path = np.array([[x, y] for tr in chart["traces"] if tr["name"] in ("stance", "swing", "bench trajectory")
                     for x, y in zip(tr["x"], tr["y"], strict=True) if x is not None and y is not None])
    target = np.array([traces["target"]["x"], traces["target"]["y"]], dtype=float).T
    span, tspan = np.ptp(path, axis=0), np.ptp(target, axis=0)
    assert abs(tspan[0] - length) <= 1.0 and abs(tspan[1] - height) <= 1.0
    assert np.allclose(tspan, span, atol=1.5)


def test_rtclm_shows_a_target_only_when_a_stage_optimizes_one_and_says_which(page: Any, studio: Any) -> None:
    show(page, studio, RTCLM, "rtclm_primary")
    open_target_panel(page)
    expect(page.get_by_text(re.compile(r"Not shown: no stage of the RTCLM.* optimizes a target"))).to_be_visible()
    # Its own targets, h6 and h4, are there to set (they were fixed at case 1's 50 / 220 mm until session 24).
    expect(page.get_by_text(re.compile(r"RTCLM targets: h6 = 50 mm .* h4 = 220 mm"))).to_be_visible()
    field(page, "h4 target [mm]").fill("260")
    wait_for(lambda: studio.session.view.target.h4 == 260.0, "the h4 target to reach the server")
    expect(page.get_by_text(re.compile(r"h4 = 260 mm \(auxiliary mode\)"))).to_be_visible()
    assert studio.session.view.target.h6 == 50.0
    wait_for(lambda: "target" not in {tr["name"] for tr in bench(page)["traces"]}, "the chart without a target")
    assert len(studio.scene.frames.target) == 0 and len(studio.scene.frames.leg_target) == 0
    # Running a target-matching problem in the first stage's place: now the target is optimized, and shown.
    choose(page, "Problem", "subtask2")  # (subtask 1's analytic placement does not fit the RTCLM: not offered)
    expect(page.get_by_text("Optimized by rtclm1.")).to_be_visible()
    wait_for(lambda: "target" in {tr["name"] for tr in bench(page)["traces"]}, "the chart with its target")
    assert len(studio.scene.frames.leg_target) > 0
    show(page, studio, "Stephenson-I six-bar", "stephenson1")  # a six-bar has no heights to set
    expect(field(page, "h4 target [mm]")).to_be_hidden()


def flat_session(tmp_path: Path) -> Path:
    """A session whose design is a four-bar tracing an arc of its rocker (about 60 x 1 mm): a flat bench path."""
    from core.kinematics import mechanisms
    from core.kinematics.design import Design
    from studio.state import Session
    from studio.target import Curve

    mech = mechanisms.MECHANISMS["fourbar"]
    values = {"b": np.pi, "g": 0.0, "x_a": 0.0, "y_a": 0.0, "r1": 30.0, "r2": 500.0, "r3": 400.0, "r4": 300.0,
              "r5": 500.0, "r6": 0.0}
    s = Session.default("fourbar/chebyshev")
    s.set_design(Design(mech, np.array([[values[p.name] for p in mech.params]])))
    # The target: a flat ellipse over the arc (the chart covers path and target; both are flat).
    point = s.view.solution.point[0]
    mid, span = 0.5 * (point.min(axis=0) + point.max(axis=0)), np.ptp(point, axis=0)
    a = np.linspace(0.0, 2.0 * np.pi, 90, endpoint=False)
    ellipse = np.stack([mid[0] + 0.5 * span[0] * np.cos(a), mid[1] + 0.5 * span[1] * np.sin(a)], axis=1)
    s.set_curve(Curve("flat", tuple((float(x), float(y)) for x, y in ellipse), None, 2.0))
    leg = s.view.solution.leg[0]
    assert np.ptp(leg[:, 1]) < 0.05 * np.ptp(leg[:, 0])  # the premise: flat
    assert np.ptp(s.view.target_leg[:, 1]) < 0.05 * np.ptp(leg[:, 0])
    path = tmp_path / "flat.json"
    path.write_text(json.dumps(s.to_dict()))
    return path


def test_a_flat_bench_path_keeps_a_readable_chart_with_equal_scales(page: Any, studio: Any, tmp_path: Path) -> None:
    load_session(page, studio, flat_session(tmp_path))
    wait_for(lambda: studio.session.view.design.mechanism.name == "fourbar", "the flat design to load")
    wait_for(lambda: any(tr["name"] == "target" and np.ptp(tr["y"]) < 5 for tr in bench(page)["traces"]),
             "the flat design's chart")
    chart = bench(page)
    (x0, x1), (y0, y1) = chart["x"], chart["y"]
    # Equal scales: a millimetre is as long across as up, and the plot has real height.
    assert abs(chart["w"] / (x1 - x0) - chart["h"] / (y1 - y0)) <= 0.02 * chart["w"] / (x1 - x0)
    assert chart["h"] >= 0.25 * chart["w"] and chart["h"] > 40
    # The path is inside the axes, and its curves are drawn (not a zero-height strip).
    path = np.array([[x, y] for tr in chart["traces"] if tr["name"] in ("stance", "swing", "bench trajectory")
                     for x, y in zip(tr["x"], tr["y"], strict=True) if x is not None and y is not None])
    assert x0 < path[:, 0].min() and path[:, 0].max() < x1 and y0 < path[:, 1].min() and path[:, 1].max() < y1
    drawn = np.ptp(path[:, 0]) * chart["w"] / (x1 - x0)  # px the path spans across
    assert drawn > 20 and any(abs((r[2] - r[0]) - drawn) <= 3 for r in chart["lines"]), (drawn, chart["lines"])
    # The y ticks are apart from each other, not stacked.
    tops = sorted(t[1] for t in chart["yticks"])
    assert len(tops) >= 2 and min(np.diff(tops)) >= 10


def test_coincident_feature_points_share_a_label_and_the_walking_metrics_sit_above_the_trunk(
        page: Any, studio: Any) -> None:
    from studio.geometry import SCENE_SCALE

    # The opening X3 design: t1 and t4, t2 and t5 are near each other (8 mm apart: listed, not "=").
    wait_for(lambda: "t1,t4" in {lab[0] for lab in bench(page)["labels"]}, "the chart's merged labels")
    chart = bench(page)
    names = [lab[0] for lab in chart["labels"]]
    assert {"t1,t4", "t2,t5"} <= set(names)
    assert not {"t1", "t4", "t2", "t5"} & set(names)
    assert overlapping({f"{n}#{k}": tuple(lab[1:]) for k, (n, *_) in enumerate(chart["labels"])
                        for lab in [chart["labels"][k]]}) == []
    # The scene's labels, as pushed to the page: merged the same way, none covering another.
    frames = studio.scene.frames
    scene_names = [t.text for t in frames.feature_labels]
    assert {"t1,t4", "t2,t5"} <= set(scene_names) and not {"t1", "t4", "t2", "t5"} & set(scene_names)
    assert overlapping({t.key: t.box for t in frames.feature_labels}) == []
    # The walking metrics: a line of their own, above the trunk wherever the trunk goes over the stride.
    text = next(t for t in frames.texts if t.key == "walk_text")
    title = next(t for t in frames.texts if t.key == "walk_title")
    trunk_top = float(frames.walk.body[:, 0, :, 1].max()) / SCENE_SCALE + frames.composition.walk_offset[1]
    assert text.box[1] > trunk_top and title.box[1] >= text.box[3] - 1e-9
    assert "hₘ" in text.text and "ψ₂" in text.text
