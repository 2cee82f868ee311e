"""The array-based evolution blocks against small cases computed by hand (spec §8.3 item 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from core.optimize.evolve import spea2
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.sorting import cdp_better, cdp_ranks, crowding, nd_ranks
from core.optimize.evolve.variation import de_rand_1, ga, polynomial_mutation, sbx
from core.optimize.evolve.weights import das_dennis, neighbours, pbi, tchebycheff


def test_non_dominated_sort_of_a_hand_made_set():
    F = np.array([[1, 5], [2, 3], [3, 1], [2, 4], [4, 4], [5, 5]], dtype=float)
    # (2,4) is dominated by (2,3); (4,4) by (2,4); (5,5) by (4,4).
    assert nd_ranks(F).tolist() == [0, 0, 0, 1, 2, 3]


def test_constraint_domination_puts_feasible_fronts_first_then_violation_order():
    F = np.array([[1, 5], [2, 3], [0, 0], [0, 1], [9, 9]], dtype=float)
    cv = np.array([0.0, 0.0, 2.0, 0.5, 0.0])
    # Feasible: (1,5),(2,3) front 0; (9,9) front 1. Infeasible after: cv 0.5 then cv 2.
    assert cdp_ranks(F, cv).tolist() == [0, 0, 3, 2, 1]
    assert cdp_ranks(F, np.full(5, 1.0)).tolist() == [0, 0, 0, 0, 0]  # equal violation: one front
    assert cdp_better(F, cv, np.array([0, 3, 1]), np.array([2, 2, 4])).tolist() == [True, True, True]


def test_crowding_of_a_four_point_front():
    F = np.array([[0, 4], [1, 2], [2, 1], [4, 0]], dtype=float)
    cd = crowding(F, np.zeros(4, dtype=np.int64))
    # objective 1 (range 4): (1,2) gets (2-0)/4, (2,1) gets (4-1)/4; objective 2 the mirror image.
    assert cd[0] == cd[3] == math.inf
    np.testing.assert_allclose(cd[1:3], [0.5 + 0.75, 0.75 + 0.5])
    assert crowding(F[:2], np.zeros(2, dtype=np.int64)).tolist() == [math.inf, math.inf]


def test_spea2_fitness_of_a_hand_computed_set():
    F = np.array([[0, 0], [1, 1], [2, 0.5], [0, 2]], dtype=float)
    # (0,0) dominates all three others: S = 3, R = 3 for each of them; k = floor(sqrt(4)) = 2nd nearest.
    want = [0 + 1 / (2 + 2), 3 + 1 / (math.sqrt(2) + 2), 3 + 1 / (math.sqrt(4.25) + 2), 3 + 1 / (2 + 2)]
    np.testing.assert_allclose(spea2.fitness(F), want, rtol=1e-12)


def test_spea2_constraint_domination_orders_infeasible_by_violation():
    F = np.array([[0, 0], [5, 5], [1, 1]], dtype=float)
    cv = np.array([3.0, 0.0, 1.0])
    D = spea2.dominance(F, cv)
    # smaller cv dominates whatever the objectives: (5,5) > (1,1) > (0,0)
    assert D.tolist() == [[False, False, False], [True, False, True], [True, False, False]]


def fitness_by_definition(F, cv=None):
    """SPEA2's fitness as written, from the (n, n) dominance and distance matrices."""
    D = spea2.dominance(F, cv)
    S = D.sum(axis=1)
    R = (D * S[:, None]).sum(axis=0)
    k = int(math.floor(math.sqrt(len(F))))
    sigma = np.sort(spea2.distances(F), axis=1)[:, k - 1]
    return R + 1.0 / (sigma + 2.0)


@settings(max_examples=150, deadline=None)
@given(st.integers(2, 30).flatmap(lambda n: st.tuples(
    arrays(np.float64, (n, 3), elements=st.sampled_from([0.0, 0.5, 1.0, 2.0, 3.0, np.inf, np.nan])),
    st.one_of(st.none(), arrays(np.float64, (n,), elements=st.sampled_from([0.0, 0.0, 1.0, 2.5, np.nan]))))))
