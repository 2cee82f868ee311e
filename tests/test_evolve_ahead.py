"""Children evaluated ahead in one batch (CMOEMT's task 2, MOEA/D-CMT) give the published one-at-a-time loop's
run exactly: same populations, traces and evaluation counts, with far fewer calls of the problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pymoo.core.problem import Problem
from pymoo.optimize import minimize
from pymoo.problems import get_problem

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.evolve import ahead

CONFIGS = Path(__file__).resolve().parents[1] / "assets" / "configs"


class Counted(Problem):
    """A pymoo problem that counts its calls and the members it evaluated."""

    def __init__(self, inner: Problem) -> None:
        super().__init__(n_var=inner.n_var, n_obj=inner.n_obj, n_ieq_constr=inner.n_ieq_constr, xl=inner.xl,
                         xu=inner.xu)
        self.inner, self.calls, self.rows = inner, 0, 0

    def _evaluate(self, X, out, *args, **kwargs):
        self.calls += 1
        self.rows += len(X)
        res = self.inner.evaluate(X, return_as_dictionary=True)
        out["F"], out["G"] = res["F"], res["G"]


def run(name: str, problem: str, ahead: bool, seed: int, evals: int = 3000):
    p = Counted(get_problem(problem))
    alg = make_algorithm(AlgorithmSpec(name, 40, {"ahead": ahead}), p.n_obj, seed)
    minimize(p, alg, ("n_eval", evals), seed=seed, copy_algorithm=False)
    return alg, p


@pytest.mark.parametrize("name", ["cmoemt", "moead_cmt"])
@pytest.mark.parametrize("problem,seed,window", [("mw3", 1, 8), ("ctp2", 2, 8), ("mw3", 3, 1), ("ctp2", 1, 40)])
def test_ahead_gives_the_one_at_a_time_run_exactly_with_fewer_calls(name, problem, seed, window, monkeypatch):
    monkeypatch.setattr(ahead, "WINDOW", window)
    fast, pf = run(name, problem, True, seed)
    slow, ps = run(name, problem, False, seed)
    for key in ("X", "F", "G", "cv"):
        np.testing.assert_array_equal(getattr(fast.arrays, key), getattr(slow.arrays, key))
    assert fast.evaluator.n_eval == slow.evaluator.n_eval == ps.rows
    assert len(fast.trace) == len(slow.trace)
    missed = [row.pop("evaluated_ahead_unused") for row in fast.trace[1:]]
    assert all(row.pop("evaluated_ahead_unused") == 0 for row in slow.trace[1:])
    for a, b in zip(fast.trace, slow.trace, strict=True):
        assert a.keys() == b.keys()
        np.testing.assert_array_equal(np.array(list(a.values())), np.array(list(b.values())))
    # Both ways were taken: children used as evaluated ahead, and children made again after a replacement.
    per_gen = len(fast.W) if name == "moead_cmt" else 5 * max(len(fast.W) // 5, 1)  # CMOEMT: 5 rounds of N/5
    children = per_gen * (len(fast.trace) - 1)
    assert sum(missed) > 0
    assert pf.rows == ps.rows + sum(missed)  # the extra evaluations are reported
    # one call per generation for the batch and one per window of children made again, instead of one per child
    gens = len(fast.trace) - 1
    windows = pf.calls - (ps.calls - children) - gens
    assert sum(missed) / window <= windows <= sum(missed)
    if window == 1:
        assert windows == sum(missed)
    else:
        assert windows < sum(missed)


def test_ahead_must_be_true_or_false():
    with pytest.raises(ValueError, match="'ahead' must be true or false"):
        make_algorithm(AlgorithmSpec("moead_cmt", 20, {"ahead": "no"}), 2, 1)


def test_a_design_config_turns_it_off_and_a_wrong_value_names_the_key(tmp_path):
    from core.formats.config import load_config

    text = (CONFIGS / "stephenson1_cycloid_moead_cmt.toml").read_text()
    assert '[algorithm]\nname = "moead_cmt"\n' in text
    off = tmp_path / "off.toml"
    off.write_text(text.replace('[algorithm]\nname = "moead_cmt"\n', '[algorithm]\nname = "moead_cmt"\n'
                                                                      'options = { ahead = false }\n'))
    assert {s.algorithm.options.get("ahead") for s in load_config(off).stages} == {False}
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('[algorithm]\nname = "moead_cmt"\n', '[algorithm]\nname = "moead_cmt"\n'
                                                                      'options = { ahead = "no" }\n'))
    with pytest.raises(ValueError, match="ahead"):
        load_config(bad)


@pytest.mark.parametrize("d", [1, 5, 16])
def test_children_made_from_their_drawn_numbers_are_the_operators_children(d):
    from core.optimize.evolve.variation import de_rand_1, ga

    rng = np.random.default_rng(d)
    lo, hi = np.zeros(d), np.linspace(1.0, 3.0, d)
    X = rng.uniform(lo - 0.2, hi + 0.2, (12, d))  # some parents outside the box: children are clipped
    X[3, 0] = np.nan  # NaN passes through the clip as in np.clip
    n = 7
    pp = rng.integers(0, 2, (n, 3))
    pi = rng.integers(0, 6, (n, 3))
    XA, XB = X[:6], X[6:]
    rows = [[XA[pi[c, q]] if pp[c, q] == 0 else XB[pi[c, q]] for q in range(3)] for c in range(n)]
    for op in (ahead.DE, ahead.GA_HALF):
        state = rng.bit_generator.state
        want = []
        for c in range(n):  # the operators, one child at a time, drawing from the generator
            p = [r[None, :] for r in rows[c]]
            want.append(de_rand_1(*p, lo, hi, rng) if op == ahead.DE else ga(p[0], p[1], lo, hi, rng, half=True))
        rng.bit_generator.state = state
        nums = np.empty((n, ahead.numbers(op, d)))
        for c in range(n):
            rng.random(out=nums[c])
        below, above = ahead.powers(nums, d) if op == ahead.GA_HALF else (nums, nums)
        got = ahead.make_children(op, np.arange(n)[::-1].copy(), pp, pi, XA, XB, nums, below, above, lo, hi)
        np.testing.assert_array_equal(got[::-1], np.vstack(want))
        assert np.isfinite(got).sum() >= got.size - n  # only the NaN parent's variable can be NaN


def _started(name: str, problem: str, seed: int):
    """An algorithm after its initial population and one generation, ready for the next."""
    p = get_problem(problem)
    alg = make_algorithm(AlgorithmSpec(name, 40), p.n_obj, seed)
    alg.setup(p, termination=("n_eval", 10**6), seed=seed)
    alg.next()
    alg.next()
    return alg


@pytest.mark.parametrize("problem,seed", [("mw3", 1), ("ctp2", 4), ("mw14", 2)])
@pytest.mark.parametrize("k", [0, 1])
def test_moead_cmt_draws_each_childs_numbers_in_the_published_loops_order(problem, seed, k):
    # The published loop (PlatEMO's MOEADCMT.m), one child at a time with the operators drawing from the generator,
    # against the numbers drawn first and the children made from them: same pools, same children, same draws used.
    from core.optimize.evolve.moead_cmt import DELTA, RMP
    from core.optimize.evolve.variation import de_rand_1, ga

    alg = _started("moead_cmt", problem, seed)
    rng, n, P1, P2 = alg.random_state, len(alg.W), alg.P1, alg.P2
    state = rng.bit_generator.state
    pools, offs, pp, pi, nums = alg._draw(k)
    after = rng.random()
    op = ahead.DE if k == 0 else ahead.GA_HALF
    below, above = ahead.powers(nums, alg.problem.n_var) if k else (nums, nums)
    got = ahead.make_children(op, np.arange(n), pp, pi, P1.X, P2.X, nums, below, above, alg.xl, alg.xu)
    rng.bit_generator.state = state
    for i in range(n):
        pool = rng.permutation(alg.B[i]) if rng.random() < DELTA else rng.permutation(n)
        np.testing.assert_array_equal(pools[offs[i]:offs[i + 1]], pool)
        if k == 0:
            src = P1 if rng.random() < RMP else P2
            x = de_rand_1(P1.X[i:i + 1], src.X[pool[:1]], src.X[pool[1:2]], alg.xl, alg.xu, rng)
        else:
            src = P2 if rng.random() < RMP else P1
            x = ga(src.X[pool[:1]], src.X[pool[1:2]], alg.xl, alg.xu, rng, half=True)
        np.testing.assert_array_equal(got[i], x[0])
    assert rng.random() == after


@pytest.mark.parametrize("problem,seed", [("mw3", 1), ("ctp2", 4), ("mw14", 2)])
def test_cmoemt_task2_draws_each_childs_numbers_in_the_published_loops_order(problem, seed):
    from core.optimize.evolve.cmoemt import DELTA, ROUNDS
    from core.optimize.evolve.variation import de_rand_1

    alg = _started("cmoemt", problem, seed)
    rng, n, P = alg.random_state, alg.n, alg.P2
    state = rng.bit_generator.state
    pools, offs, pp, pi, nums = alg._draw()
    after = rng.random()
    got = ahead.make_children(ahead.DE, np.arange(len(pi)), pp, pi, P.X, P.X, nums, nums, nums, alg.xl, alg.xu)
    rng.bit_generator.state = state
    c = 0
    for _ in range(ROUNDS):
        for i in alg._subset():
            pool = rng.permutation(alg.B[i]) if rng.random() < DELTA else rng.permutation(n)
            np.testing.assert_array_equal(pools[offs[c]:offs[c + 1]], pool)
            x = de_rand_1(P.X[i:i + 1], P.X[pool[:1]], P.X[pool[1:2]], alg.xl, alg.xu, rng)
            np.testing.assert_array_equal(got[c], x[0])
            c += 1
    assert c == len(pi) and rng.random() == after


@pytest.mark.parametrize("n", [0, 1, 2, 3, 20, 200, 1001])
def test_the_compiled_permutation_draws_numpys_permutation(n):
    # numba's own permutation swaps through 0-d array views (~36 ns a member); ours must draw the same numbers.
    values = np.arange(n, dtype=np.int64) * 7 + 3
    a, b = np.random.default_rng(n), np.random.default_rng(n)
    for _ in range(5):
        np.testing.assert_array_equal(ahead.permuted(a, values), b.permutation(values))
    assert a.random() == b.random()  # the generators agree afterwards
