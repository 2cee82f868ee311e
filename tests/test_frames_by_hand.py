"""The scene's arrays by hand: label boxes, scale bars, feature and candidate labels, colours, the leg view's
ground line and the layout's text (a mutation audit of studio/frames.py found each of these unchecked)."""

from __future__ import annotations

import itertools
import re
from dataclasses import replace

import numpy as np
import pytest

from core.kinematics.model import Ground
from studio import palette
from studio.frames import (
    TEXT_SCALE,
    SceneText,
    _text,
    build_frames,
    feature_texts,
    marker_texts,
    paint,
    scale_bar,
    text_height,
    text_width,
    vertex_colours,
)
from studio.geometry import EDGE_CRANK, EDGE_GROUND, EDGE_LINK, SCENE_SCALE, link_edges, to_scene
from studio.spots import overlaps
from studio.spots import overlaps as _overlaps
from studio.state import Session, build_view

S = SCENE_SCALE


@pytest.fixture(scope="module")
def x3_view():
    return Session.default("stephenson1/X3").view


@pytest.fixture(scope="module")
def x3(x3_view):
    return build_frames(x3_view)


def texts_by_key(f) -> dict[str, SceneText]:
    return {t.key: t for t in f.texts}


def test_a_labels_size_follows_its_longest_line_and_its_number_of_lines():
    h = 10.0
    assert text_width("ab\nabcd\nabc", h) == pytest.approx(text_width("abcd", h)) == pytest.approx(
        2 * text_width("ab", h))
    assert text_height("a", h) > 0
    assert text_height("a\nbb\nccc", h) == pytest.approx(3 * text_height("a", h))


@pytest.mark.parametrize(("vert", "horiz"), list(itertools.product(("top", "center", "bottom"),
                                                                     ("left", "center", "right"))))
def test_a_label_box_has_its_anchor_where_the_anchor_says(vert: str, horiz: str):
    x, y, h, off = 40.0, -25.0, 6.0, (1000.0, 500.0)
    t = _text("k", "two\nlines!", x, y, f"{vert}-{horiz}", h, off)
    x0, y0, x1, y1 = t.box
    assert x1 - x0 == pytest.approx(text_width("lines!", h)) and y1 - y0 == pytest.approx(2 * text_height("a", h))
    gx = {"left": x0, "right": x1, "center": 0.5 * (x0 + x1)}[horiz] - off[0]
    gy = {"bottom": y0, "top": y1, "center": 0.5 * (y0 + y1)}[vert] - off[1]
    assert (gx, gy) == pytest.approx((x, y))
    assert t.position == pytest.approx((x * S, y * S, 0.0)) and t.height == pytest.approx(h * S)


def test_a_scale_bar_is_as_long_as_its_label_says_and_round():
    seg, label = scale_bar(10.0, 20.0, 480.0, 8.0, "k")
    (a, b), tick0, tick1 = seg
    length = float(label.text.removesuffix(" mm"))
    assert length == 100.0  # about a fifth of 480 mm, rounded to 1, 2 or 5 x 10^k
    assert a[1] == b[1] == 20.0 and b[0] - a[0] == pytest.approx(length) and a[0] == 10.0
    assert tick0[0][0] == tick0[1][0] == a[0] and tick1[0][0] == tick1[1][0] == b[0]  # end ticks, upright
    assert tick0[0][1] < 20.0 < tick0[1][1]
    assert label.box[0] > b[0] and label.box[1] < 20.0 < label.box[3]  # right of the bar, level with it


def test_feature_points_closer_than_a_label_print_as_one_label_in_numeric_order():
    h = 4.0
    got = feature_texts((("t6", (0.0, 0.0)), ("t1=t4", (0.5 * h, 0.0)), ("t2", (1.01 * h, 0.0))), h,
                        np.zeros(2))
    # t6 is near t1=t4, not on it: listed, not joined by "="; t2 is just over a label's height from t6
    assert [t.text for t in got] == ["t1=t4,t6", "t2"]


def test_every_feature_point_on_one_spot_prints_a_short_label():
    # "t1=t2=t3=t4=t5=t6=t7=t8" ran past the bench view's box (a foot path collapsed to a point).
    h = 4.0
    got = feature_texts(tuple((f"t{i}", (0.0, 0.0)) for i in (8, 3, 1, 2, 7, 4, 6, 5)), h, np.zeros(2))
    assert [t.text for t in got] == ["t1=…=t8"]
    got = feature_texts((("t1", (0.0, 0.0)), ("t2", (0.0, 0.0)), ("t4", (0.0, 0.0)), ("t5", (0.0, 0.0))), h,
                        np.zeros(2))
    assert [t.text for t in got] == ["t1=t2=t4=t5"]  # not a run: every name


