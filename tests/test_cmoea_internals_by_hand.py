"""Two CMOEA rules on internal state built by hand: CMOES's stage-1 mating keys (spec §3: binary tournament on
(front, -crowding), §1.5) and MCCMO's combine-occasion test (spec §6: Q_j is flagged when its worst front is
strictly better than the best front of a flagged Q_i, or of A; touching ranges are not)."""

from __future__ import annotations

import numpy as np
import pytest
from pymoo.core.problem import Problem

from core.optimize.evolve import cmoes
from core.optimize.evolve.base import Arrays
from core.optimize.evolve.mccmo import MCCMO, Sub
from core.optimize.moea import problem_by_name

# CMOES ---------------------------------------------------------------------------------------------------------


def test_cmoes_stage1_tournament_prefers_the_lower_front_then_the_larger_crowding(monkeypatch):
    alg = cmoes.CMOES(pop_size=6)
    alg.setup(problem_by_name("mw3"), termination=("n_eval", 10**6), seed=1)
    alg.next()  # the initial populations
    alg.front = np.array([1, 0, 0, 1, 0, 2])
    alg.crowd = np.array([np.inf, 0.5, np.inf, 0.2, 0.1, 3.0])
    keys_seen = []
    real = cmoes.tournament

    def spy(keys, n, rng):
        keys_seen.append(tuple(np.array(k, dtype=float) for k in keys))
        return real(keys, n, rng)

    monkeypatch.setattr(cmoes, "tournament", spy)
    alg._stage1(alg.arrays, 6)
    keys = next(k for k in keys_seen if len(k) == 2)  # P1's (P2 mates on its SPEA2 fitness alone)
    best_first = sorted(range(6), key=lambda i: tuple(k[i] for k in keys))  # the lower key wins (§1.5)
    assert best_first == [2, 1, 4, 0, 3, 5]  # front 0 by crowding inf, 0.5, 0.1; front 1 by inf, 0.2; front 2


# MCCMO ---------------------------------------------------------------------------------------------------------


class Three(Problem):
    def __init__(self) -> None:
        super().__init__(n_var=2, n_obj=2, n_ieq_constr=3, xl=0.0, xu=10.0)

    def _evaluate(self, X, out, *args, **kwargs):
        out["F"], out["G"] = X.copy(), -np.ones((len(X), 3))


# Points on three anti-diagonal lines: x + y = 3 (front 0), 5 (front 1), 7 (front 2) of their union.
FRONT0 = [[0.0, 3.0], [1.0, 2.0], [2.0, 1.0], [3.0, 0.0]]  # fronts {0}
MIXED01 = [[0.5, 2.5], [2.5, 0.5], [1.5, 3.5], [3.5, 1.5]]  # fronts {0, 1}
MIXED12 = [[1.0, 4.0], [4.0, 1.0], [2.0, 5.0], [5.0, 2.0]]  # fronts {1, 2}


def arrays(F) -> Arrays:
    F = np.array(F)
    return Arrays(F.copy(), F, -np.ones((len(F), 3)), np.zeros(len(F)))  # every constraint satisfied


def mccmo_state(Q: list[Sub], A, upf: bool) -> MCCMO:
    alg = MCCMO(pop_size=4)
    alg.setup(Three(), termination=("n_eval", 10**6), seed=0)
    alg.xl, alg.xu = np.zeros(2), np.full(2, 10.0)
    alg.n_con, alg.Q, alg.arrays, alg.fit_a = 3, Q, arrays(A), np.zeros(4)
    alg.upf = alg.dupf = upf
    alg.reinit, alg.merges, alg.reinits = False, 0, 0
    return alg


def test_mccmo_flags_a_q_strictly_ahead_of_a_settled_one_and_not_one_that_touches_it():
    settled = Sub(arrays(MIXED12), np.zeros(4), (0,), dormant=False, stable=True)  # fronts 1..2
    touching = Sub(arrays(MIXED01), np.zeros(4), (1,), dormant=False)  # fronts 0..1: max 1 == min 1
    ahead = Sub(arrays(FRONT0), np.zeros(4), (2,), dormant=False)  # front 0: max 0 < min 1
    alg = mccmo_state([settled, touching, ahead], MIXED12, upf=False)
    alg._combine(5)
    # the settled one and the one ahead of it merge into one population under both their constraints
    assert alg.merges == 1 and [q.S for q in alg.Q] == [(0, 2), (1,)]
    assert [q.stable for q in alg.Q] == [False, False]


def test_mccmo_flags_a_q_strictly_ahead_of_the_archive_and_not_one_that_touches_it():
    touching = Sub(arrays(MIXED01), np.zeros(4), (0,), dormant=False)  # max front 1 == the archive's min 1
    ahead = Sub(arrays(FRONT0), np.zeros(4), (1,), dormant=False)  # max front 0 < 1
    alg = mccmo_state([touching, ahead], MIXED12, upf=True)
    alg._combine(5)
    assert [q.stable for q in alg.Q] == [False, True]
    assert alg.merges == 0 and len(alg.Q) == 2  # one flagged population has nobody to merge with


@pytest.mark.parametrize("upf", [False, True])
def test_mccmo_merges_nothing_when_no_front_range_is_strictly_ahead(upf):
    a = Sub(arrays(MIXED01), np.zeros(4), (0,), dormant=False, stable=not upf)
    b = Sub(arrays(MIXED12), np.zeros(4), (1,), dormant=False)
    alg = mccmo_state([a, b], MIXED12, upf=upf)
    alg._combine(5)
    assert alg.merges == 0 and [q.stable for q in alg.Q] == [not upf, False]