def test_spea2_fitness_equals_its_definition_with_ties_and_penalised_members(case):
    F, cv = case  # one fused pass (no distance matrix, a heap per row) must give the definition's numbers
    assert spea2.fitness(F, cv).tolist() == fitness_by_definition(F, cv).tolist()


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 90), st.integers(1, 3), st.integers(0, 2**32 - 1))
def test_spea2_fitness_does_not_depend_on_the_members_order(n, m, seed):
    # the kernel visits members sorted by the first objective; shuffling them must only shuffle the fitness,
    # and it must still be the definition's on continuous values (each heap replaced many times)
    rng = np.random.default_rng(seed)
    F = rng.normal(size=(n, m))
    cv = np.where(rng.random(n) < 0.3, rng.random(n), 0.0)
    perm = rng.permutation(n)
    fit = spea2.fitness(F, cv)
    assert spea2.fitness(F[perm], cv[perm]).tolist() == fit[perm].tolist()
    assert fit.tolist() == fitness_by_definition(F, cv).tolist()


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 40).flatmap(lambda n: arrays(np.float64, (n, 3),
       elements=st.one_of(st.floats(-1e3, 1e3), st.sampled_from([np.inf, np.nan])))))
def test_spea2_distances_are_euclidean_with_inf_where_undefined(F):
    with np.errstate(invalid="ignore"):  # inf - inf
        want = np.sqrt(((F[:, None, :] - F[None, :, :]) ** 2).sum(axis=2))
    want = np.where(np.isnan(want), np.inf, want)
    np.fill_diagonal(want, np.inf)
    assert spea2.distances(F).tolist() == want.tolist()