def test_a_feature_label_that_would_cover_another_moves_below_its_point():
    h = 4.0
    got = feature_texts((("t1=t4", (0.0, 0.0)), ("t2=t5", (1.5 * h, 0.0))), h, np.zeros(2))
    assert [t.anchor for t in got] == ["bottom-center", "top-center"]
    assert not _overlaps(got[0].box, got[1].box)
    assert got[1].box[3] < 0.0  # under its point


def test_a_feature_label_keeps_off_the_lines_through_its_point_and_apart_from_its_neighbour():
    h = 4.0
    # The foot path rises to the right of t4 through the spot above it (QA session 37: "t4" sat on the green
    # swing line): the label goes below, where nothing runs.
    rising = np.array([[[0.0, 0.0], [2.0 * h, 2.0 * h]]])
    flat = np.array([[[-5.0 * h, -3.0 * h], [5.0 * h, -3.0 * h]]])
    (t,) = feature_texts((("t4", (0.0, 0.0)),), h, np.zeros(2), (rising, flat))
    assert t.anchor == "top-center" and t.box[3] < 0.0
    # With the spots below and right crossed too, it goes left, the side nothing crosses.
    under = np.array([[[-0.5 * h, -h], [3.0 * h, -h]], [[1.2 * h, -h], [1.2 * h, h]]])
    (t,) = feature_texts((("t4", (0.0, 0.0)),), h, np.zeros(2), (rising, under))
    assert t.anchor == "center-right"
    # Crossing every line beats covering a label; two labels side by side keep a narrow letter's width apart.
    a, b = feature_texts((("t1", (0.0, 0.0)), ("t2", (1.3 * h, 0.0))), h, np.zeros(2))
    assert a.anchor == "bottom-center" and b.anchor != "bottom-center"
    (c,) = feature_texts((("t1", (0.0, 0.0)),), h, np.array([10.0, 5.0]), (rising + (10.0, 5.0),))
    assert c.anchor == "bottom-center"  # the offset moves the lines with the view: nothing crosses
    # Within a letter's width of a label costs less than covering it (review, session 38: every spot came within
    # the gap, they cost the same, and the first covered t1's label where the right-hand spot was clear).
    a, b = feature_texts((("t1", (0.0, 0.0)), ("t2", (0.8, 4.5))), h, np.zeros(2))
    assert not _overlaps(a.box, b.box)
    # A spot that leaves the view costs more than one crossing a line.
    (d,) = feature_texts((("t5", (0.0, 0.0)),), h, np.zeros(2), (rising,), frame=(-10.0 * h, -h, 0.5 * h, 10.0 * h))
    assert d.anchor in ("bottom-center", "top-center", "center-right") and d.box[2] <= 0.5 * h


def test_a_candidates_label_sits_above_its_own_sphere_without_covering_it():
    r, h = 3.0, 4.0
    (t,) = marker_texts((("K1", (10.0, 20.0)),), h, r)
    assert t is not None and t.anchor == "bottom-center"
    assert not _overlaps(t.box, (10.0 - r, 20.0 - r, 10.0 + r, 20.0 + r))
    assert t.box[1] >= 20.0 + r and t.box[3] - 20.0 < r + 2 * h  # just above it, not far off


def test_line_colours_are_srgb_decoded_as_the_standard_says():
    # IEC 61966-2-1: c <= 0.04045 -> c / 12.92, else ((c + 0.055) / 1.055) ** 2.4. sRGB 128 is linear 0.21586
    # (55 of 255), sRGB 188 is linear 0.50289 (128 of 255); sRGB 10 lies on the straight part (0.00304 -> 1).
    got = vertex_colours(np.array([[0, 10, 128], [188, 255, 255]]))
    assert got.dtype == np.uint8 and got.tolist() == [[0, 1, 55], [128, 255, 255]]


def test_lines_get_decoded_colours_and_point_clouds_the_colour_as_given():
    lines, points = np.zeros((4, 2, 3), dtype=np.float32), np.zeros((5, 3), dtype=np.float32)
    assert paint(lines, (128, 188, 0)).shape == (4, 2, 3)
    assert (paint(lines, (128, 188, 0)) == [55, 128, 0]).all()
    assert paint(points, (128, 188, 0)).shape == (5, 3) and (paint(points, (128, 188, 0)) == [128, 188, 0]).all()


