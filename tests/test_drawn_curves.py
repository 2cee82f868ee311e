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


def _chains(seg: np.ndarray, colors: np.ndarray | None) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """The input's chains (joined segments of one colour, finite): their samples and colour."""
    ok = np.isfinite(seg).all(axis=(1, 2))
    seg, colors = seg[ok], None if colors is None else colors[ok]
    out, s = [], 0
    for i in range(1, len(seg) + 1):
        if i == len(seg) or (seg[i, 0] != seg[i - 1, 1]).any() or (
                colors is not None and (colors[i, 0] != colors[i - 1, 0]).any()):
            out.append((np.concatenate([seg[s:i, 0], seg[i - 1 : i, 1]]), None if colors is None else colors[s, 0]))
            s = i
    return out


def _check(seg: np.ndarray, drawn: np.ndarray, colors: np.ndarray | None = None,
           painted: np.ndarray | None = None) -> None:
    """Walk the drawn segments along the input's chains, in order: each joins samples i < j of one chain (so none
    bridges a gap or a colour change), the samples between are within the tolerance of it, it has the chain's
    colour, and each chain is drawn from its first sample to its last. With repeated points a drawn end can be
    several samples, and a chain's end the next one's start: every reading ``(chain, sample)`` is followed."""
    pts = seg[np.isfinite(seg).all(axis=(1, 2))].reshape(-1, 2)
    tol = DRAWN * np.ptp(pts, axis=0).max() * (1 + 1e-9) + 1e-12
    chains = _chains(seg, colors)
    at = {(0, 0)}
    for k, (u, v) in enumerate(drawn):
        # a reading at a chain's last sample may go on from the next chain's first
        at |= {(c + 1, 0) for c, i in at if i == len(chains[c][0]) - 1 and c + 1 < len(chains)}
        nxt = set()
        for c, i in at:
            samples, colour = chains[c]
            if not (samples[i] == u).all() or (colour is not None and not (painted is not None
                                                                            and (painted[k] == colour).all())):
                continue
            for j in np.flatnonzero((samples[i + 1 :] == v).all(axis=1)) + i + 1:
                if (_to_segments(samples[i : j + 1], u[None], v[None]) <= tol).all():
                    nxt.add((c, int(j)))
        assert nxt, f"drawn segment {k} does not follow a chain within the tolerance in its colour"
        at = nxt
    assert (len(chains) - 1, len(chains[-1][0]) - 1) in at, "the drawing does not end at the last chain's end"


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
    # out along x to 100 and back, 0.001 mm above: the tip (100, 0) lies on the line through the ends (0, 0)
    # and (1.02, 0.001) of a chord RDP measuring to lines would take, within 0.05 % of the extent
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
    _check(seg, drawn, colors, painted)
    # no drawn segment bridges the gap from arc[80] to arc[82] (x falls along the arc)
    gap = (drawn[:, 0, 0] >= arc[80, 0]) & (drawn[:, 1, 0] <= arc[82, 0])
    assert not gap.any()
    # each drawn segment has the colour of the samples it passes: red ones start at or after segment 120's start
    red = (painted[:, 0] == (200, 10, 10)).all(axis=1)
    start_x = seg[120, 0, 0]
    assert (drawn[red, 0, 0] <= start_x + 1e-12).all() and (drawn[~red, 1, 0] >= start_x - 1e-12).all()
    assert red.any() and (~red).any()
    np.testing.assert_array_equal(painted[:, 0], painted[:, 1])


def test_each_segment_its_own_colour_is_drawn_as_given_and_a_colour_change_on_a_line_stays() -> None:
    # Review of session 39: a colour index off by the chain's number, or no break at a colour change, passed.
    t = np.linspace(0, np.pi, 100)
    arc = np.stack([100 * np.cos(t), 100 * np.sin(t)], axis=1)
    seg = np.stack([arc[:-1], arc[1:]], axis=1)
    colors = np.zeros((len(seg), 2, 3), dtype=np.uint8)
    colors[1::2] = (200, 10, 10)
    line = np.stack([np.linspace(0, 100, 60), np.zeros(60)], axis=1)
    lseg = np.stack([line[:-1], line[1:]], axis=1)
    lcol = np.zeros((len(lseg), 2, 3), dtype=np.uint8)
    lcol[30:] = (0, 200, 0)
    (d, c), (dl, cl) = simplified((seg, colors), (lseg, lcol))
    np.testing.assert_array_equal(d, seg)
    np.testing.assert_array_equal(c, colors)
    assert len(dl) == 2 and (dl[0, 1] == line[30]).all() and cl is not None
    np.testing.assert_array_equal(cl[:, 0], [[0, 0, 0], [0, 200, 0]])
    _check(lseg, dl, lcol, cl)


@given(st.integers(0, 10_000))
@settings(max_examples=80, deadline=None)
def test_random_chains_with_gaps_colours_and_repeated_points_are_drawn_within_the_tolerance(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 200))
    pts = np.cumsum(rng.standard_normal((n + 1, 2)) * rng.choice([0.0, 1.0, 10.0], size=(n + 1, 1)), axis=0)
    seg = np.stack([pts[:-1], pts[1:]], axis=1)
    seg = seg[rng.random(n) > 0.1]  # gaps
    colors = np.repeat(np.array([[0, 0, 0], [9, 9, 9]], dtype=np.uint8)[rng.integers(0, 2, len(seg)) * (
        rng.random() < 0.5)][:, None], 2, axis=1)
    if len(seg) and rng.random() < 0.2:
        seg[int(rng.integers(len(seg))), 1] = np.nan  # left out: a gap
    [(drawn, painted)] = simplified((seg, colors))
    assert np.isfinite(drawn).all()
    if len(drawn):
        _check(seg, drawn, colors, painted)
    else:
        assert not np.isfinite(seg).all(axis=(1, 2)).any()


def test_curves_given_together_are_drawn_as_each_alone() -> None:
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    a = closed_polyline(np.stack([np.cos(t), np.sin(3 * t)], axis=1))
    b = closed_polyline(1000 * np.stack([np.cos(t), 0.2 * np.sin(t)], axis=1))
    together = simplified((a, None), (b, None), (np.zeros((0, 2, 2)), None))
    assert len(together[2][0]) == 0
    for (x, _), (y, _) in zip(together[:2], [simplified((a, None))[0], simplified((b, None))[0]], strict=True):
        np.testing.assert_array_equal(x, y)


def test_the_default_scene_draws_an_eighth_of_its_curve_segments() -> None:
    view = Session.default().view
    f = build_frames(view)
    n = view.n_samples
    drawn = len(f.path) + len(f.target) + len(f.leg_path) + len(f.leg_target) + len(f.walk.trails)
    assert drawn < (4 * n + 2 * (n - 1)) / 6
    stance = view.stance
    assert stance is not None
    # the stance and swing colours are both still there, and each foot's trail keeps its leg's colour
    assert len(np.unique(f.leg_path_colors.reshape(-1, 3), axis=0)) == 2
    assert len(np.unique(f.walk.trail_colors.reshape(-1, 3), axis=0)) == f.walk.feet.shape[1] == 2
