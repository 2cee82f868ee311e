"""World-frame gait: standing feet stay put, the trunk bobs by h_s, every swing is the WT arc."""

from __future__ import annotations

import numpy as np
import pytest

from core.analysis.features import feature_points
from core.analysis.gait import BIPED, arc_offsets, quadruped, walking_trajectory, world_paths
from core.analysis.metrics import stance_fluctuation, stance_length
from core.kinematics.presets import get

N = 360


@pytest.fixture(scope="module", params=["stephenson1/X0", "stephenson1/X3", "stephenson1/MCCMO-X1"])
def leg(request: pytest.FixtureRequest) -> tuple[np.ndarray, np.ndarray]:
    sol = get(request.param).design().solve(N, joints=False, backend="numpy")
    return sol.leg, sol.dleg


def test_standing_feet_do_not_slide(leg: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = leg
    fp = feature_points(path, dpath)
    w = world_paths(path, dpath, fp, BIPED, n_strides=2)
    # sample k is k T / N after leg A's take-off: B stands for k in [0, N/2], A for [N/2, N], ...
    for leg_i, start in ((1, 0), (0, N // 2), (1, N), (0, 3 * N // 2)):
        foot = w.feet[0, leg_i, start : start + N // 2 + 1]
        np.testing.assert_allclose(foot, np.broadcast_to(foot[0], foot.shape), atol=1e-9)
        assert foot[0, 1] == pytest.approx(w.ground[0], abs=1e-7)


def test_trunk_bobs_by_the_stance_fluctuation(leg: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = leg
    fp = feature_points(path, dpath)
    w = world_paths(path, dpath, fp, BIPED, n_strides=2)
    h_s = stance_fluctuation(path, fp)[0]
    bob = np.ptp(w.hip[0, :, 1])
    assert bob == pytest.approx(h_s, abs=0.02 * h_s + 1e-3)  # samples vs refined extremes
    # the hip advances by one stance length per half period (toward -x)
    np.testing.assert_allclose(w.hip[0, N, 0] - w.hip[0, 0, 0], -2 * stance_length(fp)[0], rtol=1e-9)


def test_every_swing_is_the_walking_trajectory_shifted(leg: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = leg
    fp = feature_points(path, dpath)
    wt = walking_trajectory(path, dpath, fp)  # N/2 + 1 samples from t2: the world grid's spacing
    for layout in (BIPED, quadruped(), quadruped(333.0)):
        w = world_paths(path, dpath, fp, layout, n_strides=3)
        shift = arc_offsets(wt.advance, layout)[0]
        for i, ph in enumerate(layout.phases):
            for stride in range(2):
                k0 = int(round(ph * N)) + stride * N  # leg i takes off ph T after leg A
                arc = w.feet[0, i, k0 : k0 + N // 2 + 1]
                expect = wt.points[0] + np.array([shift[i] + 2 * stride * wt.advance[0], 0.0])
                np.testing.assert_allclose(arc, expect, atol=1e-7)


def test_quadruped_rear_module_is_the_front_one_a_trunk_behind(leg: tuple[np.ndarray, np.ndarray]) -> None:
    path, dpath = leg
    fp = feature_points(path, dpath)
    w = world_paths(path, dpath, fp, quadruped(400.0), n_strides=1)
    # rear-right is in phase with front-left, rear-left with front-right (diagonal pairs)
    np.testing.assert_allclose(w.feet[0, 3], w.feet[0, 0] - [400.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(w.feet[0, 2], w.feet[0, 1] - [400.0, 0.0], atol=1e-9)


def test_biped_footprints_alternate_one_stance_apart(leg: tuple[np.ndarray, np.ndarray]) -> None:
    """Eq. 7 with one hip: leg B's WT starts l_s behind leg A's (toward the walking direction)."""
    path, dpath = leg
    fp = feature_points(path, dpath)
    wt = walking_trajectory(path, dpath, fp)
    dx = arc_offsets(wt.advance, BIPED)[0]
    assert dx[0] == 0.0
    assert dx[1] == pytest.approx(-stance_length(fp)[0], rel=1e-12)