def test_ground_crank_and_links_are_drawn_in_their_own_colours(x3_view, x3):
    kinds = link_edges(x3_view.design.mechanism).kinds
    for kind, rgb in ((EDGE_GROUND, palette.GROUND), (EDGE_CRANK, palette.CRANK), (EDGE_LINK, palette.LINK)):
        assert (kinds == kind).any()
        assert (x3.link_colors[kinds == kind] == vertex_colours(np.array(rgb))).all(), kind


def test_only_ground_pivots_a_link_touches_are_drawn_and_framed():
    aux = Session.default("rtclm/case2/auxiliary").view
    f = build_frames(aux)
    assert f.pivot_names == ("E", "H")  # the locked primary linkage A..D is no loose diamond
    j = aux.solution.joints[0][0]
    names = aux.design.mechanism.joint_names
    np.testing.assert_allclose(f.pivots[:, :2], j[[names.index("E"), names.index("H")]] * S, rtol=1e-6)
    grounds = [s.name for s in Session.default("stephenson1/X3").view.design.mechanism.steps if isinstance(s, Ground)]
    assert build_frames(Session.default("stephenson1/X3").view).pivot_names == tuple(grounds)  # a six-bar: all


def test_the_leg_view_draws_its_ground_line_at_t1s_height_and_none_outside_the_view(x3_view, x3):
    t1 = x3_view.features[0]
    assert re.split("[=,]", t1[0])[0] == "t1"
    assert len(x3.leg_axes) == 5  # the border's four sides and the ground line
    (a, b) = x3.leg_axes[4]
    assert a[1] == b[1] == pytest.approx(t1[1][1] * S) and b[0] - a[0] > 0.3  # across the ~300 mm view
    # A t1 off the view (a hand-moved feature point): no ground line outside the border.
    far = replace(x3_view, features=(("t1", (0.0, 1e4)),) + x3_view.features[1:])
    assert len(build_frames(far).leg_axes) == 4


def test_stance_and_swing_segments_have_their_colours(x3_view, x3):
    stance = x3_view.stance
    assert stance is not None and 0 < stance.sum() < len(stance)
    want = np.where(stance[:, None], vertex_colours(np.array(palette.STANCE)), vertex_colours(np.array(palette.SWING)))
    # Segment i -> i + 1 has sample i's colour; a drawn segment spans samples i..j - 1 of one colour and has it.
    ends = _sample_ends(x3.leg_path, x3_view.solution.leg[0])
    n = len(stance)
    for (i, j), c in zip(ends, x3.leg_path_colors, strict=True):
        run = np.arange(i, j if j > i else j + n) % n
        assert (want[run] == c[0]).all() and (c[1] == c[0]).all()
    assert sum((j - i) % n for i, j in ends) == n  # the whole closed path, once


def _sample_ends(drawn, points):
    """``(k, 2)`` the sample indices of each drawn segment's ends (leg-view local scene coordinates)."""
    samples = to_scene(np.nan_to_num(points, nan=1e9))[:, :2]
    at = [np.flatnonzero(np.abs(samples - p).sum(axis=1) < 1e-9) for p in drawn[:, :, :2].reshape(-1, 2)]
    assert all(len(i) == 1 for i in at)
    return np.array([i[0] for i in at]).reshape(-1, 2)


def test_the_bench_path_leaves_out_every_segment_with_an_end_where_the_mechanism_does_not_assemble(x3_view):
    broken = build_view(x3_view.design.replace(r4=131.8), "stephenson1/X3", x3_view.target)
    leg = broken.solution.leg[0]
    ok = np.isfinite(leg).all(axis=1)
    assert 0 < ok.sum() < len(ok)
    f = build_frames(broken)
    assert np.isfinite(f.leg_path).all()
    assert 0 < len(f.leg_path) == len(f.leg_path_colors) <= int((ok & np.roll(ok, -1)).sum())
    # Drawn with fewer segments (tests/test_drawn_curves.py), none across the samples that do not assemble: each
    # segment joins two samples with every sample between them assembled.
    for i, j in _sample_ends(f.leg_path, leg):
        run = np.arange(i, j + 1 if j >= i else j + 1 + len(ok)) % len(ok)
        assert ok[run].all()


