"""DRLOS-EMCMO's second phase, replay and Q-network training data (spec §4), on hand-built populations.

One generation of the second phase is run on populations of four (GA: two children each) whose selections are
known by hand. A member is its objective vector and its violation (``Plane``). Each population lies on one of
two anti-diagonal lines: the "good" line x + y = 1 dominates every point of the "bad" line x + y = 21, and the
points of one line do not dominate each other. Each population is either feasible (cv 0) or violates by 1.

- succ1 judges P2's material (P2 and its children O2) by task 1 (constraint domination): P2 feasible on the bad
  line and O2 infeasible on the good line make all four of P2 survive, succ1 = 4/100 - 0/50 > 0; the reverse
  makes both of O2 survive with two of P2, succ1 = 2/100 - 2/50 < 0. Plain dominance would say the opposite.
- succ2 judges P1's material (P1, O1) by task 2 (plain dominance): P1 infeasible on the good line beats O1
  feasible on the bad line (succ2 > 0), and the reverse (succ2 < 0). Constraint domination would say the opposite.

Then P1's pool takes N/2 random parents of P2 when succ1 > 0, else O2; P2's pool takes N/2 random members of the
*updated* P1 when succ2 > 0, else O1 (spec §4's loop and pitfall 7).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pymoo.core.problem import Problem

from core.optimize.evolve import spea2
from core.optimize.evolve.drlos_emcmo import DRLOSEMCMO, reward, state
from core.optimize.evolve.qnet import QNet, Scaler

N = 4


class Plane(Problem):
    """F = (x0, x1), g = x2."""

    def __init__(self) -> None:
        super().__init__(n_var=3, n_obj=2, n_ieq_constr=1, xl=-5.0, xu=30.0)

    def _evaluate(self, X, out, *args, **kwargs):
        out["F"] = X[:, :2].copy()
        out["G"] = X[:, 2:3].copy()


def members(good: bool, feasible: bool, phase: float, n: int) -> np.ndarray:
    """n points of the good (x + y = 1) or bad (x + y = 21) line; ``phase`` keeps populations apart."""
    t = (np.arange(n) + phase) / n
    off = 0.0 if good else 10.0
    return np.column_stack([off + t, off + 1.0 - t, np.full(n, -1.0 if feasible else 1.0)])


def scenario(succ1_positive: bool, succ2_positive: bool) -> dict[str, np.ndarray]:
    s1, s2 = succ1_positive, succ2_positive
    return {
        "P1": members(good=s2, feasible=not s2, phase=0.1, n=N),
        "O1": members(good=not s2, feasible=s2, phase=0.2, n=N // 2),
        "P2": members(good=not s1, feasible=s1, phase=0.3, n=N),
        "O2": members(good=s1, feasible=not s1, phase=0.4, n=N // 2),
    }


def labels(rows: np.ndarray, pops: dict[str, np.ndarray]) -> list[str]:
    """Which population each row (objectives first) comes from."""
    where = {tuple(x[:2]): name for name, X in pops.items() for x in X}
    return [where[tuple(r[:2])] for r in rows]


def rowset(X: np.ndarray) -> set[tuple[float, ...]]:
    return {tuple(r) for r in np.asarray(X)[:, :2]}


def one_generation(monkeypatch, pops, seed=0, records=None, **options):
    """Run one second-phase generation (GA, a random action) from the hand-built state; returns the algorithm
    and the two pools of eight that were selected from (cv passed or None)."""
    alg = DRLOSEMCMO(pop_size=N, **options)
    problem = Plane()
    alg.setup(problem, termination=("n_eval", 10**9), seed=seed)
    alg.xl, alg.xu = np.asarray(problem.xl, dtype=float), np.asarray(problem.xu, dtype=float)
    alg.arrays, alg.p2 = alg.evaluate(pops["P1"]), alg.evaluate(pops["P2"])
    alg.fit1, alg.fit2 = np.zeros(N), np.zeros(N)
    alg.phase, alg.max_fe, alg.model, alg.since_update, alg.updates = 2, 10**9, None, 0, 0
    alg.replay = list(records or [])
    p1 = alg.arrays
    monkeypatch.setattr(alg, "_children", lambda P, fit, action: (pops["O1"] if P is p1 else pops["O2"]).copy())
    monkeypatch.setattr(alg, "_choose", lambda s, gen: (1, True, float("nan"), float("nan")))
    pools: list[tuple[np.ndarray, object]] = []
    real = spea2.select

    def spy(F, n, cv=None, *args, **kwargs):
        if len(F) == 2 * N:  # the pools P + O + transfer (the success trials have six members)
            pools.append((np.array(F), None if cv is None else np.array(cv)))
        return real(F, n, cv, *args, **kwargs)

    monkeypatch.setattr(spea2, "select", spy)
    alg._advance()
    return alg, pools


CASES = list(itertools.product((True, False), (True, False)))


@pytest.mark.parametrize("success", ["platemo", "size"])
@pytest.mark.parametrize(("s1", "s2"), CASES)
def test_success_rates_count_survivors_of_the_other_tasks_selection(monkeypatch, s1, s2, success):
    alg, _ = one_generation(monkeypatch, scenario(s1, s2), success=success)
    row = alg.trace[-1]
    # Parents' survivors / d1 - children's survivors / d2: PlatEMO's constants (100, 50), or (N, |O| = N/2).
    d1, d2 = (100.0, 50.0) if success == "platemo" else (N, N / 2)
    want1 = 4 / d1 - 0 / d2 if s1 else 2 / d1 - 2 / d2
    want2 = 4 / d1 - 0 / d2 if s2 else 2 / d1 - 2 / d2
    assert row["succ1"] == pytest.approx(want1) and row["succ2"] == pytest.approx(want2)
    assert (row["parents_to_P1"], row["parents_to_P2"]) == (float(s1), float(s2))


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize(("s1", "s2"), CASES)
def test_transfer_direction_follows_each_tasks_success(monkeypatch, s1, s2, seed):
    pops = scenario(s1, s2)
    alg, pools = one_generation(monkeypatch, pops, seed=seed)
    (F1, cv1), (F2, cv2) = pools
    new1 = alg.arrays.X
    assert cv1 is not None and cv2 is None  # P1's pool by constraint domination, P2's by plain dominance
    got1 = labels(F1, pops)
    assert got1[: N + N // 2] == ["P1"] * N + ["O1"] * (N // 2)
    extra1 = F1[N + N // 2 :]
    if s1:  # N/2 distinct random parents of P2
        assert labels(extra1, pops) == ["P2", "P2"] and len(rowset(extra1)) == 2
    else:  # P2's offspring
        assert rowset(extra1) == rowset(pops["O2"])
    got2 = labels(F2[: N + N // 2], pops)
    assert got2 == ["P2"] * N + ["O2"] * (N // 2)
    extra2 = F2[N + N // 2 :]
    if s2:  # N/2 distinct members of the P1 just selected, which here holds none of the old P1
        assert rowset(extra2) <= rowset(new1) and len(rowset(extra2)) == 2
        assert not rowset(new1) & rowset(pops["P1"])
        # P1's pool has exactly four feasible members (O1 and the transfer): constraint domination keeps them.
        assert rowset(new1) == rowset(pops["O1"]) | rowset(extra1)
    else:  # P1's offspring
        assert rowset(extra2) == rowset(pops["O1"])
    if s1:  # O2 (good line, infeasible) dominates the rest of P2's pool: plain dominance keeps both
        assert rowset(pops["O2"]) <= rowset(alg.p2.X)


def test_the_generations_record_is_state_action_reward_next_state(monkeypatch):
    pops = scenario(True, True)
    alg, _ = one_generation(monkeypatch, pops)
    [(s, a, r, s_next)] = alg.replay
    # P1 before: the good line (summed objectives 1), all violating by 1, t from 0.025 to 0.775 in x and y.
    assert s == pytest.approx([1.0, 1.0, 1.5]) and a == 1
    assert s_next.tolist() == state(alg.arrays).tolist() and s_next[0] == pytest.approx(21.0)  # P1 after
    assert r == pytest.approx(reward(s, s_next)) and r > 0


def test_the_transfers_are_distinct_members(monkeypatch):
    # N/2 of the other population without replacement: over 20 seeds, a draw with replacement would repeat one
    pops = scenario(True, True)
    for seed in range(20):
        alg, [(F1, _), (F2, _)] = one_generation(monkeypatch, pops, seed=seed)
        assert len(rowset(F1[N + N // 2 :])) == 2 and len(rowset(F2[N + N // 2 :])) == 2


def test_a_replay_grows_to_500_records(monkeypatch):
    old = [(np.full(3, float(i)), 1 + i % 2, float(i), np.full(3, i + 0.5)) for i in range(499)]
    alg, _ = one_generation(monkeypatch, scenario(True, True), records=old)
    assert len(alg.replay) == 500 and alg.replay[:499] == old and alg.replay[-1][0][0] == pytest.approx(1.0)


@pytest.mark.parametrize("kind", ["platemo", "fifo"])
def test_a_full_replay_keeps_its_first_500_records_or_drops_the_oldest(monkeypatch, kind):
    old = [(np.full(3, float(i)), 1 + i % 2, float(i), np.full(3, i + 0.5)) for i in range(500)]
    alg, _ = one_generation(monkeypatch, scenario(True, True), records=old, replay=kind)
    assert len(alg.replay) == 500
    if kind == "platemo":  # PlatEMO drops the record just appended (spec pitfall 3)
        assert alg.replay == old
    else:
        assert alg.replay[:499] == old[1:] and alg.replay[-1][0][0] == pytest.approx(1.0)  # the new record


# The Q-network's training data ------------------------------------------------------------------------------


def records(n: int) -> list:
    """n distinct replay records: s = (i, 2i, 3i), a alternating, r = -i, s' = s + 0.5 (i from a record's s)."""
    return [(np.array([i, 2.0 * i, 3.0 * i]), 1 + i % 2, -float(i), np.array([i, 2.0 * i, 3.0 * i]) + 0.5)
            for i in range(n)]


def algorithm_with(replay: list, seed: int = 0) -> DRLOSEMCMO:
    alg = DRLOSEMCMO(pop_size=N)
    alg.setup(Plane(), termination=("n_eval", 10**9), seed=seed)
    alg.replay, alg.model, alg.updates = replay, None, 0
    return alg


class Fits:
    """Records QNet.fit's calls (X, Y, steps, refit_scaling) instead of training."""

    def __init__(self, monkeypatch) -> None:
        self.calls: list[tuple[np.ndarray, np.ndarray, int, bool]] = []
        calls = self.calls

        def fit(net, X, Y, steps, refit_scaling=True):
            calls.append((np.array(X), np.array(Y), steps, refit_scaling))
            net.x_scale, net.y_scale = Scaler(X), Scaler(Y)

        monkeypatch.setattr(QNet, "fit", fit)


