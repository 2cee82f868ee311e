"""clm export's parts sheet: plate outlines (the hull of circles about a link's points) by hand and as a property,
the holes on each flat part as far apart as the design's links, and the warnings about holes too close."""

from __future__ import annotations

import math

import ezdxf
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.cli import main
from core.formats.drawing import Plates, cutting_warnings, drawing, dxf, hull, outline
from core.kinematics.presets import get


def test_a_bar_is_a_stadium_and_a_triangle_a_rounded_triangle():
    # Two holes 10 mm apart, plate radius 2: two half circles (bulge 1) joined by two straight sides.
    np.testing.assert_allclose(outline(np.array([[0.0, 0.0], [10.0, 0.0]]), 2.0),
                               [(0, 2, 1), (0, -2, 0), (10, -2, 1), (10, 2, 0)], atol=1e-12)
    # A right triangle: a quarter turn at the right angle (bulge tan(pi/8)), 135 deg at the other two.
    got = outline(np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]), 1.0)
    s = math.sqrt(0.5)
    np.testing.assert_allclose(got, [(-1, 0, math.tan(math.pi / 8)), (0, -1, 0), (10, -1, math.tan(3 * math.pi / 16)),
                                     (10 + s, s, 0), (s, 10 + s, math.tan(3 * math.pi / 16)), (-1, 10, 0)], atol=1e-12)
    # A point inside the hull and one repeated change nothing; collinear points are one bar.
    assert hull(np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [2.0, 2.0], [0.0, 0.0]])).tolist() == \
        [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]
    assert hull(np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])).tolist() == [[0.0, 0.0], [10.0, 0.0]]


points = st.lists(st.tuples(st.floats(-100, 100), st.floats(-100, 100)), min_size=2, max_size=6)


@given(points, st.floats(0.5, 20))
@settings(max_examples=200, deadline=None)
def test_a_plate_outline_keeps_its_radius_from_the_points_and_turns_once(pts, radius):
    P = np.array(pts)
    if len(hull(P)) < 2:
        return
    out = outline(P, radius)
    V = np.array([(x, y) for x, y, _ in out])
    dist = np.linalg.norm(V[:, None, :] - P[None, :, :], axis=2).min(axis=1)
    np.testing.assert_allclose(dist, radius, rtol=1e-9, atol=1e-9)  # on a circle, outside the others
    turns = sum(4 * math.atan(b) for *_, b in out)
    assert turns == pytest.approx(2 * math.pi)  # convex: the arcs turn once around, every bulge in (0, 1]
    assert all(0 <= b <= 1 + 1e-12 for *_, b in out)


@pytest.mark.parametrize("name", ["stephenson1/X3", "jansen", "klann", "fourbar/chebyshev", "watt1/paper"])
def test_each_part_is_a_closed_plate_whose_holes_are_as_far_apart_as_the_design_s_links(name, tmp_path):
    d = drawing(get(name).design(), 0.4)
    plates = Plates(hole=4.0, width=14.0)
    out = tmp_path / "d.dxf"
    out.write_text(dxf(d, plates))
    msp = ezdxf.readfile(out).modelspace()
    assembly_bottom = min(p[1] for p in d.joints)
    boxes = []
    for body in d.links:
        layer = "PART_" + "-".join(body)
        (plate,) = [e for e in msp.query("LWPOLYLINE") if e.dxf.layer == layer]
        assert plate.closed
        holes = [c for c in msp.query("CIRCLE") if c.dxf.layer == layer]
        pivots = [n for n in body if n in d.pivots()]
        assert len(holes) == len(pivots) and all(c.dxf.radius == 2.0 for c in holes)
        centres = np.array([(c.dxf.center.x, c.dxf.center.y) for c in holes])
        # Laid flat (turned and moved): the same distances between holes as between the joints.
        flat = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        real = np.linalg.norm(np.array([d.point(n) for n in pivots])[:, None]
                              - np.array([d.point(n) for n in pivots])[None], axis=2)
        np.testing.assert_allclose(flat, real, atol=1e-9)
        xy = np.array([(x, y) for x, y, *_ in plate.get_points("xyb")])
        near = np.linalg.norm(xy[:, None] - centres[None], axis=2).min(axis=1) if len(centres) else None
        if near is not None and len(pivots) == len(body):
            np.testing.assert_allclose(near, 7.0, atol=1e-9)  # the plate 14 mm wide
        boxes.append((xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()))
    boxes.sort()
    for a, b in zip(boxes, boxes[1:], strict=False):  # side by side, apart
        assert a[1] < b[0]
    assert max(b[3] for b in boxes) < assembly_bottom  # under the assembly drawing


