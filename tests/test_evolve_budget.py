"""What the array algorithms take from pymoo's run settings: the budget their schedules span under every kind of
termination, and a user's own Evaluator (spec §1.8: evaluations go through it)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from pymoo.core.evaluator import Evaluator
from pymoo.core.problem import Problem
from pymoo.core.termination import TerminateIfAll, TerminateIfAny
from pymoo.optimize import minimize
from pymoo.termination.default import DefaultMultiObjectiveTermination
from pymoo.termination.max_eval import MaximumFunctionCallTermination
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.termination.max_time import TimeBasedTermination
from pymoo.termination.robust import RobustTermination

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.moea import problem_by_name

PAPER = ["nsga2", "cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "mccmo", "moead_cmt"]
SCHEDULED = ["cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "moead_cmt"]  # MCCMO has no schedule


class Counting(Evaluator):
    """A user's evaluator: counts its calls and the members it saw (a lab's wrapper around a simulator)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls, self.seen = 0, 0

    def _eval(self, problem, pop, evaluate_values_of, **kwargs):
        self.calls += 1
        self.seen += len(pop)
        super()._eval(problem, pop, evaluate_values_of, **kwargs)


@pytest.mark.parametrize("name", PAPER)
def test_a_users_evaluator_evaluates_every_member_and_changes_nothing_else(name):
    problem = problem_by_name("mw3")
    plain = minimize(problem, make_algorithm(AlgorithmSpec(name, 20), 2, 1), ("n_eval", 400), seed=1)
    ev = Counting()
    own = minimize(problem, make_algorithm(AlgorithmSpec(name, 20), 2, 1), ("n_eval", 400), seed=1, evaluator=ev)
    # CMOEMT's and MOEA/D-CMT's children made again (ahead = true) are evaluated too, and not counted
    unused = sum(r.get("evaluated_ahead_unused", 0.0) for r in own.algorithm.trace)
    assert ev.calls > 0 and ev.seen == own.algorithm.evaluator.n_eval + unused
    assert own.algorithm.evaluator.n_eval == plain.algorithm.evaluator.n_eval
    assert np.array_equal(own.X, plain.X) and np.array_equal(own.F, plain.F)


def test_an_evaluators_callback_sees_every_evaluation():
    seen = []
    res = minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1), ("n_eval", 300),
                   seed=1, evaluator=Evaluator(callback=lambda pop: seen.append(len(pop))))
    assert sum(seen) == res.algorithm.evaluator.n_eval >= 300


def test_an_evaluator_that_leaves_members_unevaluated_is_named():
    class Lazy(Evaluator):
        def _eval(self, problem, pop, evaluate_values_of, **kwargs):
            pass

    with pytest.raises(ValueError, match="Lazy.eval left members without F"):
        minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("imtcmo", 20), 2, 1), ("n_eval", 300),
                 seed=1, evaluator=Lazy())


def budget_of(termination) -> int:
    # CMOES at N = 20: 2N initially, then 3N each generation
    alg = make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1)
    alg.setup(problem_by_name("mw3"), termination=termination, seed=1)
    alg.next()
    assert alg.max_gen == math.ceil(alg.max_fe / 20)
    return alg.max_fe


def test_the_budget_under_every_kind_of_termination():
    gens = lambda g: 40 + (g - 1) * 60  # noqa: E731
    assert budget_of(MaximumFunctionCallTermination(3000)) == 3000
    assert budget_of(MaximumGenerationTermination(30)) == gens(30)
    assert budget_of(TerminateIfAny(MaximumGenerationTermination(30), MaximumFunctionCallTermination(900))) == 900
    assert budget_of(TerminateIfAll(MaximumGenerationTermination(30), MaximumFunctionCallTermination(900))) == gens(30)
    # a RobustTermination ends period - 1 generations after its inner limit (review of session 34: 29 short)
    assert budget_of(RobustTermination(MaximumFunctionCallTermination(1200), period=5)) == 1200 + 4 * 60
    assert budget_of(RobustTermination(MaximumGenerationTermination(10))) == gens(10 + 29)
    # period=None keeps the whole run in its window, whose first value never lets it end (review of session 35)
    assert budget_of(RobustTermination(MaximumGenerationTermination(10), period=None)) == gens(101)
    # pymoo's default termination ends at its caps at the latest: 1000 generations or 100 000 evaluations
    assert budget_of(DefaultMultiObjectiveTermination(n_max_evals=5000)) == 5000
    assert budget_of(DefaultMultiObjectiveTermination(n_max_gen=50)) == gens(50)
    assert budget_of(DefaultMultiObjectiveTermination()) == min(100_000, gens(1000))
    # pymoo's unlimited defaults (inf) limit nothing (int(inf) raised; review of session 34)
    assert budget_of(TerminateIfAny(MaximumFunctionCallTermination(), MaximumGenerationTermination(30))) == gens(30)
    assert budget_of(DefaultMultiObjectiveTermination(n_max_gen=np.inf, n_max_evals=2000)) == 2000
    assert budget_of(MaximumFunctionCallTermination()) == gens(101)
    # nothing that limits evaluations: 100 generations after the first (a time in it: estimated as it runs)
    assert budget_of(TerminateIfAll(MaximumGenerationTermination(30), TimeBasedTermination(60))) == gens(101)