def test_replay_samples_are_200_distinct_records_from_the_whole_buffer():
    alg = algorithm_with(records(500))
    seen: set[int] = set()
    for _ in range(5):
        batch = alg._sample()
        idx = [int(s[0]) for s, _, _, _ in batch]
        assert len(idx) == 200 and len(set(idx)) == 200  # without replacement
        assert all(alg.replay[i] is rec for i, rec in zip(idx, batch, strict=True))
        seen |= set(idx)
    assert max(seen) >= 450 and min(seen) < 50 and len(seen) > 400  # random over all 500, not the first 200
    assert len(algorithm_with(records(150))._sample()) == 150  # fewer records than 200: all of them


def test_first_training_fits_state_and_action_to_reward_and_next_state_for_80000_steps(monkeypatch):
    fits = Fits(monkeypatch)
    alg = algorithm_with(records(300))
    alg._build()
    [(X, Y, steps, _)] = fits.calls
    assert steps == 80_000 and X.shape == (200, 4) and Y.shape == (200, 4) and alg.updates == 1
    i = X[:, 0]
    assert len(set(i)) == 200
    np.testing.assert_array_equal(X[:, 1:3], np.column_stack([2 * i, 3 * i]))
    np.testing.assert_array_equal(X[:, 3], 1 + i % 2)  # the record's action
    np.testing.assert_array_equal(Y, np.column_stack([-i, i + 0.5, 2 * i + 0.5, 3 * i + 0.5]))  # (r, s')