def test_holes_too_close_are_warned_about_and_bad_sizes_refused(tmp_path, capsys):
    d = drawing(get("stephenson1/X3").design())
    bf = float(np.linalg.norm(d.point("B") - d.point("F")))  # 6.54 mm
    assert [w.text.split(" (")[0] for w in cutting_warnings(d, Plates(5.0))] == ["holes B and F of link A-B-F"]
    assert not cutting_warnings(d, Plates(5.0))[0].overlap
    over = cutting_warnings(d, Plates(bf + 0.1))[0]
    assert "overlap" in over.text and over.overlap
    assert cutting_warnings(d, Plates(3.0, 6.0)) == []  # 3.54 mm between them, 1.5 beside each hole
    out = tmp_path / "x.dxf"
    assert main(["export", "--preset", "stephenson1/X3", "--dxf", str(out), "--hole", "3", "--width", "12"]) == 0
    cap = capsys.readouterr()
    assert "12 mm plates, 3 mm holes" in cap.out and "between them" in cap.err  # 3.54 < 4.5 beside each hole
    assert main(["export", "--preset", "stephenson1/X3", "--dxf", str(out), "--hole", "7"]) == 0
    err = capsys.readouterr().err
    assert "B and F of link A-B-F" in err and "smaller pins (--hole)" in err and out.exists()  # written all the same
    # A huge angle is the same pose as its remainder (1e8 deg read "does not assemble": sin/cos lost it).
    assert main(["export", "--preset", "stephenson1/X3", "--svg", str(tmp_path / "a.svg"), "--angle", "1e8"]) == 0
    assert "at crank angle 280.0 deg" in (tmp_path / "a.svg").read_text()
    capsys.readouterr()
    for bad in (["--hole", "0"], ["--hole", "nan"], ["--hole", "-2"], ["--hole", "5", "--width", "5"]):
        assert main(["export", "--preset", "stephenson1/X3", "--dxf", str(tmp_path / "y.dxf"), *bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--hole/--width" in err[0] and not (tmp_path / "y.dxf").exists()


def test_the_rtclm_s_parts_are_the_leg_built_its_second_motor_s_crank_apart_with_a_bore_at_h():
    """Rehearsal 5: the primary mode locks crank H-F to the rocker, and its parts sheet welded them into one plate
    D-C-H-F with no hole at H (the second motor's axis); the auxiliary mode's drawing has the four-bar alone."""
    design = get("rtclm/clm-case1").design()
    d = drawing(design)
    assert ("D", "C", "H") in d.links and ("H", "F") in d.links and not any(len(b) == 4 for b in d.links)
    assert {"H", "F"} <= d.pivots()
    hf = float(np.linalg.norm(d.point("H") - d.point("F")))
    assert hf == pytest.approx(design.named()["r6"], abs=1e-9)  # the crank's length
    aux = drawing(get("rtclm/clm-case1/auxiliary").design())
    assert ("H", "F") in aux.links  # a link of the four-bar there, as it was


def test_the_studio_names_its_own_hole_field_where_only_smaller_pins_help() -> None:
    # Review of session 29: both front ends found the overlap by the last words of core's sentence.
    from studio.exports import drawing_warnings
    from studio.state import build_view
    from studio.target import TargetSpec

    view = build_view(get("stephenson1/X3").design(), "stephenson1/X3", TargetSpec())
    said = drawing_warnings(view, 0.0, Plates(7.0))
    assert said and all(w.endswith("(Pin hole Ø above the Drawing buttons)") == ("overlap" in w) for w in said)
    assert any("overlap" in w for w in said)
    assert not any(w.endswith("buttons)") for w in drawing_warnings(view, 0.0, Plates(5.0)))


def test_a_hole_in_metres_is_warned_of(tmp_path, capsys):
    # Lab rehearsal: --hole 0.005 (5 mm written in m) drew 5 um pins without a word.
    from core.cli import main

    assert main(["export", "--preset", "stephenson1/X3", "--dxf", str(tmp_path / "m.dxf"), "--hole", "0.005"]) == 0
    assert capsys.readouterr().err.startswith("clm: warning: --hole 0.005: a pivot hole under 0.5 mm")
