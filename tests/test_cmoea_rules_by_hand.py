"""CMOEMT's, IMTCMO's and MOEA/D-CMT's individual rules (spec §2, §5, §7) on hand-built state: the defaults
tables, CMOEMT's push -> pull switch and epsilon at their boundaries, its generation counter, transfer switch and
budget, task 2's sequential replacement, which pools P1 and P3 select from; IMTCMO's AuxSel case by case; MOEA/D-CMT's
normalised violation, ideal points, task choice and rewards."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymoo.core.problem import Problem
from pymoo.optimize import minimize
from pymoo.termination.collection import TerminationCollection
from pymoo.termination.max_eval import MaximumFunctionCallTermination
from pymoo.termination.max_gen import MaximumGenerationTermination

from core.optimize.evolve import cmoemt, imtcmo, moead_cmt, spea2
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.cmoemt import CMOEMT
from core.optimize.evolve.cmoes import CMOES
from core.optimize.evolve.imtcmo import IMTCMO, aux_select
from core.optimize.evolve.moead import fmin_into
from core.optimize.evolve.moead_cmt import MOEADCMT
from core.optimize.evolve.weights import das_dennis
from core.optimize.moea import problem_by_name


def members(F, cv) -> Arrays:
    F = np.asarray(F, dtype=float)
    return Arrays(np.arange(len(F), dtype=float)[:, None], F, np.zeros((len(F), 1)), np.asarray(cv, dtype=float))


def test_the_defaults_are_the_specs():
    # spec §2 (CMOEMT), §5 (IMTCMO), §7 (MOEA/D-CMT) defaults tables
    assert (cmoemt.DELTA, cmoemt.NR, cmoemt.ROUNDS, cmoemt.WINDOW, cmoemt.CHANGE) == (0.9, 2, 5, 20, 0.1)
    assert (cmoemt.TAU, cmoemt.ALPHA, cmoemt.CP) == (0.05, 0.95, 2.0)
    assert (moead_cmt.DELTA, moead_cmt.NR, moead_cmt.RMP, moead_cmt.LEARN) == (0.9, 2, 0.2, 0.3)
    assert (moead_cmt.P_MIN, moead_cmt.S_OBJ, moead_cmt.THETA) == (0.1, 0.3, 5.0)
    assert imtcmo.F_SET.tolist() == [0.6, 0.8, 1.0] and imtcmo.CR_SET.tolist() == [0.1, 0.2, 1.0]
    assert (imtcmo.N_NEIGHBOURS, imtcmo.P_BEST, imtcmo.EPS_END) == (10, 0.1, math.exp(-6.0))


# CMOEMT ---------------------------------------------------------------------------------------------------------


def cmoemt_state(F, cv, z, gen, history=None) -> CMOEMT:
    """CMOEMT before ``_epsilon(gen)``: P2 as given, still pushing, Tc = 100; ``history`` (ideal, nadir) written
    19 generations back (else never written: zeros)."""
    alg = CMOEMT(pop_size=20)
    alg.P2 = members(F, cv)
    alg.z, alg.pull, alg.eps0, alg.eps, alg.Tc, alg.r = np.asarray(z, dtype=float), False, 0.0, 0.0, 100.0, math.inf
    alg.ideal, alg.nadir = {}, {}
    if history is not None:
        alg.ideal[gen - 19], alg.nadir[gen - 19] = (np.asarray(h, dtype=float) for h in history)
    return alg


def test_pull_starts_at_a_change_rate_of_exactly_0_1_with_eps0_the_largest_finite_violation():
    # ideal 10 -> 11 over the window: |11 - 10| / 10 = 0.1 exactly; nadir (the column max of P2) unchanged
    F, cv = [[11, 20], [20, 11], [15, 15], [12, 19]], [0.0, 3.0, 1.0, math.inf]
    alg = cmoemt_state(F, cv, [11, 11], 25, history=([10, 10], [20, 20]))
    alg._epsilon(25)
    assert alg.nadir[25].tolist() == [20.0, 20.0] and alg.ideal[25].tolist() == [11.0, 11.0]
    assert alg.r == 0.1 and alg.pull
    # eps0 = max CV(P2), the infinite one left out; then the same generation's pull update: rf = 1/4 < alpha
    assert alg.eps0 == 3.0 and alg.eps == pytest.approx(0.95 * 3.0)
    # a change of 0.1 and a bit stays in push
    alg = cmoemt_state(F, cv, [11.000001, 11], 25, history=([10, 10], [20, 20]))
    alg._epsilon(25)
    assert alg.r > 0.1 and not alg.pull and alg.eps == 0.0


def test_the_change_test_starts_at_generation_20():
    F, cv = [[0, 1], [1, 0]], [0.0, 2.0]
    alg = cmoemt_state(F, cv, [0, 0], 20, history=([0, 0], [1, 1]))  # generation 1 written: no change at all
    alg._epsilon(20)
    assert alg.r == 0.0 and alg.pull
    alg = cmoemt_state(F, cv, [0, 0], 19, history=([0, 0], [1, 1]))
    alg._epsilon(19)
    assert alg.r == math.inf and not alg.pull


@pytest.mark.parametrize(("cv", "schedule"), [
    ([0.0] * 19 + [2.0], True),  # rf = 19/20 = 0.95 = alpha: the schedule
    ([0.0] * 18 + [2.0, 2.0], False),  # 0.9 < alpha: shrink by (1 - tau)
    ([0.0, 1e-6, 5e-7] * 6 + [0.0, 0.0], True),  # a violation up to 1e-6 counts as feasible for rf
    ([0.0, 2e-6] * 10, False),
])
def test_pull_shrinks_below_alpha_feasible_and_follows_the_schedule_from_alpha(cv, schedule):
    F = [[float(i), 20.0 - i] for i in range(20)]
    alg = cmoemt_state(F, cv, [0, 0], 30)
    alg.pull, alg.eps0, alg.eps, alg.r = True, 2.0, 0.5, 0.0
    alg._epsilon(30)
    assert alg.eps == pytest.approx(2.0 * (1 - 30 / 100) ** 2 if schedule else 0.95 * 0.5)


def test_task_two_replaces_the_first_two_in_pool_order_and_moves_the_ideal_point():
    W = das_dennis(4, 2)
    P = members([[3, 3], [2, 4], [4, 2], [3.5, 3.5]], [0.0, 0.0, 0.0, 0.0])
    X, F, G, cv = (np.array(v) for v in (P.X, P.F, P.G, P.cv))
    z = np.array([1.0, 1.0])
    Y = Arrays(np.array([[9.0]]), np.array([[0.5, 0.8]]), np.zeros((1, 1)), np.array([0.0]))
    pool = np.array([3, 1, 0, 2], dtype=np.int64)
    stamps, none = np.zeros((1, 4), dtype=np.int64), np.full((1, 3), -1, dtype=np.int64)
    end = cmoemt._place(0, 1, pool, np.array([0, 4]), X, F, G, cv, W, z, 0.0, False, True, Y.X, Y.F, Y.G, Y.cv,
                        stamps, np.zeros(1, dtype=np.int64), none, none)
    assert end == 1
    assert z.tolist() == [0.5, 0.8]  # z = min(z, f(y)) first: the child is on it, so it beats every member
    assert X[:, 0].tolist() == [0.0, 9.0, 2.0, 9.0] and stamps[0].tolist() == [0, 1, 0, 1]  # nr = 2: 3 and 1
    # pull with eps 0.4: a child violating 0.5 beats a feasible member on objectives but may not replace it
    X, F, G, cv = (np.array(v) for v in (P.X, P.F, P.G, P.cv))
    Y = Arrays(Y.X, Y.F, Y.G, np.array([0.5]))
    cmoemt._place(0, 1, pool, np.array([0, 4]), X, F, G, cv, W, np.array([1.0, 1.0]), 0.4, True, True, Y.X, Y.F,
                  Y.G, Y.cv, np.zeros((1, 4), dtype=np.int64), np.zeros(1, dtype=np.int64), none, none)
    assert X[:, 0].tolist() == [0.0, 1.0, 2.0, 3.0]


def started(cls, problem="mw3", seed=1, **kw):
    p = problem_by_name(problem) if isinstance(problem, str) else problem
    alg = cls(**kw)
    alg.setup(p, termination=("n_eval", 10**6), seed=seed)
    alg.next()
    return alg


def test_task_two_places_with_the_current_stage_and_epsilon(monkeypatch):
    alg = started(CMOEMT, pop_size=20)
    alg.pull, alg.eps = True, 0.25
    seen = []
    original = cmoemt._place

    def spy(*args):
        seen.append((args[11], args[10]))  # pull, eps
        return original(*args)

    monkeypatch.setattr(cmoemt, "_place", spy)
    alg._task2()
    assert seen and set(seen) == {(True, 0.25)}


@pytest.mark.parametrize("variant", ["platemo", "author_repo"])
def test_task_two_replaces_in_place_only_in_platemos_variant(variant):
    # PlatEMO's: children replace P2's members as they are placed; the authors' repository's: task 2's children
    # leave P2 alone until SPEA2 under epsilon-relaxed CDP selects P2 from P2 and them (spec §2 pitfall 1)
    alg = started(CMOEMT, pop_size=20, variant=variant)
    before = alg.P2.X.copy()
    alg._task2()
    assert np.array_equal(alg.P2.X, before) == (variant == "author_repo")
    if variant == "author_repo":  # the generation's selection does replace it
        alg.next()
        assert not np.array_equal(alg.P2.X, before)


def test_generation_counter_transfer_switch_and_budget_on_a_short_run():
    # N = 20 at two objectives (20 weights): 3N = 60 initially, then 2N = 40 per generation; maxFE = 200.
    alg = CMOEMT(pop_size=20)
    minimize(problem_by_name("mw3"), alg, ("n_eval", 200), seed=1, copy_algorithm=False)
    rows = alg.trace
    assert alg.n == 20 and alg.max_fe == 200 and [r["n_eval"] for r in rows] == [60, 100, 140, 180, 220]
    # gen = ceil(FE / 2N) with FE as the generation starts (60, 100, 140, 180): 2, 3, 4, 5 (spec pitfall 4)
    assert sorted(alg.ideal) == [2, 3, 4, 5]
    # transfer from FE >= maxFE / 2 = 100, tested before the generation's evaluations
    assert [r["transfer"] for r in rows[1:]] == [0.0, 1.0, 1.0, 1.0]
    # an n_gen budget: the initial 3N and 2N for each generation after the first
    alg = CMOEMT(pop_size=20)
    minimize(problem_by_name("mw3"), alg, ("n_gen", 3), seed=1, copy_algorithm=False)
    assert alg.max_fe == 60 + 2 * 40 == alg.evaluator.n_eval


def test_the_budget_of_a_collection_is_the_first_to_end():
    alg = CMOEMT(pop_size=20)
    alg.termination = TerminationCollection(MaximumGenerationTermination(5), MaximumFunctionCallTermination(100))
    assert alg.budget(40, 60) == 100  # 5 generations would be 60 + 4 x 40 = 220
    alg.termination = TerminationCollection(MaximumGenerationTermination(5), MaximumFunctionCallTermination(300))
    assert alg.budget(40, 60) == 220


@pytest.mark.parametrize("transfer", [False, True])
def test_p1_and_p3_select_from_the_specs_pools_with_fitness_from_their_tournaments(monkeypatch, transfer):
    alg = started(CMOEMT, pop_size=20)
    alg.next()
    if transfer:
        alg.max_fe = 0  # FE >= maxFE / 2 from now on
    n, fit1, fit3 = alg.n, alg.fit1.copy(), alg.fit3.copy()
    p1F, p3F = alg.arrays.F.copy(), alg.p3.F.copy()
    selects, keys = [], []
    select, tournament = spea2.select, cmoemt.tournament

    def spy_select(F, k, cv=None, **kw):
        out = select(F, k, cv, **kw)
        selects.append((np.array(F), None if cv is None else np.array(cv), out[0]))
        return out

    def spy_tournament(k, size, rng):
        keys.append(k[0].copy())
        return tournament(k, size, rng)

    monkeypatch.setattr(spea2, "select", spy_select)
    monkeypatch.setattr(cmoemt, "tournament", spy_tournament)
    alg.next()
    assert len(keys) == 2 and keys[0].tolist() == fit1.tolist() and keys[1].tolist() == fit3.tolist()
    (F1, cv1, order1), (F3, cv3, _) = selects
    assert cv1 is not None and cv3 is None  # P1 under CDP, P3 ignoring constraints
    offspring = 2 * (n // 2) + 5 * (n // 5)
    if not transfer:  # own population and all offspring
        assert len(F1) == len(F3) == n + offspring
        assert F1[:n].tolist() == p1F.tolist() and F3[:n].tolist() == p3F.tolist()
        assert F1[n:].tolist() == F3[n:].tolist()
    else:  # P3's pool starts with the P1 just selected (spec pitfall 7)
        assert len(F1) == len(F3) == 3 * n + offspring
        assert F1[:n].tolist() == p1F.tolist() and F3[:n].tolist() == F1[order1].tolist()
        assert F3[n:].tolist() == F1[n:].tolist()


# IMTCMO ---------------------------------------------------------------------------------------------------------


def test_aux_select_counts_a_violation_equal_to_var_as_epsilon_feasible():
    order, _, n_feas = aux_select(np.array([[1.0, 1.0], [0.0, 0.0]]), np.array([0.5, 2.0]), 1, 0.5)
    assert order.tolist() == [0] and n_feas == 1


def test_aux_select_without_epsilon_feasible_members_is_spea2_under_cdp():
    # (0, 0) Pareto-dominates (1, 1) but violates more
    order, _, n_feas = aux_select(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([5.0, 2.0]), 1, 1.0)
    assert order.tolist() == [1] and n_feas == 0


def test_aux_select_ranks_epsilon_feasible_members_on_f_and_cv():
    # Two members at the same f, the second violating less (both within var): on [f, CV] it dominates the first.
    order, _, n_feas = aux_select(np.array([[1.0, 1.0], [1.0, 1.0]]), np.array([0.3, 0.0]), 2, 1.0)
    assert order.tolist() == [1, 0] and n_feas == 2
    # More than N epsilon-feasible: SPEA2 on [f, CV]; (0, 1) with cv 0 dominates its copy with cv 0.2 there
    order, _, n_feas = aux_select(np.array([[0.0, 1.0], [0.0, 1.0], [1.0, 0.0]]), np.array([0.0, 0.2, 0.0]), 2, 1.0)
    assert sorted(order.tolist()) == [0, 2] and n_feas == 2


def test_aux_select_fills_by_cdp_after_the_epsilon_feasible_ones_with_offset_fitness():
    # one epsilon-feasible member (alone: fitness 1/2); the filler is the smaller violation (cv 2), not the
    # Pareto-better (0, 0) with cv 5; its fitness within the two infeasible ones, 1/(sqrt 2 + 2) (k = 1), is
    # offset by the feasible ones' largest
    F = np.array([[3.0, 3.0], [0.0, 0.0], [1.0, 1.0]])
    order, fit, n_feas = aux_select(F, np.array([0.1, 5.0, 2.0]), 2, 0.5)
    assert order.tolist() == [0, 2] and n_feas == 1
    np.testing.assert_allclose(fit, [0.5, 0.5 + 1 / (math.sqrt(2) + 2)], rtol=1e-12)


def test_imtcmo_pools_ideal_points_and_initial_epsilon(monkeypatch):
    alg = started(IMTCMO, "mw3", 3, pop_size=20)
    p1, p2 = alg.arrays, alg.p2
    # VAR0: the largest violation over both initial populations (this seed's is P2's)
    assert p2.cv.max() > p1.cv.max() and alg.var0 == p2.cv.max()
    n, z1, z2 = 20, alg.z1.copy(), alg.z2.copy()
    seen = {}
    select, aux = spea2.select, imtcmo.aux_select

    def spy_select(F, k, cv=None, **kw):
        seen.setdefault("pool1", np.array(F))
        return select(F, k, cv, **kw)

    def spy_aux(F, cv, k, var, cuts=None):
        seen["pool2"] = np.array(F)
        return aux(F, cv, k, var, cuts)

    monkeypatch.setattr(spea2, "select", spy_select)
    monkeypatch.setattr(imtcmo, "aux_select", spy_aux)
    alg.next()
    pool1, pool2 = seen["pool1"], seen["pool2"]
    o1, o2 = pool1[n : 2 * n], pool1[2 * n :]
    assert pool1[:n].tolist() == p1.F.tolist() and pool2[:n].tolist() == p2.F.tolist()  # P1 u O1 u O2, P2 u O2 u O1
    assert pool2[n : 2 * n].tolist() == o2.tolist() and pool2[2 * n :].tolist() == o1.tolist()
    assert alg.z1.tolist() == np.minimum(z1, o1.min(axis=0)).tolist()  # each population's own children
    assert alg.z2.tolist() == np.minimum(z2, o2.min(axis=0)).tolist()


def test_current_to_pbest_never_takes_the_target_as_r1():
    # N = 3: A (0) and B (0.2) are the best two (pbest among them), M (0.5) the worst. M's child on a crossed site
    # is 0.5 + F (x_pb - 0.5 + x_r1 - x_r2), with r1, r2 = A, B: never 0.5. With r1 = M (the target) and pbest = r2
    # it would be 0.5 on every site: a copy of M in a sixth of the calls. A copy of M otherwise needs every site
    # crossed (CR 1) by A's or B's child with the right F and members: ~1/12 of the calls.
    d = 100
    X = np.repeat([[0.0], [0.2], [0.5]], d, axis=1)
    a = Arrays(X, np.zeros((3, 2)), np.zeros((3, 0)), np.zeros(3))
    fit, rng, copies = np.array([0.0, 1.0, 2.0]), np.random.default_rng(8), 0
    for _ in range(300):
        child = imtcmo.pbest_de(a, fit, 3, np.zeros(d), np.ones(d), rng)
        copies += int(((child == 0.5).sum(axis=1) >= d - 4).sum())  # the mutation moves ~1 site
    assert copies < 45  # ~25; ~75 if r1 could be the target


def test_neighbour_pairing_never_takes_the_parent_as_its_own_neighbour():
    # One-hot members (x_i = e_i): a child is e_i + F (e_a - e_b) on crossed sites, so its own variable stays 1
    # unless b = i (then 1 - F); only the mutation (1/d per variable) moves it otherwise. Self as a neighbour
    # (cosine 1, the most similar) would make b = i for a tenth of the children.
    N = 400
    rng = np.random.default_rng(9)
    a = Arrays(np.eye(N), rng.random((N, 2)) + 0.1, np.zeros((N, 0)), np.zeros(N))
    child = imtcmo.neighbour_de(a, np.zeros(2), N, np.zeros(N), np.ones(N), np.random.default_rng(10))
    assert (child.max(axis=1) < 0.99).mean() < 0.01  # ~0.1 % from the mutation; ~4 % with self allowed


class HalfUndefined(Problem):
    """Two objectives, the second undefined (NaN) where x3 > 0.7; records every batch it evaluates."""

    def __init__(self) -> None:
        super().__init__(n_var=3, n_obj=2, xl=0.0, xu=1.0)
        self.batches: list[np.ndarray] = []

    def _evaluate(self, X, out, *args, **kwargs):
        F = np.column_stack([X[:, 0], 1.0 - X[:, 0] + X[:, 1]])
        F[X[:, 2] > 0.7, 1] = np.nan
        self.batches.append(F)
        out["F"] = F


def test_imtcmo_ideal_points_skip_undefined_objectives():
    # z = min over the population and its own children so far, as MATLAB's min (NaN skipped): batch 0 is P1,
    # batch 1 P2, then each generation's O1 (first N rows) and O2
    p, n = HalfUndefined(), 20
    alg = IMTCMO(pop_size=n)
    minimize(p, alg, ("n_gen", 4), seed=1, copy_algorithm=False)
    own1 = np.vstack([p.batches[0]] + [b[:n] for b in p.batches[2:]])
    own2 = np.vstack([p.batches[1]] + [b[n:] for b in p.batches[2:]])
    assert np.isnan(own1[:, 1]).any() and np.isnan(own2[:, 1]).any()
    assert alg.z1.tolist() == np.nanmin(own1, axis=0).tolist()
    assert alg.z2.tolist() == np.nanmin(own2, axis=0).tolist()


@pytest.mark.parametrize("cls", [CMOEMT, MOEADCMT])
def test_initial_ideal_points_skip_undefined_objectives(cls):
    # a third of the random initial members have an undefined f2: z is the min over the others (MATLAB's min);
    # a NaN z would be taken over by the first child's f2 alone, whatever the population holds
    p = HalfUndefined()
    alg = started(cls, pop_size=20, problem=p)
    assert np.isnan(p.batches[1][:, 1]).any()
    if cls is CMOEMT:  # P1, P2, P3 evaluated in that order; z is task 2's
        assert alg.z.tolist() == np.nanmin(p.batches[1], axis=0).tolist()
    else:
        assert alg.z1.tolist() == np.nanmin(p.batches[0], axis=0).tolist()
        assert alg.z2.tolist() == np.nanmin(p.batches[1], axis=0).tolist()


def test_fmin_into_takes_the_defined_side():
    z = np.array([np.nan, 1.0, 2.0])
    fmin_into(z, np.array([0.5, np.nan, 1.5]))
    assert z.tolist() == [0.5, 1.0, 1.5]


# MOEA/D-CMT -----------------------------------------------------------------------------------------------------


def cmt_place(P1: Arrays, y: Arrays, pool, z1, cmin, s_cv, P2: Arrays | None = None, z2=None):
    n, m = P1.F.shape
    P2 = P1 if P2 is None else P2
    A = [np.array(v) for v in (P1.X, P1.F, P1.G, P1.cv)]
    B = [np.array(v) for v in (P2.X, P2.F, P2.G, P2.cv)]
    z1 = np.asarray(z1, dtype=float).copy()
    z2 = z1.copy() if z2 is None else np.asarray(z2, dtype=float).copy()
    cmin_a, reps = np.array([cmin], dtype=float), np.zeros(2, dtype=np.int64)
    none = np.full((1, 3), -1, dtype=np.int64)
    pool = np.asarray(pool, dtype=np.int64)
    moead_cmt._place(0, 1, pool, np.array([0, len(pool)]), *A, *B, np.ones((n, m)), z1, z2, cmin_a, float(s_cv),
                     1.0 if m == 1 else np.nan, y.X, y.F, y.G, y.cv, np.zeros((2, n), dtype=np.int64),
                     np.zeros(1, dtype=np.int64), none, none, reps)
    return A, B, z1, z2, float(cmin_a[0]), reps


def test_moead_cmt_normalises_violations_by_a_range_that_includes_the_child():
    # One objective, w = 1, z1 = 0: g_old = 1.4, g_new = 1.0, dg = 0.4. Violations: member 1, child 3, Cmin 0,
    # Cmax = max over P1 and the child = 3: dc = 1/3 - 3/3 = -2/3. With s_obj 0.3 and s_cv 1 the child wins iff
    # dg / 0.3 >= -dc (the logistic's odds): 1.33 >= 0.67, yes. (Cmax from P1 alone, 1, would give dc = -2: no.)
    P1 = members([[1.4], [5.0]], [1.0, 0.0])
    y = Arrays(np.array([[7.0]]), np.array([[1.0]]), np.zeros((1, 1)), np.array([3.0]))
    A, _, _, _, cmin, reps = cmt_place(P1, y, [0], [0.0], 0.0, 1.0, P2=members([[0.0], [0.0]], [0.0, 0.0]))
    assert reps[0] == 1 and A[0][:, 0].tolist() == [7.0, 1.0] and cmin == 0.0
    # a child that violates less than any so far lowers Cmin
    y = Arrays(np.array([[7.0]]), np.array([[9.0]]), np.zeros((1, 1)), np.array([0.5]))
    *_, cmin, _ = cmt_place(members([[1.0], [2.0]], [1.0, 2.0]), y, [0], [0.0], 1.0, 1.0)
    assert cmin == 0.5


def test_moead_cmt_moves_both_ideal_points_with_every_child():
    P1 = members([[2.0, 2.0], [3.0, 1.0]], [0.0, 0.0])
    y = Arrays(np.array([[7.0]]), np.array([[0.5, 4.0]]), np.zeros((1, 1)), np.array([0.0]))
    _, _, z1, z2, _, _ = cmt_place(P1, y, [0, 1], [1.0, 1.0], 0.0, 1.0, z2=[2.0, 0.5])
    assert z1.tolist() == [0.5, 1.0] and z2.tolist() == [0.5, 0.5]


def test_moead_cmt_takes_the_drawn_task_and_rewards_it(monkeypatch):
    # With task 1 certain (p = [1, 0]) every generation reproduces by task 1 and only its reward grows, by the
    # children entering the archive over N each generation.
    monkeypatch.setattr(moead_cmt, "task_probabilities", lambda rwd, fe, max_fe: np.array([1.0, 0.0]))
    alg = MOEADCMT(pop_size=20)
    minimize(problem_by_name("mw3"), alg, ("n_gen", 6), seed=2, copy_algorithm=False)
    rows = alg.trace[1:]
    assert {r["task"] for r in rows} == {1.0}
    assert alg.rwd[1] == 0.0 and sum(r["from_children"] for r in rows) > 0
    assert alg.rwd[0] == pytest.approx(sum(r["from_children"] for r in rows) / 20)
    monkeypatch.setattr(moead_cmt, "task_probabilities", lambda rwd, fe, max_fe: np.array([0.0, 1.0]))
    alg = MOEADCMT(pop_size=20)
    minimize(problem_by_name("mw3"), alg, ("n_gen", 3), seed=2, copy_algorithm=False)
    assert {r["task"] for r in alg.trace[1:]} == {2.0} and alg.rwd[0] == 0.0


def test_imtcmo_s_epsilon_ends_at_0_past_its_budget_and_ignores_an_infinite_violation():
    # EMO rehearsal (session 33): under a time or pymoo's default termination X passed 1 and ε read
    # (3.4e15+3.8e15j); one member with an infinite violation made VAR0 inf, then ε NaN.
    p = problem_by_name("mw3")
    alg = IMTCMO(pop_size=20)
    r = minimize(p, alg, ("n_gen", 4), seed=1)
    a = r.algorithm
    var0 = a.var0
    assert np.isfinite(var0) and var0 > 0
    a.x = 1.7  # past the budget the schedule was made for
    assert a.epsilon() == 0.0 and isinstance(a.epsilon(), float)

    class OneUndefined(Problem):  # MW3 with the first member's violation undefined
        def __init__(self) -> None:
            super().__init__(n_var=p.n_var, n_obj=2, n_ieq_constr=p.n_ieq_constr, xl=p.xl, xu=p.xu)
            self.calls = 0

        def _evaluate(self, x, out, *args, **kwargs):
            o = p.evaluate(x, return_as_dictionary=True)
            G = np.asarray(o["G"], dtype=float).reshape(len(x), -1)
            if self.calls == 0:
                G[0] = np.inf
            self.calls += 1
            out["F"], out["G"] = o["F"], G

    b = minimize(OneUndefined(), IMTCMO(pop_size=20), ("n_gen", 4), seed=1).algorithm
    assert b.var0 == var0  # the same sample, the largest finite violation: the same level
    assert all(np.isfinite(row["eps"]) for row in b.trace)


class NaNConstraints(Problem):
    """MW3 whose members with x0 < 0.1 have undefined constraints (pymoo's CTP2-5 give NaN outside their domain)."""

    def __init__(self) -> None:
        self.p = problem_by_name("mw3")
        super().__init__(n_var=self.p.n_var, n_obj=2, n_ieq_constr=self.p.n_ieq_constr, xl=self.p.xl, xu=self.p.xu)
        self.undefined = 0

    def _evaluate(self, x, out, *args, **kwargs):
        o = self.p.evaluate(x, return_as_dictionary=True)
        G = np.asarray(o["G"], dtype=float).reshape(len(x), -1)
        G[x[:, 0] < 0.1] = np.nan
        self.undefined += int((x[:, 0] < 0.1).sum())
        out["F"], out["G"] = o["F"], G


def test_cmoes_epsilon_starts_at_the_largest_finite_violation():
    # EMO rehearsal (session 33, F16/F17): one undefined member made CMOES's largest violation +inf, so its
    # epsilon was inf (every member epsilon-feasible) until tau = 1, where inf x 0 is NaN
    alg, problem = CMOES(pop_size=20), NaNConstraints()
    minimize(problem, alg, ("n_gen", 40), seed=1, copy_algorithm=False)
    assert problem.undefined > 0
    rows = alg.trace
    assert all(np.isfinite(r["max_cv"]) and r["max_cv"] > 0 for r in rows)
    assert all(np.isfinite(r["eps"]) for r in rows if r["stage"] == 2.0) and rows[-1]["stage"] == 2.0
