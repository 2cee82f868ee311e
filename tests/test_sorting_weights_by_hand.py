"""Crowding distance at its edges and the Das-Dennis lattice and neighbourhoods (spec §1.4, §1.6), by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.optimize.evolve.sorting import crowding
from core.optimize.evolve.weights import das_dennis, neighbours, simplex_lattice


def test_crowding_gives_both_ends_of_every_objective_infinity():
    # a line (not a front): member 2 is the largest on both objectives and the smallest on none
    cd = crowding(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]), np.zeros(3, dtype=np.int64))
    assert cd.tolist() == [math.inf, 2.0, math.inf]  # middle: (2 - 0) / 2 on each of the two objectives


def test_crowding_skips_an_objective_with_no_range():
    # objective 2 is 1 everywhere: it adds nothing (0 / 0 would be NaN); objective 1: (3 - 0) / 3 = 1
    cd = crowding(np.array([[0.0, 1.0], [1.0, 1.0], [3.0, 1.0]]), np.zeros(3, dtype=np.int64))
    assert cd.tolist() == [math.inf, 1.0, math.inf]


def test_crowding_is_per_front():
    F = np.array([[0.0, 3.0], [5.0, 5.0], [1.0, 1.0], [6.0, 4.0], [3.0, 0.0], [7.0, 3.0]])
    rank = np.array([0, 1, 0, 1, 0, 1])
    cd = crowding(F, rank)
    # front 0: (0,3), (1,1), (3,0): the middle one (3 - 0)/3 + (3 - 0)/3 = 2; front 1: (5,5), (6,4), (7,3): 1 + 1
    assert cd.tolist() == [math.inf, math.inf, 2.0, 2.0, math.inf, math.inf]


def test_the_lattice_of_three_objectives_and_two_parts_by_hand():
    # n = 6..9: the largest H with C(H + 2, 2) <= n is 2; the six points of the simplex with halves
    want = [[1, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 1, 0], [0, 0.5, 0.5], [0, 0, 1]]
    for n in (6, 9):
        assert sorted(simplex_lattice(n, 3).tolist()) == sorted(want)
    assert len(simplex_lattice(10, 3)) == 10  # C(5, 2): H = 3


@pytest.mark.parametrize("m", [2, 3, 4])
@pytest.mark.parametrize("n", [5, 15, 56, 100])
def test_das_dennis_count_is_the_largest_binomial_within_n(n, m):
    H = max(h for h in range(1, n + 1) if math.comb(h + m - 1, m - 1) <= n)
    W = das_dennis(n, m)
    assert len(W) == math.comb(H + m - 1, m - 1)
    # every vector is a lattice point: components multiples of 1/H (zeros clipped to 1e-6), summing to 1
    parts = np.where(W <= 1e-6, 0.0, W) * H
    np.testing.assert_allclose(parts, np.round(parts), atol=1e-9)
    np.testing.assert_allclose(np.round(parts).sum(axis=1), H)
    assert len({tuple(r) for r in np.round(parts).tolist()}) == len(W)


def test_neighbourhoods_are_euclidean_nearest_with_ties_to_the_lower_index():
    W = np.array([[1, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 1, 0], [0, 0.5, 0.5], [0, 0, 1]])
    # from (1,0,0): (.5,.5,0) and (.5,0,.5) at sqrt .5, (0,.5,.5) at sqrt 1.5, (0,1,0) and (0,0,1) at sqrt 2
    assert neighbours(W, 4)[0].tolist() == [0, 1, 2, 4]
    assert neighbours(W, 5)[0].tolist() == [0, 1, 2, 4, 3]
    # from (0,.5,.5): (0,1,0) and (0,0,1) at sqrt .5, (.5,.5,0) and (.5,0,.5) at sqrt .5 too: index order
    assert neighbours(W, 5)[4].tolist() == [4, 1, 2, 3, 5]