@pytest.mark.parametrize("n, seed", [(150, 1), (400, 2), (900, 3)])
def test_spea2_fitness_of_large_pools_equals_its_definition(n, seed):
    # large enough for the k-th distance to be selected below the triangle-inequality bound; a sphere's points
    # (a front), copies of some, and a few penalised members
    rng = np.random.default_rng(seed)
    X = rng.random((n, 3))
    F = X / np.linalg.norm(X, axis=1, keepdims=True) * (1 + 0.2 * rng.random((n, 1)))
    F[n // 3 : n // 3 + 10] = F[:10]
    F[-3:] = np.inf
    cv = np.where(rng.random(n) < 0.4, rng.random(n), 0.0)
    assert spea2.fitness(F, cv).tolist() == fitness_by_definition(F, cv).tolist()
    assert spea2.fitness(F).tolist() == fitness_by_definition(F).tolist()


def truncate_by_definition(F, keep):
    """SPEA2's truncation as written: re-sort every remaining member's distances after each removal and drop the
    lexicographically smallest row (ties: the lowest index)."""
    D = spea2.distances(F)
    alive = list(range(len(F)))
    while len(alive) > keep:
        rows = [sorted(D[i, j] for j in alive) for i in alive]
        alive.pop(min(range(len(alive)), key=lambda k: (rows[k], k)))
    return np.isin(np.arange(len(F)), alive)


@settings(max_examples=150, deadline=None)
@given(st.integers(2, 24).flatmap(lambda n: st.tuples(
    arrays(np.float64, (n, 2), elements=st.sampled_from([0.0, 1.0, 2.0, 3.0, 5.0, np.inf])),
    st.integers(1, n))))
def test_spea2_truncation_equals_its_definition_with_ties_and_penalised_members(case):
    F, keep = case  # a small grid: many equal distances, duplicates, and +inf (penalised) members
    assert spea2.truncate(F, keep).tolist() == truncate_by_definition(F, keep).tolist()


@pytest.mark.parametrize("seed", range(4))
def test_spea2_truncation_of_a_larger_pool_equals_its_definition(seed):
    # each row lists its nearest few members; cutting 70 down to 6 exhausts those lists and makes them again
    rng = np.random.default_rng(seed)
    F = rng.normal(size=(70, 2)) if seed % 2 else rng.integers(0, 6, size=(70, 2)).astype(float)
    for keep in (6, 35):
        assert spea2.truncate(F, keep).tolist() == truncate_by_definition(F, keep).tolist()


@pytest.mark.parametrize("keep", [3, 8, 12, 20])
def test_spea2_truncation_with_copies_equals_its_definition(keep):
    # CMOES truncates unions with many exact copies, which go first in one step when the removals cover them;
    # two points whose difference underflows (distance 0, not copies) keep the member-by-member way
    rng = np.random.default_rng(keep)
    base = rng.normal(size=(10, 2))
    F = np.vstack([base, base[:6], base[:3], base[[0]]])  # 10 surplus copies among 20
    assert spea2.truncate(F, keep).tolist() == truncate_by_definition(F, keep).tolist()
    tiny = F.copy()
    tiny[-1] = tiny[0] + np.array([1e-200, 0.0])
    assert spea2.distances(tiny)[0, -1] == 0.0
    assert spea2.truncate(tiny, keep).tolist() == truncate_by_definition(tiny, keep).tolist()
    # the distinct points' kernel reports such a pair instead of cutting (it does not look for copies)
    distinct = np.vstack([base, tiny[-1]])
    assert spea2._truncate(spea2.distances(distinct), distinct, min(keep, 10), True)[1] == spea2.ZERO
    assert spea2._truncate(spea2.distances(base), base, min(keep, 9), True)[1] != spea2.ZERO


def test_spea2_keeps_its_scratch_matrix_for_pools_up_to_its_limit_only(monkeypatch):
    # review of session 34: the per-thread distance matrix only grew (one cut of a huge pool kept it for good)
    monkeypatch.setattr(spea2, "SCRATCH_KEPT", 30 * 30)
    monkeypatch.setattr(spea2._scratch, "D", None, raising=False)
    rng = np.random.default_rng(3)
    for n, kept in ((20, 20 * 20), (50, 20 * 20), (30, 30 * 30), (25, 30 * 30)):
        F = rng.normal(size=(n, 2))
        assert spea2.truncate(F, 5).tolist() == truncate_by_definition(F, 5).tolist()
        assert spea2._scratch.D.size == kept


def test_spea2_truncation_drops_the_most_crowded_member():
    F = np.array([[0, 3], [1, 2], [1.1, 1.9], [3, 0]], dtype=float)
    # (1,2) and (1.1,1.9) are nearest each other; (1,2) is also nearer its next neighbour (sqrt 2 < 1.556).
    assert spea2.truncate(F, 3).tolist() == [True, False, True, True]
    order, fit, mask = spea2.select(F, 3)
    assert mask.tolist() == [True, False, True, True]
    assert sorted(order.tolist()) == [0, 2, 3] and np.all(np.diff(fit) >= 0)


def test_spea2_select_fills_with_the_best_dominated_when_too_few_are_non_dominated():
    F = np.array([[0, 0], [1, 1], [2, 2], [3, 3]], dtype=float)
    order, fit, mask = spea2.select(F, 2)
    assert order.tolist() == [0, 1] and mask.tolist() == [True, True, False, False]


def select_by_definition(F, n, cv=None, fit_F=None, fill=True):
    """SPEA2's environmental selection as written: every member's fitness, then fill or truncate."""
    fit = spea2.fitness(F if fit_F is None else fit_F, cv)  # itself checked against the definition above
    marked = fit < 1.0
    if marked.sum() < n and fill:
        mask = np.isin(np.arange(len(F)), np.argsort(fit, kind="stable")[:n])
    elif marked.sum() > n:
        idx = np.flatnonzero(marked)
        mask = np.isin(np.arange(len(F)), idx[spea2.truncate(F[idx], n)])
    else:
        mask = marked
    surv = np.flatnonzero(mask)
    order = surv[np.argsort(fit[surv], kind="stable")]
    return order, fit[order], mask


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 70), st.integers(1, 4), st.integers(0, 2**32 - 1),
       st.sampled_from(["plain", "cv", "fit_F", "infeasible"]))
