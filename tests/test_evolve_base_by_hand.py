"""The array algorithms' evaluation (violation, counting) and output front (spec §1.1, §1.8), by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymoo.core.individual import calc_cv
from pymoo.core.problem import Problem
from pymoo.optimize import minimize

from core.optimize import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.imtcmo import IMTCMO


class Fixed(Problem):
    """Two variables; F = X; G and H read from the first variable's row index in the tables below."""

    G = np.array([[1.0, -2.0], [np.nan, 0.0], [-1.0, -1.0], [-1.0, -1.0]])
    H = np.array([[-0.5], [0.0], [0.25], [-5e-5]])

    def __init__(self) -> None:
        super().__init__(n_var=2, n_obj=2, n_ieq_constr=2, n_eq_constr=1, xl=0.0, xu=10.0)

    def _evaluate(self, X, out, *args, **kwargs):
        i = X[:, 0].astype(int)
        out["F"], out["G"], out["H"] = X.copy(), self.G[i], self.H[i]


def test_violation_sums_positive_g_and_absolute_h_past_pymoos_tolerance_and_an_undefined_one_is_infinite():
    alg = IMTCMO(pop_size=12)
    alg.setup(Fixed(), termination=("n_eval", 100), seed=1)
    before = alg.evaluator.n_eval
    a = alg.evaluate(np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0], [3.0, 1.0]]))
    # row 0: max(1, 0) + max(-2, 0) + (|-0.5| - 1e-4) = 1.4999; row 1: NaN -> +inf; row 2: 0 + 0 + 0.2499;
    # row 3: |h| = 5e-5 is within pymoo's 1e-4 of an equality: feasible
    assert a.cv.tolist() == [1.0 + (0.5 - 1e-4), math.inf, 0.25 - 1e-4, 0.0]
    assert alg.evaluator.n_eval == before + 4
    assert len(alg.evaluate(np.zeros((0, 2)))) == 0 and alg.evaluator.n_eval == before + 4
    assert alg.evaluate(np.zeros((0, 2))).G.shape == (0, 3)
    # pymoo's own count agrees where it is defined; its population gets G and |h| back
    cv = calc_cv(Fixed.G[[0, 2, 3]], Fixed.H[[0, 2, 3]])
    np.testing.assert_allclose(a.cv[[0, 2, 3]], cv, rtol=0, atol=1e-15)
    pop = a.take(np.array([0, 2, 3])).population(n_ieq=2)
    np.testing.assert_array_equal(pop.get("G"), Fixed.G[[0, 2, 3]])
    np.testing.assert_allclose(pop.get("H"), np.abs(Fixed.H[[0, 2, 3]]), rtol=0, atol=1e-15)
    assert pop.get("feas").ravel().tolist() == [False, False, True]


def test_the_output_front_is_the_feasible_non_dominated_else_the_least_violating():
    alg = IMTCMO(pop_size=12)
    F = np.array([[1.0, 2.0], [2.0, 1.0], [0.0, 0.0], [3.0, 3.0]])
    alg.arrays = Arrays(np.zeros((4, 1)), F, np.zeros((4, 1)), np.array([0.0, 0.0, 1.0, 0.0]))
    assert alg.optimum_index().tolist() == [0, 1]  # (0,0) violates; (3,3) is dominated
    alg.arrays = Arrays(np.zeros((4, 1)), F, np.zeros((4, 1)), np.array([2.0, 0.5, 1.0, 0.5]))
    assert alg.optimum_index().tolist() == [1, 3]  # nobody feasible: the least violation, dominated or not


class Line(Problem):
    """x3 = 0.5 exactly (an equality) and x1 >= 0.2: the front is x1 in [0.2, 1], x2 = 0, x3 = 0.5."""

    def __init__(self) -> None:
        super().__init__(n_var=3, n_obj=2, n_ieq_constr=1, n_eq_constr=1, xl=0.0, xu=1.0)

    def _evaluate(self, X, out, *args, **kwargs):
        out["F"] = np.c_[X[:, 0], 1 - X[:, 0] + X[:, 1] ** 2]
        out["G"], out["H"] = 0.2 - X[:, :1], X[:, 2:3] - 0.5


@pytest.mark.parametrize("name", ["nsga2", "cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "mccmo", "moead_cmt"])
def test_an_equality_constraint_is_met_within_pymoos_tolerance_and_the_result_has_a_front(name):
    res = minimize(Line(), make_algorithm(AlgorithmSpec(name, 20, {}), 2, 1), ("n_eval", 5000), seed=1)
    assert res.X is not None and len(res.X) > 0  # with |h| counted exactly nobody was ever feasible
    assert np.abs(res.opt.get("H")).max() <= 1e-4 and res.opt.get("G").max() <= 0.0
    assert res.pop.get("G").shape == (20, 1) and res.pop.get("H").shape == (20, 1)


def test_with_one_objective_the_optimum_is_the_first_best_feasible_member_as_in_pymoo():
    alg = IMTCMO(pop_size=12)
    F = np.array([[2.0], [1.0], [1.0], [0.5], [3.0]])
    alg.arrays = Arrays(np.arange(5.0)[:, None], F, np.zeros((5, 1)), np.array([0.0, 0.0, 0.0, 1.0, 0.0]))
    assert alg.optimum_index().tolist() == [1]  # (0.5) violates; copies of the best are one optimum


class Parabola(Problem):
    def __init__(self) -> None:
        super().__init__(n_var=1, n_obj=1, n_ieq_constr=1, xl=-5.0, xu=5.0)

    def _evaluate(self, X, out, *args, **kwargs):
        out["F"], out["G"] = (X - 1.0) ** 2, 0.5 - X


@pytest.mark.parametrize("name", ["cmoemt", "cmoes", "drlos_emcmo"])
def test_a_single_objective_run_returns_one_optimum_not_its_copies(name):
    res = minimize(Parabola(), make_algorithm(AlgorithmSpec(name, 12, {}), 1, 1), ("n_eval", 400), seed=1)
    assert np.shape(res.X) == (1,) and len(res.opt) == 1  # pymoo's shape for one optimum
    assert res.F[0] == res.pop.get("F")[res.pop.get("feas").ravel()].min()


def test_a_saved_history_shares_the_trace_rows_and_keeps_each_snapshots_length():
    # pymoo deep-copies the algorithm every generation for save_history: copying every trace row made a long run
    # quadratic (600 generations of CMOES at pop 20: 2.9 s against 1.3 s without a history, session 34)
    import copy

    from pymoo.optimize import minimize

    from core.optimize.algorithms import AlgorithmSpec, make_algorithm
    from core.optimize.moea import problem_by_name

    res = minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1), ("n_gen", 12), seed=1,
                   save_history=True)
    final = res.algorithm.trace
    assert [len(h.trace) for h in res.history] == list(range(1, 13))
    assert all(h.trace[k] is final[k] for h in res.history for k in range(len(h.trace)))  # rows shared
    twin = copy.deepcopy(res.algorithm)
    twin.trace.append({"gen": 99.0})  # a copy's trace is its own list
    assert len(final) == 12 and len(twin.trace) == 13
    pair = copy.deepcopy([final, final])  # one trace reached twice stays one (memo)
    assert pair[0] is pair[1] and pair[0] is not final
