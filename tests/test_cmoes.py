"""CMOES (spec §3): the promising region, EvenSearch, the stage switch and its evaluation counts, the DE
operator, determinism, and feasibility on the constrained test problems."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cmoea_common import check_repair_and_generations, check_seed
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.cmoes import CMOES, even_search, in_region
from core.optimize.moea import problem_by_name


def test_the_promising_region_is_what_no_feasible_member_dominates():
    R = np.array([[1.0, 1.0], [0.0, 3.0]])
    F = np.array([[2.0, 2.0],   # dominated by (1, 1): out
                  [0.5, 2.0],   # dominated by neither: in
                  [1.0, 1.0],   # equal to a member of R: in
                  [0.0, 3.5]])  # dominated by (0, 3): out
    assert in_region(F, R).tolist() == [False, True, True, False]
    assert in_region(F, np.zeros((0, 2))).all()  # no feasible member yet: everything is in


@pytest.mark.parametrize("seed", range(6))
def test_the_promising_region_equals_its_definition_with_ties_and_nan(seed):
    # small integer grids: many equal objectives; a NaN in R never dominates, a NaN in F counts as +inf
    rng = np.random.default_rng(seed)
    m = 1 + seed % 3
    F, R = rng.integers(0, 3, (40, m)).astype(float), rng.integers(0, 3, (25, m)).astype(float)
    R[rng.random(R.shape) < 0.1] = np.nan
    F[rng.random(F.shape) < 0.05] = np.nan
    Fi = np.where(np.isnan(F), np.inf, F)
    want = [not any((r <= f).all() and (r < f).any() for r in R) for f in Fi]
    assert in_region(F, R).tolist() == want


def arrays(F, cv):
    F = np.asarray(F, dtype=float)
    return Arrays(np.arange(len(F), dtype=float)[:, None], F, np.asarray(cv, dtype=float)[:, None],
                  np.asarray(cv, dtype=float))


def test_even_search_keeps_the_regions_non_dominated_and_its_nearly_feasible_members():
    pool = arrays([[0.5, 2.0], [2.0, 0.5], [1.0, 1.0], [3.0, 3.0], [0.4, 2.5], [0.45, 2.2], [1.2, 1.2]],
                  [0.0, 5.0, 0.2, 0.0, 9.0, 1.5, 3.0])
    R = np.array([[2.5, 2.5]])  # (3, 3) is dominated by it: out of the region
    p2, fit2, p3, key3, q = even_search(pool, R, n=10, tau=0.5, max_cv=4.0)
    assert q == 6
    # Unconstrained non-dominated members of the region, not filled up to n with (1.2, 1.2).
    assert sorted(p2.X[:, 0].tolist()) == [0.0, 1.0, 2.0, 4.0, 5.0] and np.all(fit2 < 1)
    # CV <= maxCV (1 - tau)^2 = 1.0 (not maxCV (1 - tau) = 2: member 5's 1.5 is out): members 0 and 2; the key is
    # their CV.
    assert sorted(p3.X[:, 0].tolist()) == [0.0, 2.0] and sorted(key3.tolist()) == [0.0, 0.2]
    p2, _, p3, _, _ = even_search(pool, R, n=2, tau=0.5, max_cv=4.0)
    assert len(p2) == 2 and len(p3) == 2  # truncated down to n


def run(name, evals, seed=1, pop=40, operator="ga"):
    p = problem_by_name(name)
    alg = make_algorithm(AlgorithmSpec("cmoes", pop, {"operator": operator}), p.n_obj, seed)
    return minimize(p, alg, ("n_eval", evals), seed=seed, copy_algorithm=False), alg


def test_stage_one_costs_3n_then_stage_two_n_plus_the_helpers_and_epsilon_shrinks():
    res, alg = run("mw3", 6000)
    rows = alg.trace
    assert rows[0]["n_eval"] == 80  # P1 and P2
    stage = [r["stage"] for r in rows]
    assert stage[1] == 1 and stage[-1] == 2 and sorted(stage) == stage  # one switch, never back
    first2 = stage.index(2)
    # The switch comes once P1 has a feasible member and 20 % of the generations (gen = ceil(FE/N)) are done.
    assert alg.max_gen == 150
    before = rows[first2 - 1]
    assert math.ceil(before["n_eval"] / 40) > 0.2 * alg.max_gen and before["R"] > 0
    assert math.ceil(rows[first2 - 2]["n_eval"] / 40) <= 0.2 * alg.max_gen
    for r in rows[1:first2]:
        assert r["fe_generation"] == 120  # GA mode: P1's 2N children and P2's N
    for k in range(first2 + 1, len(rows)):
        assert rows[k]["fe_generation"] == 40 + rows[k - 1]["P2"] + rows[k - 1]["P3"]
    # epsilon = maxCV (1 - tau)^2 with tau = ceil(FE/N) / maxGen (maxCV recomputed from the helpers' union).
    for k in range(first2, len(rows)):
        tau = math.ceil(rows[k - 1]["n_eval"] / 40) / alg.max_gen
        assert rows[k]["tau"] == pytest.approx(tau)
        assert rows[k]["eps"] == pytest.approx(rows[k]["max_cv"] * (1 - tau) ** 2)


def test_stage_one_lasts_while_gen_is_at_most_a_fifth_of_max_gen_and_ends_after_it():
    _, alg = run("mw3", 5800)  # max_gen 145: gen = ceil(FE / N) runs 2, 5, ..., 29, 32 and meets 0.2 max_gen = 29
    rows = alg.trace
    assert alg.max_gen == 145
    gens = [math.ceil(r["n_eval"] / 40) for r in rows]  # row k ran at gens[k - 1]
    at = gens.index(29) + 1
    assert rows[at - 1]["R"] > 0 and rows[at]["stage"] == 1  # feasible already, but gen 29 is still stage one
    assert rows[at + 1]["stage"] == 2


def test_max_gen_under_a_generation_budget_counts_stage_ones_3n_a_generation():
    p = problem_by_name("mw3")
    alg = make_algorithm(AlgorithmSpec("cmoes", 40, {}), p.n_obj, 1)
    minimize(p, alg, ("n_gen", 10), seed=1, copy_algorithm=False)
    assert alg.max_fe == 2 * 40 + 9 * 3 * 40 and alg.max_gen == math.ceil(alg.max_fe / 40)


def test_the_de_operator_makes_n_children_in_stage_one():
    _, alg = run("ctp2", 2000, operator="de")
    assert alg.trace[1]["stage"] == 1 and alg.trace[1]["fe_generation"] == 80  # N from P1 and N from P2


def test_same_seed_same_population_and_another_seed_another():
    check_seed(run, "ctp2", 1600, 7)


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="operator must be 'ga' or 'de'"):
        CMOES(pop_size=20, operator="pso")


@pytest.mark.parametrize("name", ["mw1", "mw3", "mw11", "ctp2"])
def test_reaches_a_feasible_population_at_20000_evaluations(name):
    res, _ = run(name, 20000, pop=100)
    assert (res.pop.get("CV")[:, 0] <= 0).mean() > 0.5


def test_a_repair_and_a_generation_budget():
    check_repair_and_generations(lambda **kw: CMOES(pop_size=20, **kw), "ctp2", 6)
