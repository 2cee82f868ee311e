"""Knee points and candidate ranking (core.optimize.decision) on fronts whose knee is known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from core.optimize.decision import best_per_objective, pareto_front, shortlist


def corner_front(knee: tuple[float, float], n: int = 60) -> np.ndarray:
    """Piecewise-linear 2-D front (0, 1) -> knee -> (1, 0): its knee is the corner."""
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    a = np.outer(1 - t, [0.0, 1.0]) + np.outer(t, knee)
    b = np.outer(1 - t, knee) + np.outer(t, [1.0, 0.0])
    return np.vstack([a, b, [[1.0, 0.0]]])


def octant_front(n: int = 15) -> np.ndarray:
    """Convex 3-D front f = 1 - u, u on the unit sphere's positive octant; knee f = (1 - 1/sqrt 3) (1, 1, 1)."""
    th, ph = np.meshgrid(np.linspace(0, np.pi / 2, n), np.linspace(0, np.pi / 2, n))
    u = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    u = np.vstack([u, np.ones(3) / np.sqrt(3.0)])
    return 1.0 - u


def naive_front(F: np.ndarray, cv: np.ndarray | None = None) -> list[int]:
    out = []
    for i, a in enumerate(F):
        if not np.isfinite(a).all() or (cv is not None and not cv[i] <= 0):
            continue
        if not any(
            np.isfinite(b).all() and (cv is None or cv[j] <= 0) and (b <= a).all() and (b < a).any()
            for j, b in enumerate(F)
        ):
            out.append(i)
    return out


@pytest.mark.parametrize("knee", [(0.2, 0.2), (0.1, 0.5), (0.6, 0.05)])
def test_corner_of_a_2d_front_is_the_first_knee(knee: tuple[float, float]) -> None:
    F = corner_front(knee)
    rng = np.random.default_rng(0)
    # Dominated and infeasible extras, shuffled: the answer must not depend on them or on order.
    extra = F[rng.integers(0, len(F), 40)] + rng.uniform(0.01, 0.3, (40, 2))
    bad = np.array([[-1.0, -1.0], [np.nan, 0.0]])
    allF = np.vstack([F, extra, bad])
    cv = np.r_[np.zeros(len(F) + len(extra)), 5.0, 0.0]
    perm = rng.permutation(len(allF))
    sl = shortlist(allF[perm], cv[perm])
    np.testing.assert_array_equal(allF[perm][sl.knees[0]], knee)


def test_knee_of_a_convex_3d_front_is_its_closed_form() -> None:
    F = octant_front()
    sl = shortlist(F)
    np.testing.assert_allclose(F[sl.knees[0]], np.full(3, 1.0 - 1.0 / np.sqrt(3.0)), atol=1e-12)


def test_knee_of_a_quarter_circle_is_its_middle() -> None:
    t = np.linspace(0.0, np.pi / 2, 91)
    F = 1.0 - np.stack([np.cos(t), np.sin(t)], 1)  # convex front; knee at t = pi/4 by symmetry
    assert shortlist(F).knees[0] == 45


@given(
    scale=arrays(np.float64, 2, elements=st.floats(1e-3, 1e3)),
    shift=arrays(np.float64, 2, elements=st.floats(-1e3, 1e3)),
)
@settings(max_examples=40, deadline=None)
def test_knees_do_not_depend_on_objective_units(scale: np.ndarray, shift: np.ndarray) -> None:
    F = corner_front((0.3, 0.15), 30)
    assert shortlist(F * scale + shift).knees == shortlist(F).knees


def test_several_knees_are_ranked_distinct_and_capped() -> None:
    # A staircase of 12 convex corners along the line f1 + f2 = 1: each corner is a local knee.
    corners = np.linspace(0, 1, 13)
    pts = []
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        c = np.array([a + 0.2 * (b - a), 1 - b + 0.2 * (b - a)])  # pulled towards the ideal
        s = np.linspace(0, 1, 8, endpoint=False)[:, None]
        pts += [np.array([a, 1 - a]) * (1 - s) + c * s, c * (1 - s) + np.array([b, 1 - b]) * s]
    F = np.vstack(pts + [[[1.0, 0.0]]])
    full = shortlist(F, n_max=10, radius=0.05)
    assert len(full.knees) == 10
    assert len({tuple(F[i]) for i in full.knees}) == 10
    assert (np.diff(full.scores) <= 1e-9).all()  # ranked (equal scores are ties)
    assert shortlist(F, n_max=3, radius=0.05).knees == full.knees[:3]
    for n_max in (0, -1, 2.5, True):  # "at most n_max": none would leave the knee pick nothing
        with pytest.raises(ValueError, match="n_max must be an integer >= 1"):
            shortlist(F, n_max=n_max)  # type: ignore[arg-type]
    for radius in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="radius must be a finite number >= 0"):
            shortlist(F, radius=radius)