def test_a_design_that_never_assembles_keeps_its_pivots_turns_its_crank_and_draws_no_foot(x3_view):
    # QA (session 37): every joint, pivot and the foot sat on one pivot as a red dot, and the bench view's foot fell
    # outside its frame.
    never = build_view(x3_view.design.replace(r4=1000.0), "stephenson1/X3", x3_view.target)
    assert not never.solution.valid[0].any()
    f = build_frames(never)
    assert not f.posed and build_frames(x3_view).posed  # the scene hides both feet
    # Its moving joints are not named (review of session 33: six names piled on pivot A while paused).
    assert f.joint_names == () and build_frames(x3_view).joint_names
    joints = never.solution.joints[0] * S
    steps = never.design.mechanism.steps
    ground = np.array([isinstance(s, Ground) for s in steps])
    a = joints[0, int(np.argmax(ground))]  # pivot A, (150.57, 66.12) mm: what does not solve sits there
    assert np.isfinite(joints[:, ground]).all()
    shown = np.isin(np.array(never.design.mechanism.joint_names), never.design.mechanism.pivots())
    assert shown.sum() >= 2
    np.testing.assert_allclose(f.pivots[:, :2], joints[0, shown], rtol=1e-6)  # each in its own place
    moving = joints[:, ~ground]
    solved = np.isfinite(moving).all(axis=(0, 2))
    assert 0 < solved.sum() < len(solved)  # the crank's tip solves, the rest does not
    np.testing.assert_allclose(f.joints[:, solved, :2], moving[:, solved], rtol=1e-6)  # it turns
    assert np.ptp(f.joints[:, solved, 0]) > 10 * S
    np.testing.assert_allclose(f.joints[:, ~solved, :2], np.broadcast_to(a, f.joints[:, ~solved, :2].shape), rtol=1e-6)
    assert np.isfinite(f.links).all() and np.isfinite(f.foot).all() and np.isfinite(f.leg_foot).all()
    # A link is drawn only where both its ends solve (the crank), else it is a point on A.
    length = np.linalg.norm(f.links[:, :, 0, :2] - f.links[:, :, 1, :2], axis=-1)
    assert ((length > 1e-9).sum(axis=1) >= 1).all()


def test_the_walking_metrics_print_as_two_lines_heights_then_obstacle_crossing(x3):
    lines = texts_by_key(x3)["walk_text"].text.split("\n")
    assert len(lines) == 2
    assert "hₘ" in lines[0] and "h̄" in lines[0] and "ψ" not in lines[0]
    assert lines[1].startswith("ψ₂(") and "ψ₄(" in lines[1]


def test_the_walking_legs_each_have_their_own_colour(x3):
    assert x3.walk is not None
    feet = [tuple(c) for c in x3.walk.feet_colors]
    assert len(feet) >= 2 and len(set(feet)) == len(feet)
    assert feet == list(palette.LEGS[: len(feet)])


def test_titles_sit_above_their_views_and_scale_bars_below(x3):
    t = texts_by_key(x3)
    lay, comp = x3.layout, x3.composition
    leg_top = (x3.leg_axes[:4, :, 1].max() / S) + lay.leg_offset[1]
    leg_bottom = (x3.leg_axes[:4, :, 1].min() / S) + lay.leg_offset[1]
    assert t["design_title"].box[1] >= lay.design[3]
    assert t["leg_title"].box[1] >= leg_top - 1e-9
    assert t["inset_title"].box[1] >= comp.inset[3]
    assert t["inset_note"].box[3] <= comp.inset[1]
    assert t["walk_title"].box[1] >= t["walk_text"].box[3] - 1e-9
    bars = x3.scale_bars[..., :2] / S
    assert bars[:3, :, 1].max() < lay.design[1]  # the design view's bar under its lowest point
    assert bars[3:6, :, 1].max() < leg_bottom
    assert bars[:3, :, 0].min() == pytest.approx(lay.design[0])  # starting at its left edge


@pytest.mark.parametrize("preset", ["rtclm/clm-case1", "rtclm/clm-case1/auxiliary", "stephenson1/X3", "jansen",
                                    "klann", "watt1/paper"])
def test_no_feature_label_prints_through_the_bench_view_s_title(preset):
    # The RTCLM's foot path is ~20 mm, so the bench view's padding is ~1 mm: "t6=t7=t8" over the path's top printed
    # through "Bench trajectory (leg frame)".
    f = build_frames(Session.default(preset).view, show_target=not preset.startswith("rtclm"))  # as the studio
    title, figures = texts_by_key(f)["leg_title"].box, texts_by_key(f)["leg_text"].box
    assert f.feature_labels
    for t in f.feature_labels:
        assert not overlaps(t.box, title), (t.text, t.box, title)
        assert not overlaps(t.box, figures), (t.text, t.box, figures)
    assert title[1] >= figures[3] - 1e-9  # the bench figures between the title and the view
    for t in f.texts:
        assert t.key == "leg_text" or not overlaps(t.box, figures), t.key


