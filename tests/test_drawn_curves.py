"""The scene's curves are drawn with fewer segments (studio.geometry.simplified): every sample stays within
0.05 % of its curve's extent of what is drawn, ends, gaps and colour changes stay where they were, and a
hairpin keeps its tip."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.frames import build_frames
from studio.geometry import DRAWN, closed_polyline, simplified
from studio.state import Session


def _to_segments(p: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Distance of each point of p ``(n, 2)`` to the nearest of the segments q-s ``(k, 2)``."""
    d = s - q
    r = p[:, None, :] - q[None]
    t = np.clip((r * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(r - t[..., None] * d, axis=-1).min(axis=1)


def _check(seg: np.ndarray, drawn: np.ndarray) -> None:
    pts = seg.reshape(-1, 2)
    ext = np.ptp(pts, axis=0).max()
    assert (_to_segments(pts, drawn[:, 0], drawn[:, 1]) <= DRAWN * ext * (1 + 1e-9) + 1e-12).all()
    # every drawn end is a sample
    ends = drawn.reshape(-1, 2)
    assert (np.abs(ends[:, None] - pts[None]).sum(-1).min(axis=1) == 0).all()


curve_points = st.integers(3, 400).flatmap(lambda n: st.tuples(
    st.just(n), st.floats(0.1, 1e4), st.floats(0.0, 1.0), st.integers(1, 7), st.floats(0.0, 0.5)))


@given(curve_points)
@settings(max_examples=60, deadline=None)
def test_every_sample_stays_within_the_tolerance_of_the_drawn_curve(args) -> None:
    n, size, noise, lobes, wiggle = args
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rng = np.random.default_rng(n)
    r = 1 + wiggle * np.cos(lobes * t) + noise * 0.01 * rng.standard_normal(n)
    seg = closed_polyline(size * np.stack([r * np.cos(t), 0.6 * r * np.sin(t)], axis=1))
    [(drawn, colors)] = simplified((seg, None))
    assert colors is None and len(drawn) <= len(seg)
    _check(seg, drawn)
    # closed: the drawn segments join end to start and come back to the first sample
    np.testing.assert_array_equal(drawn[1:, 0], drawn[:-1, 1])
    np.testing.assert_array_equal(drawn[-1, 1], drawn[0, 0])


def test_a_smooth_path_needs_a_fifth_of_its_segments_and_a_hairpin_keeps_its_tip() -> None:
    t = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    ellipse = closed_polyline(np.stack([150 * np.cos(t), 50 * np.sin(t)], axis=1))
    # out along x to 100 and back, 0.001 mm above: every sample lies on the line of the chord (0,0)-(0,0.001)
    x = np.concatenate([np.linspace(0, 100, 50), np.linspace(100, 0, 50)[1:]])
    hairpin = np.stack([x[:-1], np.r_[np.zeros(50), np.full(48, 0.001)]], axis=1)
    hp = np.stack([hairpin[:-1], hairpin[1:]], axis=1)
    (e, _), (h, _) = simplified((ellipse, None), (hp, None))
    assert len(e) < len(ellipse) / 5
    assert np.abs(h[:, :, 0] - 100).min() == 0  # the tip is drawn
    _check(hp, h)


def test_gaps_and_colour_changes_stay_where_they_are() -> None:
    t = np.linspace(0, np.pi, 200)
    arc = np.stack([100 * np.cos(t), 100 * np.sin(t)], axis=1)
    seg = np.stack([arc[:-1], arc[1:]], axis=1)
    seg = np.delete(seg, [80, 81], axis=0)  # a gap: segments 80 and 81 are not drawn (the leg does not assemble)
    colors = np.zeros((len(seg), 2, 3), dtype=np.uint8)
    colors[120:] = (200, 10, 10)  # swing from segment 120 on
    [(drawn, painted)] = simplified((seg, colors))
    assert painted is not None and painted.shape == (len(drawn), 2, 3) and painted.dtype == np.uint8
    _check(seg, drawn)
    # no drawn segment bridges the gap from arc[80] to arc[82] (x falls along the arc)
    gap = (drawn[:, 0, 0] >= arc[80, 0]) & (drawn[:, 1, 0] <= arc[82, 0])
    assert not gap.any()
    # each drawn segment has the colour of the samples it passes: red ones start at or after segment 120's start
    red = (painted[:, 0] == (200, 10, 10)).all(axis=1)
    start_x = seg[120, 0, 0]
    assert (drawn[red, 0, 0] <= start_x + 1e-12).all() and (drawn[~red, 1, 0] >= start_x - 1e-12).all()
    assert red.any() and (~red).any()
    np.testing.assert_array_equal(painted[:, 0], painted[:, 1])


def test_curves_given_together_are_drawn_as_each_alone() -> None:
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    a = closed_polyline(np.stack([np.cos(t), np.sin(3 * t)], axis=1))
    b = closed_polyline(1000 * np.stack([np.cos(t), 0.2 * np.sin(t)], axis=1))
    together = simplified((a, None), (b, None), (np.zeros((0, 2, 2)), None))
    assert len(together[2][0]) == 0
    for (x, _), (y, _) in zip(together[:2], [simplified((a, None))[0], simplified((b, None))[0]], strict=True):
        np.testing.assert_array_equal(x, y)


def test_the_default_scene_draws_a_fifth_of_its_curve_segments() -> None:
    view = Session.default().view
    f = build_frames(view)
    n = view.n_samples
    drawn = len(f.path) + len(f.target) + len(f.leg_path) + len(f.leg_target) + len(f.walk.trails)
    assert drawn < (4 * n + 2 * (n - 1)) / 4
    stance = view.stance
    assert stance is not None
    # the stance and swing colours are both still there
    assert len(np.unique(f.leg_path_colors.reshape(-1, 3), axis=0)) == 2
