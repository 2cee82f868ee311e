"""SPEA2's fitness under constraint domination and its truncation (spec §1.2-1.3) on cases small enough to do by
hand (the other SPEA2 tests compare with the definition written out over the code's own dominance matrix)."""

from __future__ import annotations

import math

import numpy as np

from core.optimize.evolve import spea2


def test_fitness_under_cdp_by_hand():
    # (0,0) violates; (1,1) and (2,0) are feasible and incomparable, so each dominates only (0,0): S = 1, 1, and
    # R(0,0) = 2. k = floor(sqrt 3) = 1: sigma is the nearest distance, sqrt 2 for all three.
    F, cv = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]]), np.array([1.0, 0.0, 0.0])
    d = 1 / (math.sqrt(2) + 2)
    np.testing.assert_allclose(spea2.fitness(F, cv), [2 + d, d, d], rtol=1e-14)
    # ignoring constraints (0,0) dominates both: S(0,0) = 2, R = 2 for each of them
    np.testing.assert_allclose(spea2.fitness(F), [d, 2 + d, 2 + d], rtol=1e-14)
    # cv 1, 3, 0: the smaller violation dominates whatever the objectives; S = 1, 0, 2: R(0,0) = S(2,0) = 2,
    # R(1,1) = S(0,0) + S(2,0) = 3
    np.testing.assert_allclose(spea2.fitness(F, np.array([1.0, 3.0, 0.0])), [2 + d, 3 + d, d], rtol=1e-14)


def test_truncation_breaks_a_tie_on_the_nearest_distance_by_the_next():
    # 0, 1, 2, 4 on a line; sorted distances: 0: (1, 2, 4), 1: (1, 1, 3), 2: (1, 2, 2), 4: (2, 3, 4).
    # 1's are the smallest; then among 0, 2, 4: (2, 4), (2, 2), (2, 4): 2 goes.
    F = np.array([[0.0], [1.0], [2.0], [4.0]])
    assert spea2.truncate(F, 3).tolist() == [True, False, True, True]
    assert spea2.truncate(F, 2).tolist() == [True, False, False, True]


def test_select_returns_the_survivors_by_ascending_fitness():
    # All four non-dominated, one to drop. Sorted distances: (3,0): (d03, d01, d02) = (1.414, 3.523, 4.243);
    # (1,2.9): (1.005, 2.147, 3.523); (0,3): (1.005, 2.828, 4.243); (2,1): (1.414, 2.147, 2.828). (1,2.9) and
    # (0,3) tie on the nearest; (1,2.9)'s next is smaller: it goes.
    F = np.array([[3.0, 0.0], [1.0, 2.9], [0.0, 3.0], [2.0, 1.0]])
    order, fit, mask = spea2.select(F, 3)
    assert mask.tolist() == [True, False, True, True]
    # fitness 1 / (sigma + 2), sigma the 2nd nearest (k = floor(sqrt 4)) in the pool of four: 3.523, 2.828, 2.147;
    # the largest sigma first
    sigma = [math.dist(F[0], F[1]), math.dist(F[2], F[3]), math.dist(F[3], F[1])]
    assert order.tolist() == [0, 2, 3]
    np.testing.assert_allclose(fit, [1 / (s + 2) for s in sigma], rtol=1e-14)
