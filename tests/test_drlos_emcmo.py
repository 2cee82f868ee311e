"""DRLOS-EMCMO (spec §4): its state and reward, the compiled Q-network against its matrix form, evaluation
accounting per operator, the transfer switch, exploration then Q-network choices with periodic updates,
determinism, and feasibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cmoea_common import check_repair_and_generations, check_seed
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.drlos_emcmo import DRLOSEMCMO, reward, state
from core.optimize.evolve.qnet import BATCH, DECAY, DROP_HID, DROP_IN, LR, QNet, Scaler
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
    odd = np.array([[5.0, -3.0], [7.0, 4.0], [9.0, 0.5]])  # columns that do not start at 0
    assert np.allclose(Scaler(odd).invert(Scaler(odd).apply(odd)), odd)


def test_the_q_network_learns_a_simple_value_function():
    rng = np.random.default_rng(0)
    X = rng.random((200, 4))
    y = 3.0 * X[:, 0] - 2.0 * X[:, 3]
    net = QNet(np.random.default_rng(1))
    net.fit(X, np.stack([y, -y, 0.5 * y, 0.5 * y], axis=1), 20_000)  # predict reads the first output: y
    pred = np.mean([net.predict(X) for _ in range(20)], axis=0)  # dropout stays on: average a few passes
    assert np.corrcoef(pred, y)[0, 1] > 0.9


def sgd_as_written(net, Xs, Ys, steps):
    """The network's SGD in numpy matrix form: each step draws its rows, then the input and hidden masks."""
    for _ in range(steps):
        idx = net.rng.integers(0, len(Xs), BATCH)
        x0 = Xs[idx] * (net.rng.random((BATCH, 4)) >= DROP_IN) / (1.0 - DROP_IN)
        z1 = x0 @ net.W1 + net.b1
        m1 = (net.rng.random(z1.shape) >= DROP_HID) / (1.0 - DROP_HID)
        h1d = np.maximum(z1, 0.0) * m1
        h2 = np.tanh(h1d @ net.W2 + net.b2)
        d3 = h2 @ net.W3 + net.b3 - Ys[idx]
        d2 = (d3 @ net.W3.T) * (1.0 - h2 * h2)
        d1 = (d2 @ net.W2.T) * m1 * (z1 > 0)
        for W, b, dW, d in ((net.W1, net.b1, x0.T @ d1, d1), (net.W2, net.b2, h1d.T @ d2, d2),
                            (net.W3, net.b3, h2.T @ d3, d3)):
            W -= LR * (dW + DECAY * W) / BATCH
            b -= LR * d.sum(axis=0) / BATCH


def test_the_compiled_sgd_is_the_networks_gradient_descent():
    # the compiled steps equal the matrix form up to rounding (numpy's products and tanh round differently),
    # draw the same numbers (the generators agree afterwards), and the pass predict uses is the same network
    data = np.random.default_rng(3)
    X, Y = data.random((50, 4)), data.random((50, 4))
    fast, slow = QNet(np.random.default_rng(5)), QNet(np.random.default_rng(5))
    fast.fit(X, Y, 300)
    slow.x_scale, slow.y_scale = Scaler(X), Scaler(Y)
    sgd_as_written(slow, slow.x_scale.apply(X), slow.y_scale.apply(Y), 300)
    for a, b in zip(fast.params(), slow.params(), strict=True):
        assert np.abs(a - b).max() < 1e-12
    assert not np.allclose(fast.W2, QNet(np.random.default_rng(5)).W2)  # it moved
    assert fast.rng.random() == slow.rng.random()
    x = fast.x_scale.apply(X[:3])
    fast.rng, rng = np.random.default_rng(9), np.random.default_rng(9)
    got = fast.forward(x)[-1]
    x0 = x * (rng.random(x.shape) >= DROP_IN) / (1.0 - DROP_IN)
    z1 = x0 @ fast.W1 + fast.b1
    h1d = np.maximum(z1, 0.0) * (rng.random(z1.shape) >= DROP_HID) / (1.0 - DROP_HID)
    want = np.tanh(h1d @ fast.W2 + fast.b2) @ fast.W3 + fast.b3
    assert got.shape == (3, 4) and np.abs(got - want).max() < 1e-12


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
    # Generation k chooses with gen = ceil(FE / 2N) of the evaluations before it, gens[k - 1]; a generation adds
    # N or 2N evaluations, so gen passes every integer: gen 201 (the first past 200) builds it, not gen 200.
    assert gens[built - 1] == 201 and gens[built - 2] == 200
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