def test_the_text_height_follows_the_larger_side_of_the_whole_composition(x3):
    b = x3.composition.bounds
    size = max(b[2] - b[0], b[3] - b[1])
    assert x3.text_height / S == pytest.approx(size / TEXT_SCALE, rel=0.03)  # the fixed point stops within 2 %


@pytest.mark.parametrize("preset", ["jansen", "klann", "stephenson1/X3", "watt1/paper", "fourbar/chebyshev"])
def test_a_pivot_label_takes_the_corner_the_links_cross_least(preset):
    # Always at the lower right, Jansen's "Q" sat on a link at most crank angles and read as a second "O".
    from studio.frames import PIVOT_SPOTS, pivot_label_spots, text_height, text_width

    f = build_frames(Session.default(preset).view)
    h, off = 0.8 * f.text_height, 0.6 * f.marker
    spots = pivot_label_spots(f.pivot_names, f.pivots, f.links, h, off)
    seg = f.links[..., :2].astype(np.float64)

    def crossed(name: str, p: np.ndarray, sx: float, sy: float) -> int:  # by 400 points a segment, independently
        w, th = text_width(name, h), text_height(name, h)
        x0, y0 = p[0] + sx * off, p[1] + sy * off
        box = (min(x0, x0 + sx * w), min(y0, y0 + sy * th), max(x0, x0 + sx * w), max(y0, y0 + sy * th))
        t = np.linspace(0, 1, 400)[:, None]
        pts = seg[:, :, None, 0] + t * (seg[:, :, None, 1] - seg[:, :, None, 0])
        inside = ((pts[..., 0] > box[0]) & (pts[..., 0] < box[2]) & (pts[..., 1] > box[1]) & (pts[..., 1] < box[3]))
        return int(inside.any(axis=(1, 2)).sum())

    for name, p, (_, anchor) in zip(f.pivot_names, f.pivots, spots, strict=True):
        counts = {a: crossed(name, p, sx, sy) for sx, sy, a in PIVOT_SPOTS}
        assert counts[anchor] <= min(counts.values()) + 0.02 * len(seg), (name, anchor, counts)
        if preset == "jansen" and name == "Q":
            assert counts[anchor] < counts["top-left"], counts  # the old spot is crossed more often


def test_a_segment_crosses_a_box_by_hand():
    from studio.spots import crosses_box as _crosses_box

    box = (0.0, 0.0, 2.0, 1.0)
    a = np.array([[-1.0, 0.5], [-1.0, 2.0], [0.5, 0.5], [1.0, -1.0], [-1.0, 0.5], [3.0, 0.0], [0.5, 0.2]])
    d = np.array([[4.0, 0.0], [4.0, 0.0], [0.1, 0.0], [0.0, 0.5], [0.9, 0.0], [-1.0, 2.0], [0.0, 0.0]])
    # through; above it; inside; stops short; stops short of the left side; cuts the corner at (2, 1)... outside;
    # a point inside
    assert _crosses_box(a, d, box).tolist() == [True, False, True, False, False, False, True]


def test_the_auxiliary_mode_draws_the_links_it_holds_still_in_the_frames_colour():
    # Rehearsal 7: the auxiliary mode drew the four-bar E-H-F-G alone, at another scale: a switch of mode looked like
    # another mechanism. The primary mode's crank, coupler and rocker are drawn where the switching state locks them.
    aux = Session.default("rtclm/case2/auxiliary").view
    mech = aux.design.mechanism
    edges = link_edges(mech)
    names = mech.joint_names
    drawn = {frozenset((names[a], names[b])) for (a, b), k in zip(edges.pairs, edges.kinds, strict=True)
             if k == EDGE_GROUND}
    assert drawn == {frozenset(p) for p in (("A", "B"), ("B", "C"), ("B", "E"), ("C", "E"), ("D", "C"), ("D", "H"),
                                            ("C", "H"))}
    f = build_frames(aux)
    assert f.pivot_names == ("E", "H")  # still no loose diamonds
    # Inside the mechanism view the camera frames (mm): case 1's CMOES row locks C outside E-H-F-G's sweep.
    for preset in ("rtclm/case2/auxiliary", "rtclm/case1-CMOES/auxiliary"):
        v = Session.default(preset).view
        box, j = build_frames(v).layout.design, v.solution.joints[0][0]
        for n in ("A", "B", "C", "D"):
            x, y = j[names.index(n)]
            assert box[0] <= x <= box[2] and box[1] <= y <= box[3], (preset, n)
    assert Session.default("rtclm/case2").view.design.mechanism.locked == ()  # the primary mode moves them


