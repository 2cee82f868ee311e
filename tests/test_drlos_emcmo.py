"""DRLOS-EMCMO (spec §4): its state and reward, the numpy Q-network, evaluation accounting per operator, the
transfer switch, exploration then Q-network choices with periodic updates, determinism, and feasibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cmoea_common import check_repair_and_generations, check_seed
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.drlos_emcmo import DRLOSEMCMO, reward, state
from core.optimize.evolve.qnet import QNet, Scaler
from core.optimize.moea import problem_by_name


def test_the_state_and_both_rewards_by_hand():
    F = np.array([[1.0, 2.0], [3.0, 0.0], [np.inf, 1.0]])
    cv = np.array([0.0, 2.0, 0.0])
    a = Arrays(np.zeros((3, 1)), F, cv[:, None], cv)
    # Finite members only: mean summed objectives (3 + 3) / 2, mean CV 1, spread (3 - 1) + (2 - 0).
    assert state(a).tolist() == [3.0, 1.0, 4.0]
    s, s2 = np.array([3.0, 1.0, 4.0]), np.array([2.0, 0.5, 5.0])
    assert reward(s, s2) == pytest.approx(-0.5)  # PlatEMO's: the state's increase (spec pitfall 1)
    assert reward(s, s2, "improvement") == pytest.approx(1.0 + 0.5 + 1.0)


def test_scaling_maps_columns_to_minus_one_one_and_constants_to_minus_one():
    data = np.array([[0.0, 5.0], [10.0, 5.0], [5.0, 5.0]])
    sc = Scaler(data)
    assert sc.apply(data).tolist() == [[-1.0, -1.0], [1.0, -1.0], [0.0, -1.0]]
    assert np.allclose(sc.invert(sc.apply(data))[:, 0], data[:, 0])


def test_the_q_network_learns_a_simple_value_function():
    rng = np.random.default_rng(0)
    X = rng.random((200, 4))
    y = 3.0 * X[:, 0] - 2.0 * X[:, 3]
    net = QNet(np.random.default_rng(1))
    net.fit(X, np.repeat(y[:, None], 4, axis=1), 20_000)
    pred = np.mean([net.predict(X) for _ in range(20)], axis=0)  # dropout stays on: average a few passes
    assert np.corrcoef(pred, y)[0, 1] > 0.9


def run(name, evals, seed=1, pop=100, **options):
    p = problem_by_name(name)
    alg = make_algorithm(AlgorithmSpec("drlos_emcmo", pop, options), p.n_obj, seed)
    return minimize(p, alg, ("n_eval", evals), seed=seed, copy_algorithm=False), alg


def test_ga_costs_n_de_2n_and_transfer_starts_at_a_fifth_of_the_budget():
    _, alg = run("mw3", 10000, pop=40)
    rows = alg.trace
    assert rows[0]["n_eval"] == 80
    for r in rows[1:]:
        assert r["fe_generation"] == (40 if r["action"] == 1 else 80)
    switch = next(k for k, r in enumerate(rows) if r["phase"] == 2)
    assert rows[switch]["n_eval"] >= 2000 and rows[switch - 1]["n_eval"] < 2000
    assert all(math.isnan(r["succ1"]) for r in rows[1 : switch + 1])
    later = rows[switch + 1 :]
    assert {r["parents_to_P1"] for r in later} <= {0.0, 1.0} and not any(math.isnan(r["succ1"]) for r in later)


@pytest.fixture(scope="module")
def long_run():
    return run("mw3", 16000, pop=20)[1]  # gen = ceil(FE / 2N) passes 200: the Q-network is built and used


def test_random_operators_for_200_generations_then_the_q_network_chooses(long_run):
    rows = long_run.trace
    gens = [math.ceil(r["n_eval"] / 40) for r in rows]
    built = next(k for k, r in enumerate(rows) if r["updates"] >= 1)
    assert gens[built - 1] == 200 or gens[built] > 200  # the first generation past 200 builds it
    assert all(r["random_action"] == 1 for r in rows[: built + 1])
    chosen = [r for r in rows[built + 1 :] if r["random_action"] == 0]
    assert len(chosen) > 0.8 * len(rows[built + 1 :])  # greedy 95 %
    assert all(r["action"] == (1 if r["q1"] >= r["q2"] else 2) for r in chosen)
    # Updates every 51 generations after the first training.
    steps = [k for k in range(built + 1, len(rows)) if rows[k]["updates"] > rows[k - 1]["updates"]]
    assert steps and steps[0] - built in (50, 51)  # the building generation counts as the first
    assert all(b - a == 51 for a, b in zip(steps, steps[1:], strict=False))
    assert rows[-1]["replay"] == 500  # full: PlatEMO keeps its first 500 records


def test_same_seed_same_population_and_options_are_checked():
    check_seed(run, "ctp2", 3000, 3, pop=40)
    d, _ = run("ctp2", 3000, seed=3, pop=40, reward="improvement", replay="fifo", success="size")
    assert len(d.pop) == 40
    with pytest.raises(ValueError, match="reward must be one of platemo, improvement"):
        DRLOSEMCMO(pop_size=20, reward="worse")


@pytest.mark.parametrize("name", ["mw1", "mw3", "mw11", "ctp2"])
def test_reaches_a_feasible_population_at_20000_evaluations(name):
    res, _ = run(name, 20000)
    assert (res.pop.get("CV")[:, 0] <= 0).mean() > 0.5


def test_a_repair_and_a_generation_budget():
    check_repair_and_generations(lambda **kw: DRLOSEMCMO(pop_size=20, **kw), "mw3", 5)