def test_spea2_select_equals_its_definition(size, m, seed, kind):
    # select computes only the survivors' densities when enough members are non-dominated; the survivors, their
    # order and their fitness must be the definition's (fill, exact and truncation cases; copies; +inf members)
    rng = np.random.default_rng(seed)
    F = rng.normal(size=(size, m)) if seed % 3 else rng.integers(0, 4, size=(size, m)).astype(float)
    if seed % 5 == 0:
        F[rng.random(size) < 0.2] = np.inf
    cv = np.where(rng.random(size) < 0.4, rng.random(size), 0.0) if kind == "cv" else None
    if kind == "infeasible":  # every member violates, with ties: the least violation's Pareto set leads
        cv = 1.0 + rng.integers(0, 3, size).astype(float)
    fit_F = np.hstack([F, rng.random((size, 1))]) if kind == "fit_F" else None
    if seed % 7 == 0:  # exact copies, computed once
        F[size // 2 :] = F[: size - size // 2]
    for n in sorted({1, max(1, size // 3), max(1, size // 2), size, size + 2}):
        for fill in (True, False):  # without fill: the non-dominated members only (CMOES's EvenSearch)
            got, want = spea2.select(F, n, cv, fit_F, fill=fill), select_by_definition(F, n, cv, fit_F, fill)
            assert got[0].tolist() == want[0].tolist() and got[2].tolist() == want[2].tolist()
            assert got[1].tolist() == want[1].tolist()
        if fit_F is None:  # the mask alone (DRLOS-EMCMO's success counts)
            assert spea2.survivors(F, n, cv).tolist() == select_by_definition(F, n, cv)[2].tolist()


def test_spea2_cuts_are_reused_for_the_same_members_only():
    # CMOES, CMOEMT and IMTCMO cut their populations' non-dominated members with one dict: the same rows and keep,
    # in any order, give the first result (a new array: the caller may change it); anything else is cut anew
    rng = np.random.default_rng(4)
    F = rng.normal(size=(40, 2))
    cuts: spea2.Cuts = {}
    first = spea2.truncate(F, 10, cuts)
    assert len(cuts) == 1 and first.tolist() == truncate_by_definition(F, 10).tolist()
    first[:] = False
    assert spea2.truncate(F.copy(), 10, cuts).tolist() == truncate_by_definition(F, 10).tolist()
    assert spea2.truncate(F, 12, cuts).tolist() == truncate_by_definition(F, 12).tolist()
    assert len(cuts) == 2
    perm = rng.permutation(40)
    assert spea2.truncate(F[perm], 10, cuts).tolist() == truncate_by_definition(F[perm], 10).tolist()
    assert len(cuts) == 2  # reused: no removal was decided by index
    G = F.copy()
    G[0, 0] += 1e-9
    assert spea2.truncate(G, 10, cuts).tolist() == truncate_by_definition(G, 10).tolist()
    assert len(cuts) == 3


@settings(max_examples=120, deadline=None)
@given(st.integers(2, 30), st.integers(0, 2**32 - 1))
def test_spea2_cuts_of_the_same_points_in_another_order_equal_the_definition(size, seed):
    # A reused cut must be what cutting the permuted rows gives. Distinct first objectives keep the key the same
    # in any order, and small integers in the others make many removals be decided by index (equal rows), whose
    # cuts must not be reused; copies keep their last one in either order; +inf, NaN and -0.0 rows ride along.
    rng = np.random.default_rng(seed)
    m = 2 + seed % 2
    first = rng.permutation(2 * size)[:size].astype(float)
    F = np.column_stack([first] + [rng.integers(0, 1 + seed % 4, size).astype(float) for _ in range(m - 1)])
    if seed % 3 == 0:  # copies
        F[size // 2 :] = F[: size - size // 2]
    if seed % 5 == 0:  # a penalised member, an undefined one, a signed zero
        F[rng.integers(0, size), 1] = np.inf
        F[rng.integers(0, size), m - 1] = np.nan
        F[rng.integers(0, size), 1] = -0.0
    keep = int(rng.integers(1, size + 1))
    cuts: spea2.Cuts = {}
    assert spea2.truncate(F, keep, cuts).tolist() == truncate_by_definition(F, keep).tolist()
    for _ in range(3):
        G = F[rng.permutation(size)]
        assert spea2.truncate(G, keep, cuts).tolist() == truncate_by_definition(G, keep).tolist()


def test_tournament_lower_key_wins_and_ties_go_to_the_first_drawn():
    keys = (np.array([0, 0, 1, 1]), np.array([5.0, 3.0, 0.0, 0.0]))
    w = tournament(keys, 400, np.random.default_rng(7))
    rng = np.random.default_rng(7)
    a, b = rng.integers(0, 4, 400), rng.integers(0, 4, 400)
    want = [
        (x if (keys[0][x], keys[1][x]) <= (keys[0][y], keys[1][y]) else y) for x, y in zip(a, b, strict=True)
    ]
    assert w.tolist() == want


def test_sbx_without_crossover_returns_the_parents_and_keeps_the_mean_otherwise():
    rng = np.random.default_rng(1)
    P1, P2 = rng.uniform(0, 10, (50, 6)), rng.uniform(0, 10, (50, 6))
    lo, hi = np.full(6, -1e9), np.full(6, 1e9)
    c1, c2 = sbx(P1, P2, lo, hi, np.random.default_rng(2), prob=0.0)
    assert np.array_equal(c1, P1) and np.array_equal(c2, P2)
    c1, c2 = sbx(P1, P2, lo, hi, np.random.default_rng(2))
    np.testing.assert_allclose(c1 + c2, P1 + P2, rtol=1e-12)
    assert not np.array_equal(c1, P1)


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, (8, 5), elements=st.floats(-3, 3)), st.integers(0, 2**32 - 1))
def test_variation_stays_in_bounds_and_is_reproducible(X, seed):
    xl, xu = np.full(5, -3.0), np.full(5, 3.0)
    for op in (
        lambda r: ga(X[:4], X[4:], xl, xu, r),
        lambda r: polynomial_mutation(X, xl, xu, r, prob_var=1.0),
        lambda r: de_rand_1(X[:3], X[3:6], X[5:8], xl, xu, r),
    ):
        a, b = op(np.random.default_rng(seed)), op(np.random.default_rng(seed))
        assert np.array_equal(a, b)
        assert np.all(a >= xl) and np.all(a <= xu)


def test_ga_half_gives_one_child_per_pair():
    X = np.random.default_rng(0).random((6, 3))
    assert ga(X[:3], X[3:], np.zeros(3), np.ones(3), np.random.default_rng(0), half=True).shape == (3, 3)
    assert ga(X[:3], X[3:], np.zeros(3), np.ones(3), np.random.default_rng(0)).shape == (6, 3)


@pytest.mark.parametrize(("n", "m", "count"), [(50, 2, 50), (100, 2, 100), (200, 2, 200), (100, 3, 91),
                                               (200, 3, 190)])
def test_das_dennis_counts(n, m, count):
    W = das_dennis(n, m)
    assert W.shape == (count, m)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-5)
    assert W.min() >= 1e-6


def test_neighbourhoods_and_scalarisations():
    W = das_dennis(5, 2)
    B = neighbours(W, 2)
    assert B[:, 0].tolist() == list(range(5))
    assert tchebycheff(np.array([1.0, 2.0]), np.array([0.5, 0.5]), np.zeros(2)) == 1.0
    # PBI on the weight direction itself: d2 = 0, d1 = the distance along it.
    np.testing.assert_allclose(pbi(np.array([1.0, 1.0]), np.array([0.5, 0.5]), np.zeros(2)), math.sqrt(2))