@pytest.mark.parametrize("preset", ["stephenson1/X3", "jansen", "klann", "watt1/paper", "rtclm/case1", "rtclm/case3"])
def test_moving_joint_labels_keep_off_each_other_and_the_pivot_labels(preset):
    # Session 33: the joints' labels at a fixed corner read "BF" where the Stephenson-I's B and F sit close.
    from studio.frames import joint_label_spots, label_box, pivot_label_spots

    f = build_frames(Session.default(preset).view)
    h, off = 0.8 * f.text_height, 0.6 * f.marker
    pivots = tuple(label_box(n, xyz, a, h) for n, (xyz, a) in
                   zip(f.pivot_names, pivot_label_spots(f.pivot_names, f.pivots, f.links, h, off), strict=True))
    worst = 0
    for i in range(0, f.n_samples, 7):
        spots = joint_label_spots(f.joint_names, f.joints[i], f.links[i], h, off, pivots)
        boxes = [label_box(n, xyz, a, h) for n, (xyz, a) in zip(f.joint_names, spots, strict=True)]
        for (xyz, _), p in zip(spots, f.joints[i], strict=True):  # a marker's offset from its joint, diagonally
            np.testing.assert_allclose(np.abs(np.array(xyz[:2]) - p[:2]), off, rtol=1e-5)
        clash = sum(_overlaps(a, b) for a, b in itertools.combinations(boxes, 2))
        clash += sum(_overlaps(a, b) for a in boxes for b in pivots)
        worst = max(worst, clash)
    assert worst == 0, worst  # a clash costs more than any number of links under a label (session 39)
    # A fixed corner would not have kept them apart (the test can fail): B and F of the Stephenson-I at 0.
    if preset == "stephenson1/X3":
        fixed = [label_box(n, (p[0] + off, p[1] + off, 0.0), "bottom-left", h)
                 for n, p in zip(f.joint_names, f.joints[0], strict=True)]
        assert sum(_overlaps(a, b) for a, b in itertools.combinations(fixed, 2)) >= 1


def test_the_bench_figures_print_over_the_bench_view_as_the_metrics_rows_read(x3_view, x3):
    # The Metrics panel sat below the fold at 1280 x 720: MSE, S, I and h_s are what a slider is moved for.
    from studio.metrics import shape_error

    ev = x3_view.evaluation
    want = (f"MSE {shape_error(ev):.2f} mm · S {float(ev.S[0]):.2f} %\n"
            f"I {float(ev.I[0]):.2f} mm/s · hₛ {float(ev.h_s[0]):.2f} mm")
    assert texts_by_key(x3)["leg_text"].text == want
    assert want.startswith("MSE 4.10 mm · S 2.00 %")  # the paper's X3: 4.102 mm, 2.002 % (Appendix B)


def test_the_bench_figures_leave_out_what_is_not_this_leg_s():
    from studio.frames import bench_text

    x3 = Session.default("stephenson1/X3").view
    breaks = build_view(x3.design.replace(r4=131.8), "stephenson1/X3", x3.target)
    assert bench_text(breaks) == "does not assemble over the whole\ncycle (shortfall 0.23 mm)\nno walking view"
    seen = set()
    for v in (x3, *(build_view(x3.design.replace(r3=r3), "stephenson1/X3", x3.target) for r3 in (110.0, 130.0))):
        walks = bool(v.evaluation.feasible[0])
        assert ("S " in bench_text(v)) == walks and bench_text(v).startswith("MSE "), (walks, bench_text(v))
        assert bench_text(v).endswith("\nno walking view") != walks  # its view is gone: said (QA, session 37)
        seen.add(walks)
    assert seen == {True, False}  # r3 = 130 mm assembles and does not walk: its MSE alone
    rtclm = Session.default("rtclm/clm-case1").view  # its stages drive h6 and h4, not a shape: no MSE, h6 first
    h6 = float(rtclm.evaluation.h_m[0])
    assert bench_text(rtclm).startswith(f"h6 {h6:.2f} mm · S ") and "MSE" not in bench_text(rtclm)
    assert bench_text(Session.default("rtclm/case1").view).startswith("no single landing/take-off pair")