def test_one_point_front() -> None:
    sl = shortlist(np.array([[3.0, 4.0, 5.0]]))
    assert (sl.knees, sl.best, sl.front, sl.fallback) == ((0,), (0, 0, 0), (0,), None)


def test_two_point_front_gives_one_knee_and_both_extremes() -> None:
    sl = shortlist(np.array([[1.0, 2.0], [2.0, 1.0]]))
    assert len(sl.knees) == 1 and sl.knees[0] in (0, 1)
    assert sl.best == (0, 1) and sl.front == (0, 1)


def test_collinear_front_gives_the_point_nearest_the_ideal() -> None:
    t = np.linspace(0.0, 1.0, 21)
    F = np.stack([t, 1.0 - t, np.full_like(t, 7.0)], 1)  # straight, third objective constant
    sl = shortlist(F)
    assert sl.knees == (10,)
    assert sl.best[0] == 0 and sl.best[1] == 20


def test_an_objective_that_varies_by_rounding_near_zero_does_not_count() -> None:
    t = np.linspace(0.0, 1.0, 21)
    noise = np.where(np.arange(21) % 3 == 1, 1e-14, 0.0)  # a constant 0 up to rounding: not an objective to trade
    sl = shortlist(np.stack([t, 1.0 - t, noise], 1))
    assert sl.knees == (10,)


def test_the_fallback_among_equal_violations_prefers_defined_objectives() -> None:
    F = np.array([[np.nan, 1.0], [2.0, 3.0], [1.0, 1.0]])
    sl = shortlist(F, np.array([2.0, 2.0, 2.0]))
    assert sl.knees == () and sl.fallback == 1


def test_duplicates_collapse_to_their_first_member() -> None:
    F = corner_front((0.2, 0.2), 20)
    dup = np.vstack([F, F, F])
    sl, ref = shortlist(dup), shortlist(F)
    assert sl.knees == ref.knees  # first occurrences are the original rows
    assert len(sl.front) == 3 * len(ref.front)


def test_all_infeasible_gives_empty_shortlist_and_least_violation_fallback() -> None:
    F = corner_front((0.2, 0.2), 10)
    cv = np.linspace(5.0, 1.0, len(F))
    cv[3] = 0.5
    sl = shortlist(F, cv)
    assert (sl.knees, sl.best, sl.front) == ((), (), ())
    assert sl.fallback == 3 and sl.first == 3


def test_nan_rows_are_ignored() -> None:
    F = corner_front((0.25, 0.1), 20)
    noisy = np.vstack([np.full((3, 2), np.nan), F, [[np.nan, -5.0]]])
    sl, ref = shortlist(noisy), shortlist(F)
    assert tuple(i - 3 for i in sl.knees) == ref.knees
    assert tuple(i - 3 for i in sl.best) == ref.best


def test_empty_input() -> None:
    sl = shortlist(np.zeros((0, 2)), np.zeros(0))
    assert (sl.knees, sl.best, sl.front, sl.fallback) == ((), (), (), None)


@given(
    F=arrays(np.float64, st.tuples(st.integers(1, 25), st.integers(1, 3)), elements=st.integers(0, 4).map(float)),
    data=st.data(),
)
@settings(max_examples=60, deadline=None)
def test_front_and_best_match_brute_force(F: np.ndarray, data: st.DataObject) -> None:
    cv = np.array(data.draw(st.lists(st.sampled_from([0.0, 0.0, 1.0, np.nan]), min_size=len(F), max_size=len(F))))
    assert list(pareto_front(F, cv)) == naive_front(F, cv)
    best = best_per_objective(F, cv)
    ok = [i for i in range(len(F)) if cv[i] <= 0]
    if not ok:
        assert best == ()
        return
    for m, i in enumerate(best):
        keys = [tuple([F[j, m]] + [F[j, k] for k in range(F.shape[1]) if k != m] + [j]) for j in ok]
        assert i == min(keys)[-1]
    sl = shortlist(F, cv)
    assert 1 <= len(sl.knees) <= 10
    assert set(sl.knees) <= set(sl.front)
    assert len({tuple(F[i]) for i in sl.knees}) == len(sl.knees)


def test_a_front_that_differs_only_by_rounding_has_one_knee_and_no_error():
    # Seen in a real stage: two members 1e-14 apart in f1 and 6e-12 in f2.
    F = np.array([[6.62194761, 36.42620847], [6.62194761 + 1e-14, 36.42620847 - 6e-12]])
    sl = shortlist(F)
    assert len(sl.knees) == 1 and sl.knees[0] in (0, 1)
