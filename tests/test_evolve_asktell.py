"""pymoo's ask-and-tell on the array algorithms: the same run as minimize(), evaluations counted once, and the
members told back checked (an EMO researcher's script drives an external simulator this way)."""

from __future__ import annotations

import numpy as np
import pytest
from pymoo.core.evaluator import Evaluator
from pymoo.core.problem import Problem
from pymoo.optimize import minimize
from pymoo.problems import get_problem

from core.optimize.algorithms import AlgorithmSpec, make_algorithm

PAPER = ["nsga2", "cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "mccmo", "moead_cmt"]


class Equality(Problem):
    """Two objectives, one inequality and one equality constraint."""

    def __init__(self) -> None:
        super().__init__(n_var=3, n_obj=2, n_ieq_constr=1, n_eq_constr=1, xl=0.0, xu=1.0)

    def _evaluate(self, x, out, *args, **kwargs):
        out["F"] = np.c_[x[:, 0], 1.0 - x[:, 0] + x[:, 1] ** 2]
        out["G"] = 0.2 - x[:, 2]
        out["H"] = x[:, 1] + x[:, 2] - 1.0


def ask_tell(name: str, problem, termination, own_evaluator: bool):
    alg = make_algorithm(AlgorithmSpec(name, 20), problem.n_obj, 1)
    alg.setup(problem, termination=termination, seed=1)
    asks = 0
    while alg.has_next():
        pop = alg.ask()
        (alg.evaluator if own_evaluator else Evaluator()).eval(problem, pop)
        alg.tell(infills=pop)
        asks += 1
    return alg, asks


@pytest.mark.parametrize("name", PAPER)
@pytest.mark.parametrize(("problem", "termination", "own"), [("mw3", ("n_gen", 6), True),
                                                              ("equality", ("n_eval", 600), False)])
def test_ask_and_tell_is_the_same_run_as_minimize(name, problem, termination, own):
    p = Equality() if problem == "equality" else get_problem(problem)
    alg, asks = ask_tell(name, p, termination, own)
    ref = minimize(p, make_algorithm(AlgorithmSpec(name, 20), p.n_obj, 1), termination, seed=1)
    r = alg.result()
    assert np.array_equal(r.X, ref.X) and np.array_equal(r.F, ref.F) and np.array_equal(r.CV, ref.CV)
    assert alg.evaluator.n_eval == ref.algorithm.evaluator.n_eval  # counted once, by either evaluator
    assert alg.n_gen == ref.algorithm.n_gen and asks >= ref.algorithm.n_gen - 1
    assert alg.ask() is None  # terminated


def test_a_generation_that_evaluates_in_batches_asks_for_each():
    # MOEA/D-CMT makes its children ahead in batches (docs/algorithms.md): more asks than generations, each a part.
    alg, asks = ask_tell("moead_cmt", get_problem("mw3"), ("n_gen", 3), True)
    assert asks > alg.n_gen


def test_tell_takes_only_the_members_ask_gave():
    p = get_problem("mw3")
    alg = make_algorithm(AlgorithmSpec("nsga2", 20), 2, 1)
    alg.setup(p, termination=("n_gen", 3), seed=1)
    with pytest.raises(ValueError, match="ask first"):
        alg.tell(infills=p.evaluate(np.full((20, p.n_var), 0.5), return_as_dictionary=True))
    pop = alg.ask()
    assert np.array_equal(alg.ask().get("X"), pop.get("X"))  # asking again: the same members
    Evaluator().eval(p, pop)
    with pytest.raises(ValueError, match="the 20 members ask\\(\\) gave, got 10"):
        alg.tell(infills=pop[:10])
    from pymoo.core.population import Population

    with pytest.raises(ValueError, match="their X differ from what ask"):
        alg.tell(infills=Population.new("X", pop.get("X")[::-1], "F", pop.get("F"), "G", pop.get("G")))
    with pytest.raises(ValueError, match=r"evaluated: F \(2 each\), G \(2 each\) missing or of another shape"):
        alg.tell(infills=Population.new("X", pop.get("X")))  # not evaluated
    alg.tell(infills=pop)  # the right ones still go through
    assert alg.n_gen == 2 and alg.evaluator.n_eval == 20


def test_a_copy_after_tell_runs_on_alike_and_a_copy_between_ask_and_tell_is_refused():
    import copy
    import pickle

    p = get_problem("mw3")
    alg = make_algorithm(AlgorithmSpec("cmoes", 20), 2, 1)
    alg.setup(p, termination=("n_gen", 4), seed=1)
    pop = alg.ask()
    with pytest.raises(TypeError, match=r"between ask\(\) and tell\(\)"):
        copy.deepcopy(alg)
    alg.evaluator.eval(p, pop)
    alg.tell(infills=pop)
    while alg.n_gen is None or alg.n_gen < 2:  # CMOES evaluates two populations in its first generation
        with pytest.raises(TypeError, match="tell first"):
            pickle.dumps(alg)
        pop = alg.ask()
        alg.evaluator.eval(p, pop)
        alg.tell(infills=pop)
    twin = pickle.loads(pickle.dumps(alg))  # between generations: a copy goes on as the original does
    for a in (alg, twin):
        while a.has_next():
            pop = a.ask()
            a.evaluator.eval(p, pop)
            a.tell(infills=pop)
    assert np.array_equal(alg.result().F, twin.result().F) and twin.evaluator.n_eval == alg.evaluator.n_eval


@pytest.mark.parametrize("name", PAPER)
def test_a_keyword_the_algorithm_does_not_take_is_refused_not_swallowed(name):
    # EMO rehearsal (session 33): pymoo's Algorithm swallowed any keyword, so `popsize=20` ran at pop 100 and
    # `crossover=SBX(...)` did nothing, without a word.
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.sampling.rnd import FloatRandomSampling

    cls = type(make_algorithm(AlgorithmSpec(name, 20), 2, 1))
    with pytest.raises(TypeError, match="takes no keyword 'popsize'"):
        cls(popsize=20)
    with pytest.raises(TypeError, match="takes no keyword 'crossover'"):
        cls(pop_size=20, crossover=SBX())
    with pytest.raises(TypeError, match="sampling is an \\(n, d\\) array"):
        cls(pop_size=20, sampling=FloatRandomSampling())
    cls(pop_size=20, seed=3, save_history=True, verbose=False)  # pymoo's own keywords pass


def test_an_array_sampling_is_the_first_population():
    p = get_problem("mw3")
    X = np.random.default_rng(7).uniform(p.xl, p.xu, size=(20, p.n_var))
    cls = type(make_algorithm(AlgorithmSpec("nsga2", 20), 2, 1))
    r = minimize(p, cls(pop_size=20, sampling=X), ("n_gen", 1), seed=1)
    got = r.pop.get("X")
    assert np.array_equal(got[np.lexsort(got.T)], X[np.lexsort(X.T)])


def test_next_between_ask_and_tell_is_refused_and_an_interrupted_tell_goes_on():
    # Review of session 33: ask(); next() ran a second generation beside the waiting one, and a Ctrl-C inside
    # tell() left its worker running while the next ask() started another: 140 evaluations where minimize spent 120.
    from core.optimize.evolve import base

    p = get_problem("mw3")
    alg = make_algorithm(AlgorithmSpec("nsga2", 20), 2, 1)
    alg.setup(p, termination=("n_gen", 6), seed=1)
    pop = alg.ask()
    with pytest.raises(RuntimeError, match="waiting for tell"):
        alg.next()
    alg.evaluator.eval(p, pop)
    alg.tell(infills=pop)
    real, hit = base._AskTell.request, []

    def interrupted(self):  # the user's Ctrl-C while tell() waits for the worker
        if not hit:
            hit.append(1)
            raise KeyboardInterrupt
        return real(self)

    pop = alg.ask()
    alg.evaluator.eval(p, pop)
    base._AskTell.request = interrupted
    try:
        with pytest.raises(KeyboardInterrupt):
            alg.tell(infills=pop)
    finally:
        base._AskTell.request = real
    while alg.has_next():  # the notebook cell run again
        pop = alg.ask()
        alg.evaluator.eval(p, pop)
        alg.tell(infills=pop)
    ref = minimize(p, make_algorithm(AlgorithmSpec("nsga2", 20), 2, 1), ("n_gen", 6), seed=1)
    assert np.array_equal(alg.result().F, ref.F) and alg.evaluator.n_eval == ref.algorithm.evaluator.n_eval == 120