def test_an_update_targets_reward_plus_09_times_the_batchs_largest_prediction(monkeypatch):
    fits = Fits(monkeypatch)
    alg = algorithm_with(records(500), seed=3)
    alg._build()
    asked: list[np.ndarray] = []

    def predict(X):  # a known "network": q = s1 / 10 + action
        asked.append(np.array(X))
        return X[:, 0] / 10.0 + X[:, 3]

    monkeypatch.setattr(alg.model, "predict", predict)
    alg._update()
    X, Y, steps, refit = fits.calls[-1]
    assert steps == 8_000 and refit and alg.updates == 2
    np.testing.assert_array_equal(asked[0], X)  # predicted for the batch it trains on
    i = X[:, 0]
    q = i / 10.0 + X[:, 3]
    y = -i + 0.9 * q.max()  # r_j + gamma * max over the sampled batch (not over actions)
    assert Y.shape == (200, 4)
    for col in range(4):  # the one-dimensional target on all four outputs
        np.testing.assert_allclose(Y[:, col], y, rtol=0, atol=1e-12)


def test_a_fit_refits_the_scaling_on_its_own_data():
    net = QNet(np.random.default_rng(0))
    X1, Y1 = np.random.default_rng(1).random((20, 4)), np.random.default_rng(2).random((20, 4))
    net.fit(X1, Y1, 1)
    X2, Y2 = 5.0 + X1 * 3.0, -2.0 + Y1
    net.fit(X2, Y2, 1)
    assert net.steps == 2
    np.testing.assert_array_equal(net.x_scale.lo, X2.min(axis=0))
    np.testing.assert_array_equal(net.y_scale.lo, Y2.min(axis=0))
    net.fit(X1, Y1, 1, refit_scaling=False)  # the old scaling kept
    np.testing.assert_array_equal(net.x_scale.lo, X2.min(axis=0))
