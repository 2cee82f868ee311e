"""The candidates inset on a real (browserless) viser server, and the animation clock (a mutation audit of
studio/inset.py found the inset's frame, captions, sphere colours and sizes, and the clock's timing unchecked)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import viser

from studio import palette
from studio.frames import SMALL_TEXT
from studio.geometry import SCENE_SCALE
from studio.inset import Animator, CandidateInset, InsetMarker

S = SCENE_SCALE
BOX = np.array([200.0, 100.0, 300.0, 200.0])  # mm, a 100 mm square
TEXT = 0.004  # m, the scene's title height


@pytest.fixture(scope="module")
def server():
    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


@pytest.fixture
def inset(server):
    picks: list[int] = []
    inset = CandidateInset(server, lambda member, client: picks.append(member))
    inset.place(BOX, "x: a (mm)\ny: b (scaled)", TEXT)
    return inset


MARKERS = (InsetMarker(7, "K1", "knee", (220.0, 180.0)), InsetMarker(3, "best a", "best", (280.0, 120.0)),
           InsetMarker(9, "#9", "shown", (250.0, 150.0)))


def test_the_inset_is_a_square_frame_with_its_title_above_and_its_axes_below(inset):
    edges = {frozenset(map(tuple, np.round(seg[:, :2] / S, 6).tolist())) for seg in np.asarray(inset.border.points)}
    x0, y0, x1, y1 = BOX
    assert edges == {frozenset({(x0, y0), (x1, y0)}), frozenset({(x1, y0), (x1, y1)}),
                     frozenset({(x1, y1), (x0, y1)}), frozenset({(x0, y1), (x0, y0)})}
    tx, ty, _ = inset.title.position
    nx, ny, _ = inset.note.position
    assert tx == pytest.approx(x0 * S) and nx == pytest.approx(x0 * S)  # both at its left edge
    assert y1 * S < ty < y1 * S + TEXT  # bottom-anchored just above the top edge
    assert y0 * S - TEXT < ny < y0 * S  # top-anchored just below the bottom edge
    assert inset.note.text == "x: a (mm)\ny: b (scaled)"
    assert inset.note.font_scene_height == pytest.approx(SMALL_TEXT * TEXT)


def test_candidates_are_small_spheres_where_their_markers_are_coloured_by_kind(inset):
    inset.show(MARKERS, np.array([[230.0, 160.0], [260.0, 140.0]]), None)
    spheres = inset._spheres
    assert set(spheres) == {7, 3, 9}
    side = (BOX[2] - BOX[0]) * S
    for m in MARKERS:
        h = spheres[m.member]
        assert tuple(h.position) == pytest.approx((m.xy[0] * S, m.xy[1] * S, h.position[2]))
        assert 0 < 2 * h.radius < 0.1 * side  # a marker, not a ball filling the square
    assert tuple(spheres[7].color) == palette.KNEE and tuple(spheres[3].color) == palette.BEST
    assert tuple(spheres[9].color) == palette.PATH  # not the member shown (none is)
    # The rest of the front: grey dots, smaller than the spheres one clicks.
    assert inset.front.visible and 0 < inset.front.point_size < 2 * spheres[7].radius
    assert np.asarray(inset.front.points)[:, :2] / S == pytest.approx(np.array([[230.0, 160.0], [260.0, 140.0]]))


def test_the_member_shown_turns_red_and_back_without_rebuilding_the_spheres(inset):
    inset.show(MARKERS, np.zeros((0, 2)), None)
    before = dict(inset._spheres)
    inset.show(MARKERS, np.zeros((0, 2)), 3)
    assert inset._spheres == before  # the same handles, recoloured
    assert tuple(before[3].color) == palette.FOOT and tuple(before[7].color) == palette.KNEE
    inset.show(MARKERS, np.zeros((0, 2)), 7)
    assert tuple(before[3].color) == palette.BEST and tuple(before[7].color) == palette.FOOT


def test_each_candidate_is_tagged_next_to_its_sphere_in_the_scenes_small_text(inset):
    lone = (InsetMarker(7, "K1", "knee", (250.0, 150.0)),)
    inset.show(lone, np.zeros((0, 2)), None)
    (label,) = inset._labels
    sphere = inset._spheres[7]
    assert label.text == "K1" and label.font_scene_height == pytest.approx(0.8 * TEXT)
    x, y, _ = label.position
    assert x == pytest.approx(250.0 * S)
    assert sphere.position[1] + sphere.radius < y < sphere.position[1] + sphere.radius + TEXT  # just above it


def test_the_member_shown_gets_its_label_first_in_a_crowd(inset):
    # QA (session 38): K2 picked in a cluster of knees stood red and unlabelled, its neighbours' labels around it.
    crowd = tuple(InsetMarker(10 + k, f"K{k + 1}", "knee", (240.0 + 2.0 * k, 150.0 + 2.0 * (k % 2)))
                  for k in range(5))
    inset.show(crowd, np.zeros((0, 2)), None)
    unlabelled = {m.member for m in crowd} - {int(lab.name.rsplit("_", 1)[1]) for lab in inset._labels}
    assert unlabelled  # the crowd leaves some without a spot
    last = max(unlabelled)
    inset.show(crowd, np.zeros((0, 2)), last)
    tagged = {lab.text for lab in inset._labels}
    assert f"K{last - 9}" in tagged  # its label, placed first
    spheres = dict(inset._spheres)
    inset.show(crowd, np.zeros((0, 2)), None)  # back: the same spheres, the labels in K1's order again
    assert inset._spheres == spheres
    assert {int(lab.name.rsplit("_", 1)[1]) for lab in inset._labels} == {m.member for m in crowd} - unlabelled


def test_an_empty_front_hides_the_grey_dots_of_the_previous_one(inset):
    inset.show(MARKERS, np.array([[230.0, 160.0]]), None)
    assert inset.front.visible
    inset.show((), np.zeros((0, 2)), None)
    assert not inset.front.visible and inset._spheres == {} and inset._labels == []


def run_animator(fps: float, seconds: float, stall_at: int | None = None, stall: float = 0.0
                 ) -> tuple[list[float], float]:
    """Run an Animator for ``seconds``; the ``stall_at``-th tick takes ``stall`` s. Returns its dts and the wall
    time from start to stop."""
    dts: list[float] = []
    lock = threading.Lock()

    def tick(dt: float) -> None:
        with lock:
            dts.append(dt)
            k = len(dts)
        if k == stall_at:
            time.sleep(stall)

    a = Animator(tick, fps)
    t0 = time.perf_counter()
    a.start()
    time.sleep(seconds)
    a.stop()
    wall = time.perf_counter() - t0
    with lock:
        return list(dts), wall


def test_the_animator_ticks_at_its_rate_with_the_time_between_ticks():
    dts, wall = run_animator(50.0, 0.4)
    assert 5 <= len(dts) <= 25  # 20 at 50 fps (a loaded machine ticks fewer, never more)
    assert all(dt >= 0.0 for dt in dts)
    assert sum(dts) <= wall + 1e-3  # each dt is the time since the previous tick: they add up to at most the run


def test_after_a_slow_frame_the_animator_does_not_rush_to_catch_up():
    # A frame that takes 0.3 s at 20 fps: the next ones come a period apart again, not six at once.
    dts, _ = run_animator(20.0, 0.6, stall_at=2, stall=0.3)
    assert len(dts) >= 4
    assert dts[2] >= 0.3  # the stalled frame's time is passed on to the next tick
    assert not any(dt < 0.001 for dt in dts[3:]), dts


def test_a_failing_frame_does_not_stop_the_animation(capsys):
    calls: list[float] = []

    def tick(dt: float) -> None:
        calls.append(dt)
        if len(calls) == 1:
            raise RuntimeError("bad frame")

    a = Animator(tick, 50.0)
    a.start()
    time.sleep(0.2)
    a.stop()
    assert len(calls) >= 3
    assert "animation frame failed: RuntimeError('bad frame')" in capsys.readouterr().out
