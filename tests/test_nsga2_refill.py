"""NSGA-II's offspring are unlike each other and unlike the population, also when duplicates force refills.

A repair that snaps every variable to a coarse grid ({0, 0.5, 1}^3, 27 points) makes most children copies of a
parent or of each other, so ``offspring`` must refill, and every refill must be de-duplicated against the
population *and the children already kept* (checked by hand: rows unique, none in the population).
"""

from __future__ import annotations

import numpy as np
import pytest
from pymoo.core.problem import Problem

from core.optimize.evolve.base import Arrays
from core.optimize.evolve.nsga2 import NSGA2


class Cube(Problem):
    def __init__(self) -> None:
        super().__init__(n_var=3, n_obj=2, xl=0.0, xu=1.0)

    def _evaluate(self, X, out, *args, **kwargs):
        out["F"] = X[:, :2].copy()


class Snap:
    """Rounds every variable to the nearest of 0, 0.5, 1 (and counts its calls)."""

    def __init__(self) -> None:
        self.calls = 0

    def _do(self, problem, X):
        self.calls += 1
        return np.round(np.asarray(X) * 2.0) / 2.0


POPULATION = np.array([[0.0, 0.0, 0.5], [0.5, 0.5, 0.5], [1.0, 0.5, 0.0], [0.5, 1.0, 1.0]])


def offspring(seed: int, repair, n: int = 4) -> tuple[np.ndarray, NSGA2]:
    alg = NSGA2(pop_size=n, repair=repair)
    alg.setup(Cube(), termination=("n_gen", 10), seed=seed)
    X = POPULATION[:n]
    alg.arrays = Arrays(X, X[:, :2].copy(), np.zeros((n, 0)), np.zeros(n))
    alg.rank, alg.crowd = np.zeros(n, dtype=np.int64), np.zeros(n)
    return alg.offspring(), alg


@pytest.mark.parametrize("seed", range(12))
def test_refilled_offspring_are_distinct_and_new(seed):
    snap = Snap()
    C, _ = offspring(seed, snap)
    assert C.shape == (4, 3)
    assert len({tuple(r) for r in C}) == 4  # no two children alike, across refills too
    assert not {tuple(r) for r in C} & {tuple(r) for r in POPULATION}  # none a member of the population
    assert set(np.unique(C)) <= {0.0, 0.5, 1.0}  # every child went through the repair


def test_the_grid_forces_refills():
    # the cases above are refills: the first batch of children rarely gives four new grid points
    calls = []
    for seed in range(12):
        snap = Snap()
        offspring(seed, snap)
        calls.append(snap.calls)
    assert sum(c > 1 for c in calls) >= 6
