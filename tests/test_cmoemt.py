"""CMOEMT (spec §2): the change rate, the push/pull replacement rule, evaluation accounting, the push -> pull
switch and the falling epsilon, knowledge transfer in the second half, both variants, determinism, and
feasibility on the constrained test problems."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cmoea_common import check_repair_and_generations, check_seed, replace_ok
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.cmoemt import ALPHA, CMOEMT, CP, TAU, change_rate
from core.optimize.moea import problem_by_name


def test_the_change_rate_over_twenty_generations_counts_unwritten_history_as_zero():
    ideal = {g: np.array([1.0, 2.0]) for g in range(2, 40)}
    nadir = {g: np.array([10.0, 10.0]) for g in range(2, 40)}
    assert change_rate(ideal, nadir, 30) == 0.0
    nadir[39] = np.array([10.0, 11.5])  # 15 % on the second objective, against generation 20
    assert change_rate(ideal, nadir, 39) == pytest.approx(0.15)
    # Generation 20 compares with generation 1, never written: zeros, a huge change (spec pitfall 4).
    assert change_rate(ideal, nadir, 20) > 1e5


def test_push_compares_objectives_only_and_pull_applies_the_improved_epsilon_rule():
    g_old, g_new = np.array([2.0, 1.0, 2.0, 2.0]), np.array([1.0, 2.0, 1.0, 1.0])
    cv_old = np.array([0.5, 0.0, 3.0, 0.0])
    assert replace_ok(g_old, g_new, cv_old, 2.0, eps=1.0, pull=False).tolist() == [True, False, True, True]
    # Pull, eps 1: member 0 (cv 0.5) and the child (cv 2) are not both within eps and differ: only a lower
    # violation would do (2 > 0.5: no); member 2 (cv 3): the child's violation is lower: yes.
    assert replace_ok(g_old, g_new, cv_old, 2.0, eps=1.0, pull=True).tolist() == [False, False, True, False]
    # A child within eps (0.5): members within eps are compared by objectives alone.
    assert replace_ok(g_old, g_new, cv_old, 0.5, eps=1.0, pull=True).tolist() == [True, False, True, True]


def run(name, evals, seed=1, pop=100, variant="platemo"):
    p = problem_by_name(name)
    alg = make_algorithm(AlgorithmSpec("cmoemt", pop, {"variant": variant}), p.n_obj, seed)
    return minimize(p, alg, ("n_eval", evals), seed=seed, copy_algorithm=False), alg


def test_two_n_evaluations_per_generation_push_then_pull_and_transfer_in_the_second_half():
    _, alg = run("ctp2", 20000)  # (on MW3 the ideal point nears 0 and its relative change never settles)
    rows = alg.trace
    assert rows[0]["n_eval"] == 300
    assert set(np.diff([r["n_eval"] for r in rows])) == {200.0}  # N/2 + 5 x N/5 + N/2
    pull = [r["pull"] for r in rows]
    first = pull.index(1.0)
    assert sorted(pull) == pull and first >= 20  # push, then pull for good; no switch before the 20-generation window
    eps = [r["eps"] for r in rows[first:]]
    assert eps[0] > 0 and eps[-1] < eps[0]
    # The improved epsilon rule, generation by generation (spec §2): shrink by (1 - tau) while the feasible ratio
    # is below alpha, else the schedule eps0 (1 - gen / Tc)^cp; gen counts 2N-evaluation loops, Tc N-evaluation
    # ones (Tc = 0.9 ceil(maxFE / N), never reached: spec pitfall 2).
    assert alg.Tc == pytest.approx(0.9 * math.ceil(20000 / alg.n))
    both = {"shrink": 0, "schedule": 0}
    for before, row in zip(rows[first:], rows[first + 1 :], strict=False):
        gen = math.ceil(before["n_eval"] / (2 * alg.n))
        if row["rf"] < ALPHA:
            want, both["shrink"] = (1 - TAU) * before["eps"], both["shrink"] + 1
        else:
            want, both["schedule"] = row["eps0"] * (1 - gen / alg.Tc) ** CP, both["schedule"] + 1
        assert row["eps"] == pytest.approx(want, rel=1e-12), (gen, row)
    assert both["shrink"] > 0  # CTP2's task 2 stays below alpha feasible: the schedule is tested below
    # The switch happens when the change rate over 20 generations is at most 0.1.
    assert rows[first]["r"] <= 0.1 and all(r["r"] > 0.1 for r in rows[1:first] if math.isfinite(r["r"]))
    transfer = [r["transfer"] for r in rows]
    half = next(k for k, r in enumerate(rows) if r["n_eval"] >= 10000)
    assert not any(transfer[: half + 1]) and all(transfer[half + 1 :])
    # Survivors may come from P2 and P3 only once populations are shared.
    assert all(r["from_P2"] == 0 and r["from_P3"] == 0 for r in rows[1 : half + 1])
    assert any(r["from_P2"] + r["from_P3"] > 0 for r in rows[half + 1 :])


def test_the_epsilon_schedule_once_task_two_is_feasible_enough_and_zero_from_tc():
    alg = CMOEMT(pop_size=20)
    alg.P2 = members([[0, 1], [1, 0], [2, 2]], [0.0, 0.0, 0.0])  # feasible ratio 1 >= alpha
    alg.z, alg.pull, alg.eps0, alg.eps, alg.Tc, alg.r = np.zeros(2), True, 2.0, 0.5, 100.0, 0.0
    alg.ideal, alg.nadir = {}, {}
    alg._epsilon(30)
    assert alg.eps == pytest.approx(2.0 * (1 - 30 / 100.0) ** 2)
    alg.P2 = members([[0, 1], [1, 0], [2, 2]], [0.0, 3.0, 0.0])  # 2/3 < alpha: shrink by (1 - tau)
    alg._epsilon(31)
    assert alg.eps == pytest.approx((1 - TAU) * 2.0 * 0.7**2)
    alg._epsilon(100)
    assert alg.eps == 0.0 and alg.pull


def test_the_effective_population_is_the_number_of_weight_vectors():
    res, alg = run("mw4", 2000, pop=100)  # three objectives: 91 vectors
    assert alg.n == 91 and len(res.pop) == 91 and alg.trace[0]["n_eval"] == 3 * 91
    # Task 2's subset always holds the m extreme subproblems (the axis weights) and the middle one (spec §2).
    axes = np.flatnonzero(alg.W.max(axis=1) > 1 - 1e-3)
    assert len(axes) == 3 and sorted(alg.extremes.tolist()) == sorted(axes.tolist())
    subset = alg._subset()
    assert len(subset) == 91 // 5 and set(axes) | {91 // 2 - 1} <= set(subset.tolist())


def members(F, cv):
    F = np.asarray(F, dtype=float)
    return Arrays(np.zeros((len(F), 1)), F, np.zeros((len(F), 1)), np.asarray(cv, dtype=float))


def test_the_author_repo_task_two_counts_a_violation_equal_to_epsilon_as_feasible():
    alg = CMOEMT(pop_size=20, variant="author_repo")
    alg.n, alg.eps = 2, 1.0
    # A (cv = eps) dominates all; B dominates C; D is infeasible beyond eps. Relaxed: A and B survive.
    kept = alg._select_task2(members([[0, 0], [1, 1]], [1.0, 0.0]), members([[2, 2], [0.5, 0.5]], [0.0, 5.0]))
    assert sorted(kept.F[:, 0].tolist()) == [0.0, 1.0]


def test_the_author_repo_trial_gives_a_tie_to_task_two():
    alg = CMOEMT(pop_size=20, variant="author_repo")
    alg.n = 2
    worse = members([[5, 5]], [0.0])
    alg.p3 = members([[1, 0]], [0.0])  # one survivor from task 3 ...
    pool, src = alg._trial(worse, members([[0, 1]], [0.0]), worse, worse, worse)  # ... and one from task 2
    assert set(src.tolist()) == {0, 1, 3, 4} and [0.0, 1.0] in pool.F.tolist()


def test_same_seed_same_population_and_another_seed_another():
    check_seed(run, "ctp2", 2000, 4)


def test_the_author_repo_variant_selects_task_two_and_changes_the_run():
    a, alg = run("mw3", 12000, variant="author_repo")
    b, _ = run("mw3", 12000)
    assert not np.array_equal(a.pop.get("X"), b.pop.get("X"))
    assert (a.pop.get("CV")[:, 0] <= 0).mean() > 0.5
    with pytest.raises(ValueError, match="variant must be one of platemo, author_repo"):
        CMOEMT(pop_size=20, variant="bogus")


@pytest.mark.parametrize("name", ["mw3", "mw11", "ctp2"])
def test_reaches_a_feasible_population_at_20000_evaluations(name):
    res, _ = run(name, 20000)
    assert (res.pop.get("CV")[:, 0] <= 0).mean() > 0.5


def test_mw1_is_reached_in_two_of_three_seeds():
    # MW1's feasible band is thin; PlatEMO's version misses it with seed 1 at this budget (docs/algorithms.md).
    hits = sum((run("mw1", 20000, seed=s)[0].pop.get("CV")[:, 0] <= 0).mean() > 0.5 for s in (1, 2, 3))
    assert hits >= 2


def test_a_repair_and_a_generation_budget():
    check_repair_and_generations(lambda **kw: CMOEMT(pop_size=20, **kw), "mw3", 4)
