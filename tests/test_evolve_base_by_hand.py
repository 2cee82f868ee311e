"""The array algorithms' evaluation (violation, counting) and output front (spec §1.1, §1.8), by hand."""

from __future__ import annotations

import math

import numpy as np
from pymoo.core.problem import Problem

from core.optimize.evolve.base import Arrays
from core.optimize.evolve.imtcmo import IMTCMO


class Fixed(Problem):
    """Two variables; F = X; G and H read from the first variable's row index in the tables below."""

    G = np.array([[1.0, -2.0], [np.nan, 0.0], [-1.0, -1.0]])
    H = np.array([[-0.5], [0.0], [0.25]])

    def __init__(self) -> None:
        super().__init__(n_var=2, n_obj=2, n_ieq_constr=2, n_eq_constr=1, xl=0.0, xu=10.0)

    def _evaluate(self, X, out, *args, **kwargs):
        i = X[:, 0].astype(int)
        out["F"], out["G"], out["H"] = X.copy(), self.G[i], self.H[i]


def test_violation_sums_positive_g_and_absolute_h_and_an_undefined_one_is_infinite():
    alg = IMTCMO(pop_size=12)
    alg.setup(Fixed(), termination=("n_eval", 100), seed=1)
    before = alg.evaluator.n_eval
    a = alg.evaluate(np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]]))
    # row 0: max(1, 0) + max(-2, 0) + |-0.5| = 1.5; row 1: NaN -> +inf; row 2: 0 + 0 + 0.25
    assert a.cv.tolist() == [1.5, math.inf, 0.25]
    assert alg.evaluator.n_eval == before + 3
    assert len(alg.evaluate(np.zeros((0, 2)))) == 0 and alg.evaluator.n_eval == before + 3


def test_the_output_front_is_the_feasible_non_dominated_else_the_least_violating():
    alg = IMTCMO(pop_size=12)
    F = np.array([[1.0, 2.0], [2.0, 1.0], [0.0, 0.0], [3.0, 3.0]])
    alg.arrays = Arrays(np.zeros((4, 1)), F, np.zeros((4, 1)), np.array([0.0, 0.0, 1.0, 0.0]))
    assert alg.optimum_index().tolist() == [0, 1]  # (0,0) violates; (3,3) is dominated
    alg.arrays = Arrays(np.zeros((4, 1)), F, np.zeros((4, 1)), np.array([2.0, 0.5, 1.0, 0.5]))
    assert alg.optimum_index().tolist() == [1, 3]  # nobody feasible: the least violation, dominated or not
