"""The scene's layout numbers worked out by hand: the camera's margin, the walking view's gap, the grid's step
and its lines (a mutation audit of studio/geometry.py found these unchecked)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studio.geometry import Layout, camera_pose, compose, grid_lines, inset_positions, nice_step


def test_the_camera_leaves_fifteen_percent_of_room_around_the_bounds():
    # 200 x 100 mm under a 90 deg field of view (tan 45 deg = 1) on a square canvas: the width decides,
    # half of it with the margin is 115 mm, so the camera stands 115 mm above the centre (100, 50).
    pos, look = camera_pose(np.array([0.0, 0.0, 200.0, 100.0]), math.pi / 2, 1.0)
    np.testing.assert_allclose(look, [0.1, 0.05, 0.0])
    np.testing.assert_allclose(pos, [0.1, 0.05, 0.115])


def test_the_walking_view_sits_one_and_a_half_gaps_below_the_top_views_left_aligned():
    lay = Layout(design=np.array([0.0, 0.0, 100.0, 50.0]), leg=np.array([-10.0, -20.0, 30.0, 20.0]),
                 leg_offset=np.array([170.0, 25.0]), scene=np.array([0.0, 0.0, 200.0, 50.0]))
    c = compose(lay, np.array([-50.0, -10.0, 150.0, 30.0]), gap=60.0)
    # the leg view is drawn at [160, 5, 200, 45]: the inset is a 40 mm square a gap to its right
    np.testing.assert_allclose(c.inset, [260.0, 5.0, 300.0, 45.0])
    # its top 90 mm (1.5 x 60) below the lowest of the top views and the inset, its left edge at theirs
    np.testing.assert_allclose(c.walk_offset, [50.0, -120.0])
    np.testing.assert_allclose(c.bounds, [0.0, -130.0, 300.0, 50.0])
    assert compose(lay, np.array([-50.0, -10.0, 150.0, 30.0]), gap=60.0, walk_gap=10.0).walk_offset[1] == -40.0


@pytest.mark.parametrize(("span", "step"), [(40.0, 1.0), (60.0, 2.0), (80.0, 2.0), (100.0, 5.0), (200.0, 5.0),
                                            (300.0, 10.0), (0.4, 0.01)])
def test_the_grid_step_is_the_smallest_1_2_5_step_giving_at_most_40_lines(span: float, step: float):
    assert nice_step(span) == pytest.approx(step)


def test_the_grid_covers_the_box_and_its_margin_with_lines_at_both_ends():
    # [0, 100] with 10 % margins is [-10, 110]: 120 mm over 40 lines is 3 mm, rounded up to a 5 mm step;
    # -10, -5, ..., 110 are 25 lines each way.
    segs, step = grid_lines(np.array([0.0, 0.0, 100.0, 100.0]))
    assert step == 5.0 and segs.shape == (50, 2, 2)
    vertical, horizontal = segs[:25], segs[25:]
    np.testing.assert_allclose(vertical[:, 0, 0], np.arange(-10.0, 111.0, 5.0))
    np.testing.assert_allclose(horizontal[:, 0, 1], np.arange(-10.0, 111.0, 5.0))
    np.testing.assert_allclose(vertical[0], [[-10.0, -10.0], [-10.0, 110.0]])
    np.testing.assert_allclose(horizontal[-1], [[-10.0, 110.0], [110.0, 110.0]])


def test_inset_points_fill_the_inner_square_and_a_constant_objective_sits_in_its_middle():
    box = np.array([0.0, 0.0, 100.0, 100.0])  # 10 % margin: the points fill [10, 90] on each axis
    out = inset_positions(np.array([[0.0, 3.0], [10.0, 3.0], [5.0, 3.0], [np.nan, 1.0]]), box)
    np.testing.assert_allclose(out, [[10.0, 50.0], [90.0, 50.0], [50.0, 50.0], [0.0, 0.0]])


def test_the_inset_is_at_least_half_as_high_as_the_top_views():
    # The RTCLM's small bench view beside its large linkage gave a square too small to click in (rehearsal 5).
    lay = Layout(design=np.array([0.0, 0.0, 100.0, 300.0]), leg=np.array([-10.0, -20.0, 30.0, 20.0]),
                 leg_offset=np.array([170.0, 25.0]), scene=np.array([0.0, 0.0, 200.0, 300.0]))
    c = compose(lay, None, gap=60.0)
    np.testing.assert_allclose(c.inset, [260.0, 25.0 - 75.0, 410.0, 25.0 + 75.0])  # 150 mm around the leg view
