"""Variation operators, duplicates, ε-CDP and scalarisations of the array core, against hand-computed cases
and against pymoo's own bounded SBX (the NSGA-II's operator)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymoo.operators.crossover.sbx import cross_sbx

from core.optimize.evolve import spea2
from core.optimize.evolve.duplicates import fresh_rows
from core.optimize.evolve.moead import _pbi, _tchebycheff
from core.optimize.evolve.sorting import cdp_better, cdp_ranks, epsilon_cv
from core.optimize.evolve.variation import de_current_to_pbest_1, de_rand_1, polynomial_mutation, sbx, sbx_bounded
from core.optimize.evolve.weights import das_dennis, pbi, tchebycheff, tchebycheff_div


class Draws:
    """A stand-in Generator whose ``random`` hands out prepared arrays, in order."""

    def __init__(self, *arrays: np.ndarray) -> None:
        self.arrays = list(arrays)

    def random(self, shape=None):
        a = np.asarray(self.arrays.pop(0), dtype=float)
        assert a.shape == (() if shape is None else np.empty(shape).shape)
        return a


def test_polynomial_mutation_of_one_variable_by_hand():
    # x = 0.5 in [0, 1], eta = 20; u = 0.25 (lower branch): dq = (2u + (1-2u)(1-0.5)^21)^(1/21) - 1.
    X = np.array([[0.5, 0.3]])
    rng = Draws([[0.0, 0.9]], [[0.25, 0.5]])  # site draws (< 1/2 mutates the first variable only), then u
    Y = polynomial_mutation(X, np.zeros(2), np.ones(2), rng, prob_var=0.5, eta=20.0)  # type: ignore[arg-type]
    dq = (0.5 + 0.5 * 0.5**21) ** (1 / 21) - 1
    np.testing.assert_allclose(Y, [[0.5 + dq, 0.3]], rtol=1e-14)
    # upper branch, u = 0.75, x = 0.9 in [0, 2]: dq = 1 - (2(1-u) + 2(u-0.5)(1-(2-0.9)/2)^21)^(1/21).
    rng = Draws([[0.0]], [[0.75]])
    Y = polynomial_mutation(np.array([[0.9]]), np.zeros(1), np.full(1, 2.0), rng, prob_var=0.5)  # type: ignore[arg-type]
    dq = 1 - (0.5 + 0.5 * (1 - 1.1 / 2) ** 21) ** (1 / 21)
    np.testing.assert_allclose(Y, [[0.9 + 2 * dq]], rtol=1e-14)


def test_polynomial_mutation_leaves_unselected_rows_alone():
    X = np.random.default_rng(0).random((6, 4))
    rows = np.array([True, False, True, False, False, True])
    Y = polynomial_mutation(X, np.zeros(4), np.ones(4), np.random.default_rng(1), prob_var=1.0, rows=rows)
    assert np.array_equal(Y[~rows], X[~rows]) and (Y[rows] != X[rows]).all()


def test_de_rand_1_and_current_to_pbest_1_by_hand():
    lo, hi = np.zeros(2), np.full(2, 10.0)
    x1, x2, x3 = np.array([[1.0, 2.0]]), np.array([[4.0, 4.0]]), np.array([[2.0, 0.0]])
    rng = np.random.default_rng(3)
    # CR = 1 perturbs every variable; no mutation (prob_var = 0): x1 + 0.5 (x2 - x3) = (2, 4).
    assert de_rand_1(x1, x2, x3, lo, hi, rng, F=0.5, CR=1.0, prob_var=0.0).tolist() == [[2.0, 4.0]]
    # Clipped to the bounds: x1 + 5 (x2 - x3) = (11, 22) -> (10, 10).
    assert de_rand_1(x1, x2, x3, lo, hi, rng, F=5.0, CR=1.0, prob_var=0.0).tolist() == [[10.0, 10.0]]
    # CR = 0: no variable changes (no forced j_rand).
    assert de_rand_1(x1, x2, x3, lo, hi, rng, F=0.5, CR=0.0, prob_var=0.0).tolist() == [[1.0, 2.0]]
    # current-to-pbest: x + F (pbest - x + x2 - x3) = (1,2) + 0.5 ((5,5) - (1,2) + (2,4)) = (4, 5.5).
    pb = np.array([[5.0, 5.0]])
    assert de_current_to_pbest_1(x1, pb, x2, x3, lo, hi, rng, F=0.5, CR=1.0, prob_var=0.0).tolist() == [[4.0, 5.5]]
    # per-child F and CR as (k, 1) columns
    X = np.vstack([x1, x1])
    got = de_rand_1(X, np.vstack([x2, x2]), np.vstack([x3, x3]), lo, hi, rng, F=np.array([[0.5], [1.0]]),
                    CR=np.array([[1.0], [0.0]]), prob_var=0.0)
    assert got.tolist() == [[2.0, 4.0], [1.0, 2.0]]


def test_bounded_sbx_keeps_parents_where_it_must_and_stays_in_bounds():
    rng = np.random.default_rng(5)
    P1, P2 = rng.random((300, 5)), rng.random((300, 5))
    P2[:, 2] = P1[:, 2]  # identical variable: never crossed
    xl, xu = np.zeros(5), np.ones(5)
    xl[4] = xu[4] = 0.5  # a fixed variable
    P1[:, 4] = P2[:, 4] = 0.5
    c1, c2 = sbx_bounded(P1, P2, xl, xu, np.random.default_rng(6), prob=0.0)
    assert np.array_equal(c1, P1) and np.array_equal(c2, P2)
    c1, c2 = sbx_bounded(P1, P2, xl, xu, np.random.default_rng(6), prob=1.0)
    assert np.array_equal(c1[:, 2], P1[:, 2]) and np.array_equal(c1[:, 4], P1[:, 4])
    assert ((c1 >= xl) & (c1 <= xu) & (c2 >= xl) & (c2 <= xu)).all()
    assert (c1[:, :2] != P1[:, :2]).mean() > 0.3


def test_platemos_sbx_puts_the_first_child_on_either_parents_side_at_random():
    # GAhalf keeps only the first child: without the random sign it would always lie on the first parent's side.
    n = 20_000
    P1, P2 = np.full((n, 1), 0.2), np.full((n, 1), 0.8)
    c1, c2 = sbx(P1, P2, np.zeros(1), np.ones(1), np.random.default_rng(3), prob=1.0, prob_var=1.0)
    assert abs((c1[:, 0] > 0.5).mean() - 0.5) < 0.02  # 14 sigma from 0 or 1
    np.testing.assert_allclose(c1 + c2, P1 + P2)  # the pair stays symmetric about the parents' middle


def test_polynomial_mutation_changes_one_variable_in_d_by_default():
    n, d = 40_000, 10
    X = np.full((n, d), 0.5)
    Y = polynomial_mutation(X, np.zeros(d), np.ones(d), np.random.default_rng(4))
    assert abs((Y != X).mean() - 1 / d) < 0.005  # sigma 0.0005; 1 / (d + 1) would be 0.0091 off


def test_bounded_sbx_recombines_parents_a_hair_apart():
    n = 2000
    P1, P2 = np.full((n, 1), 0.5), np.full((n, 1), 0.5 + 1e-9)
    c1, _ = sbx_bounded(P1, P2, np.zeros(1), np.ones(1), np.random.default_rng(6), prob=1.0)
    assert (c1 != P1).mean() > 0.3 and np.abs(c1 - 0.5).max() < 1e-6


def test_bounded_sbx_draws_from_pymoos_distribution():
    n = 40_000
    P1 = np.tile([0.2, 0.5, 0.97], (n, 1))
    P2 = np.tile([0.6, 0.1, 0.99], (n, 1))
    lo, hi = np.zeros(3), np.ones(3)
    a1, a2 = sbx_bounded(P1, P2, lo, hi, np.random.default_rng(1), prob=1.0, eta=15.0)
    Q = cross_sbx(np.stack([P1, P2]), lo, hi, np.full((n, 1), 15.0), np.full((n, 1), 0.5), np.full((n, 1), 0.5),
                  random_state=np.random.default_rng(2))
    qs = [0.05, 0.2, 0.35, 0.65, 0.8, 0.95]
    for ours, theirs in ((a1, Q[0]), (a2, Q[1])):
        np.testing.assert_allclose(np.quantile(ours, qs, axis=0), np.quantile(theirs, qs, axis=0), atol=4e-3)


def test_fresh_rows_drops_exact_duplicates_within_and_against_the_population():
    E = np.array([[0.0, 1.0], [2.0, 3.0]])
    C = np.array([[2.0, 3.0], [5.0, 5.0], [5.0, 5.0], [-0.0, 1.0], [0.0, 1.0 + 1e-15], [np.nan, 1.0],
                  [np.nan, 1.0]])
    # row 0 equals E[1]; row 2 equals row 1; -0.0 == 0.0 makes row 3 equal E[0]; NaN equals nothing.
    assert fresh_rows(C, E).tolist() == [False, True, False, False, True, True, True]
    assert fresh_rows(C[:0], E).tolist() == []


def test_epsilon_constraint_domination():
    F = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    cv = np.array([0.3, 0.0, 0.05])
    assert epsilon_cv(cv, 0.1).tolist() == [0.3, 0.0, 0.0]
    # under ε = 0.1, (2,2) counts as feasible and is dominated by (1,1); (0,0) stays infeasible
    assert cdp_ranks(F, epsilon_cv(cv, 0.1)).tolist() == [2, 0, 1]
    assert cdp_ranks(F, epsilon_cv(cv, 0.5)).tolist() == [0, 1, 2]
    D = spea2.dominance(F, epsilon_cv(cv, 0.5))
    assert D[0, 1] and D[0, 2] and D[1, 2]


def test_spea2_equal_violation_falls_back_to_pareto_and_truncation_ties_drop_the_lowest_index():
    F = np.array([[0.0, 1.0], [1.0, 0.0], [2.0, 2.0]])
    D = spea2.dominance(F, np.full(3, 1.0))
    assert D.tolist() == [[False, False, True], [False, False, True], [False, False, False]]
    # on a line 0,1,2,3: members 1 and 2 have the same sorted distances (1, 1, 2); the lower index goes
    assert spea2.truncate(np.array([[0.0], [1.0], [2.0], [3.0]]), 3).tolist() == [True, False, True, True]
    # k = floor(sqrt(9)) = 3: sigma is the 3rd nearest distance
    F9 = np.column_stack([np.arange(9.0), 8.0 - np.arange(9.0)])  # all non-dominated, spacing sqrt 2
    fit = spea2.fitness(F9)
    np.testing.assert_allclose(fit[0], 1 / (3 * math.sqrt(2) + 2))
    np.testing.assert_allclose(fit[4], 1 / (2 * math.sqrt(2) + 2))


def test_epsilon_and_cdp_at_their_edges():
    assert epsilon_cv(np.array([0.1, 0.1 + 1e-12]), 0.1).tolist() == [0.0, 0.1 + 1e-12]  # within eps: feasible
    F, cv = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, 0.0]]), np.array([0.5, 0.5, 0.5])
    # equal violation: Pareto dominance decides; neither of two incomparable members wins
    assert cdp_better(F, cv, np.array([0, 1, 2, 2]), np.array([1, 0, 0, 2])).tolist() == [False, False, True, False]


def test_pbi_of_a_point_off_the_weight_ray():
    # w = (1, 1) / sqrt 2; f - z = (3, 1): d1 = 4 / sqrt 2 = 2 sqrt 2, d2 = |(3, 1) - (2, 2)| = sqrt 2
    assert pbi(np.array([3.0, 1.0]), np.array([0.5, 0.5]), np.zeros(2)) == pytest.approx(7 * math.sqrt(2))
    assert pbi(np.array([3.0, 1.0]), np.array([0.5, 0.5]), np.zeros(2), theta=0.0) == pytest.approx(2 * math.sqrt(2))


@pytest.mark.parametrize("seed", range(5))
def test_the_compiled_scalarisations_are_the_reference_ones(seed):
    rng = np.random.default_rng(seed)
    F, W, z = rng.uniform(0, 3, (40, 3)), das_dennis(40, 3), rng.uniform(-1, 0, 3)
    for i in range(len(F)):
        for w in range(0, len(W), 7):
            assert _tchebycheff(F, i, W, w, z) == pytest.approx(float(tchebycheff(F[i], W[w], z)), rel=1e-12)
            nw = float(np.linalg.norm(W[w]))
            assert _pbi(F, i, W, w, nw, z, 5.0, np.nan) == pytest.approx(float(pbi(F[i], W[w], z)), rel=1e-9)


def test_tchebycheff_forms():
    F, W, z = np.array([3.0, 1.0]), np.array([0.25, 0.75]), np.array([1.0, 0.0])
    assert tchebycheff(F, W, z) == max(0.25 * 2, 0.75 * 1)
    assert tchebycheff_div(F, W, z) == max(2 / 0.25, 1 / 0.75)
