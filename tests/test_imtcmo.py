"""IMTCMO (spec §5): its epsilon schedule, auxiliary selection, evaluation accounting, determinism, and
feasibility on the constrained test problems."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from cmoea_common import check_seed
from hypothesis import given, settings
from hypothesis import strategies as st
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.imtcmo import IMTCMO, aux_select, epsilon_schedule, most_similar, neighbour_de, pbest_de
from core.optimize.moea import problem_by_name


def test_epsilon_falls_to_e_minus_6_at_half_the_budget():
    var0, cp = epsilon_schedule(40.0)
    assert var0 * (1 - 0.5) ** cp == pytest.approx(math.exp(-6.0))
    assert var0 * (1 - 0.0) ** cp == 40.0
    assert epsilon_schedule(0.0) == (1.0, pytest.approx((-0.0 - 6.0) / math.log(0.5)))  # VAR0 = 0 reads as 1
    assert epsilon_schedule(1e-4) == (1e-4, 0.0)  # below e^-6: constant, not growing (documented)


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 12), st.integers(0, 20), st.data())
def test_most_similar_is_the_head_of_a_stable_descending_sort(n, extra, data):
    # neighbour pairing's k most similar directions: ties (copies, -inf for undefined directions) go to the
    # lower column, as the stable argsort it replaces
    N = n + extra + 1
    values = st.sampled_from([-np.inf, -0.5, 0.0, 0.25, 1.0]) | st.floats(-1, 1)
    cos = np.array(data.draw(st.lists(values, min_size=n * N, max_size=n * N))).reshape(n, N)
    k = data.draw(st.integers(1, N))
    assert np.array_equal(most_similar(cos, k), np.argsort(-cos, axis=1, kind="stable")[:, :k])


def test_aux_selection_ranks_epsilon_feasible_members_first():
    F = np.array([[1.0, 1.0], [0.0, 0.0], [2.0, 2.0], [0.5, 0.5]])
    cv = np.array([0.0, 5.0, 0.1, 3.0])
    order, fit, n_feas = aux_select(F, cv, 3, var=0.2)
    assert n_feas == 2
    assert order[:2].tolist() == [0, 2]  # (1,1,cv 0) dominates (2,2,cv .1) in [f, CV]
    assert order[2] == 3  # then the smaller violation among the rest
    assert np.all(np.diff(fit) >= 0)
    order, _, n_feas = aux_select(F, cv, 2, var=-1.0)  # nothing epsilon-feasible: SPEA2 under CDP
    assert n_feas == 0 and order.tolist() == [0, 2]
    order, _, n_feas = aux_select(F, cv, 3, var=3.0)  # a violation equal to the level is within it
    assert n_feas == 3 and set(order.tolist()) == {0, 2, 3}


def test_neighbour_de_takes_penalised_members_quietly():
    # The predesign penalises an unassemblable design with infinite objectives: its direction is undefined
    # (inf - inf), it is nobody's neighbour, and numpy says nothing about it on the console.
    rng = np.random.default_rng(3)
    X = rng.random((12, 4))
    F = rng.random((12, 2))
    F[[2, 7]] = np.inf
    a = Arrays(X, F, np.zeros((12, 0)), np.zeros(12))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        child = neighbour_de(a, np.array([np.inf, 0.0]), 6, np.zeros(4), np.ones(4), rng)
    assert child.shape == (6, 4) and np.all((child >= 0) & (child <= 1))


def test_current_to_pbest_moves_children_toward_the_best_tenth():
    # The best 10 % by fitness sit at 0.9, the rest at 0.5: x + F (pbest - x + x_r1 - x_r2) drifts toward 0.9
    # (pbest drawn among the worst would leave the mean where it is, or pull it down).
    N, d = 400, 20
    fit = np.random.default_rng(1).random(N)
    X = np.full((N, d), 0.5)
    X[np.argsort(fit)[: N // 10]] = 0.9
    a = Arrays(X, np.zeros((N, 2)), np.zeros((N, 0)), np.zeros(N))
    child = pbest_de(a, fit, N, np.zeros(d), np.ones(d), np.random.default_rng(2))
    assert child.mean() - X.mean() > 0.08  # expected ~0.13: 0.9 x E[F] 0.8 x 0.4 x E[CR] 0.43


def test_neighbour_pairing_never_takes_the_same_neighbour_twice():
    # x_a = x_b would leave a child equal to its parent on every crossed site: only the mutation would move it.
    N, d = 300, 60
    rng = np.random.default_rng(5)
    X = rng.random((N, d))
    a = Arrays(X, rng.random((N, 2)) + 0.1, np.zeros((N, 0)), np.zeros(N))
    child = neighbour_de(a, np.zeros(2), N, np.zeros(d), np.ones(d), np.random.default_rng(6))
    changed = np.min((child[:, None, :] != X[None, :, :]).sum(-1), axis=1)  # against its parent, the nearest row
    assert (changed <= 1).mean() < 0.03  # ~0.5 % (CR 0.1 on 60 variables); 7 % more if a could equal b


def run(name: str, evals: int, seed: int = 1, pop: int = 40):
    p = problem_by_name(name)
    alg = make_algorithm(AlgorithmSpec("imtcmo", pop), p.n_obj, seed)
    return minimize(p, alg, ("n_eval", evals), seed=seed, copy_algorithm=False), alg


def test_two_n_evaluations_initially_and_per_generation_and_a_falling_epsilon():
    res, alg = run("mw3", 2000)
    evals = [row["n_eval"] for row in alg.trace]
    assert evals[0] == 80 and set(np.diff(evals)) == {80.0}
    eps = [row["eps"] for row in alg.trace]
    assert all(b <= a for a, b in zip(eps, eps[1:], strict=False)) and eps[-1] < eps[0]
    assert alg.trace[-1]["X"] == pytest.approx((len(evals) - 1) * 40 / 2000)  # X += N / maxFE: ends near 0.5


def test_same_seed_same_population_and_another_seed_another():
    check_seed(run, "ctp2", 1200, 7)


def test_an_odd_or_tiny_population_is_refused():
    with pytest.raises(ValueError, match="even population of at least 12"):
        IMTCMO(pop_size=11)


@pytest.mark.parametrize("name", ["mw1", "mw3", "mw11", "ctp2"])
def test_reaches_a_feasible_population_at_20000_evaluations(name):
    res, _ = run(name, 20000, pop=100)
    assert (res.pop.get("CV")[:, 0] <= 0).mean() > 0.5