@pytest.mark.parametrize("name", SCHEDULED)
def test_a_time_budget_is_estimated_from_the_evaluations_per_second_so_far(name):
    alg = make_algorithm(AlgorithmSpec(name, 20), 2, 1)
    alg.setup(problem_by_name("mw3"), termination=TimeBasedTermination(100.0), seed=1)
    alg.next()
    alg.next()
    alg.start_time = time.time() - 25.0  # a quarter of the time used: the budget is 4x the evaluations so far
    n_eval = alg.evaluator.n_eval
    alg.rebudget()
    assert 3.9 * n_eval <= alg.max_fe <= 4 * n_eval
    if name == "cmoes":
        assert alg.max_gen == math.ceil(alg.max_fe / 20)
    if name == "cmoemt":
        assert alg.Tc == pytest.approx(0.9 * math.ceil(alg.max_fe / alg.n))
    alg.start_time = time.time() - 100.0  # the time is up: the budget is what was spent, and a generation more
    alg.rebudget()
    assert n_eval < alg.max_fe <= 4 * n_eval


def rebudgeted(termination, used: float) -> tuple[int, int]:
    """CMOES at N = 20 under ``termination`` after two generations, its time termination(s) ``used`` x 100 s
    along: the budget estimated again, and the evaluations so far."""
    alg = make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1)
    alg.setup(problem_by_name("mw3"), termination=termination, seed=1)
    alg.next()
    alg.next()
    alg.start_time = time.time() - 100.0 * used
    alg.rebudget()
    assert alg.max_gen == math.ceil(alg.max_fe / 20)
    return alg.max_fe, alg.evaluator.n_eval


def test_a_time_with_a_generation_count_ends_where_either_or_both_would():
    # review of session 34: under TerminateIfAny the time was never estimated, under TerminateIfAll only the time
    gens = lambda g: 40 + (g - 1) * 60  # noqa: E731
    t = TimeBasedTermination(100.0)
    fe, n_eval = rebudgeted(TerminateIfAny(MaximumGenerationTermination(1000), t), 0.25)
    assert 3.9 * n_eval <= fe <= 4 * n_eval < gens(1000)  # the time ends first
    fe, n_eval = rebudgeted(TerminateIfAny(MaximumGenerationTermination(3), t), 0.25)
    assert fe == gens(3)  # the generations end first
    fe, n_eval = rebudgeted(TerminateIfAll(MaximumGenerationTermination(1000), t), 0.25)
    assert fe == gens(1000)  # both must end: the later
    fe, n_eval = rebudgeted(TerminateIfAll(MaximumGenerationTermination(3), t), 0.25)
    assert 3.9 * n_eval <= fe <= 4 * n_eval
    fe, n_eval = rebudgeted(RobustTermination(TimeBasedTermination(100.0), period=3), 0.5)
    assert 1.9 * n_eval + 2 * 60 <= fe <= 2 * n_eval + 2 * 60  # its window after the time


def test_a_time_termination_runs_the_schedule_to_its_end():
    # CMOES's tau (its epsilon's progress) reaches most of the way by the end of a 3-second run (compiled first:
    # a first compile inside the run is a slow start the estimate only catches up with)
    minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1), ("n_gen", 40), seed=1)
    res = minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1), ("time", 3.0), seed=1)
    taus = [r["tau"] for r in res.algorithm.trace]
    assert taus[-1] > 0.7 and res.algorithm.max_fe < 3 * res.algorithm.evaluator.n_eval, (taus[-5:], len(taus))


class Watching(Problem):
    """MW3, noting the algorithm pymoo hands a problem's _evaluate that asks for it (``requires_kwargs``:
    kwargs["algorithm"], as pymoo's own algorithms pass it)."""

    def __init__(self) -> None:
        self.inner = problem_by_name("mw3")
        super().__init__(n_var=self.inner.n_var, n_obj=2, n_ieq_constr=self.inner.n_ieq_constr, xl=self.inner.xl,
                         xu=self.inner.xu, requires_kwargs=True)
        self.seen: list[object] = []

    def _evaluate(self, x, out, *args, **kwargs):
        self.seen.append(kwargs.get("algorithm"))
        o = self.inner.evaluate(x, return_as_dictionary=True)
        out["F"], out["G"] = o["F"], o["G"]


@pytest.mark.parametrize("own", [False, True])
@pytest.mark.parametrize("name", PAPER)
def test_the_problem_is_told_the_algorithm_as_pymoo_tells_it(name, own):
    problem = Watching()
    kwargs = {"evaluator": Counting()} if own else {}
    res = minimize(problem, make_algorithm(AlgorithmSpec(name, 20), 2, 1), ("n_gen", 3), seed=1, **kwargs)
    assert problem.seen and all(a is res.algorithm for a in problem.seen)


def test_a_robust_termination_runs_as_long_as_its_budget_says():
    alg = make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1)
    res = minimize(problem_by_name("mw3"), alg, RobustTermination(MaximumGenerationTermination(10), period=6),
                   seed=1, copy_algorithm=False)
    assert res.algorithm.n_iter - 1 == 15 and alg.max_fe == 40 + 14 * 60  # CMOES's n_eval counts its real members
