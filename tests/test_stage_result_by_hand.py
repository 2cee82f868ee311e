"""A stage result's rules on a hand-made population: unmet constraints in words, pick bounds, knee clamping,
best-by-metric, and the parent pick kept through JSON."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from core.optimize import decision
from core.optimize.result import StageResult, best_metric

sys.path.insert(0, str(Path(__file__).parent))
from test_optimize_results_json import small_result  # noqa: E402

F = np.array([[0.0, 10.0], [1.0, 5.0], [2.0, 2.0], [5.0, 1.0], [10.0, 0.5]])
CONS = ("violation<=0.0", "h_s<=6.5", "S>=40.0", "order")
# Member 0 meets everything; 1 misses h_s; 2 misses S; 3 has order 0.25; 4 does not assemble. A G of exactly 0
# (member 0's h_s on its limit) is met.
G = np.array([[0.0, 0.0, -1.0, -0.1],
              [0.0, 1.5, -1.0, -0.1],
              [0.0, -0.5, 2.0, -0.1],
              [0.0, -0.5, -1.0, 0.25],
              [7.0, 0.0, 0.0, 0.0]])


@pytest.fixture(scope="module")
def result() -> StageResult:
    r = small_result()
    idx = np.arange(5)
    cv = np.maximum(G, 0.0).sum(axis=1)
    metrics = {"h_s": np.array([6.5, 8.0, 6.0, 6.0, 6.5]), "S": np.array([41.0, 41.0, 38.0, 41.0, 40.0]),
               "width": np.array([3.0, 1.0, 2.0, 0.5, np.nan])}
    return dataclasses.replace(r, X=r.X[idx % r.pop], F=F, G=G, cv=cv, constraints=CONS, metrics=metrics,
                               shortlist=decision.shortlist(F, cv), picked=None)


def test_unmet_constraints_in_words(result: StageResult) -> None:
    assert result.unmet(0) == []
    assert result.unmet(1) == ["h_s 8 > 6.5"]
    assert result.unmet(2) == ["S 38 < 40"]
    assert result.unmet(3) == ["order violated by 0.25"]
    assert result.unmet(4) == ["does not assemble"]


def test_a_recorded_pick_must_be_a_member(result: StageResult) -> None:
    assert dataclasses.replace(result, picked=4).picked == 4
    with pytest.raises(ValueError, match="out of range"):
        dataclasses.replace(result, picked=5)


def test_a_negative_knee_index_clamps_to_the_first(result: StageResult) -> None:
    r = dataclasses.replace(result, shortlist=dataclasses.replace(result.shortlist, knees=(2, 1)))
    assert r.choose("knee:-1") == 2 and r.choose("knee:1") == 1 and r.choose("knee:5") == 1


def test_best_metric_is_the_smallest_finite_value_among_the_mask() -> None:
    v = np.array([3.0, 1.0, np.nan, 0.5, 1.0])
    assert best_metric(v, np.ones(5, dtype=bool)) == 3
    assert best_metric(v, np.array([True, True, True, False, True])) == 1  # ties: the lower index
    assert best_metric(v, np.array([False, False, True, False, False])) is None


def test_the_parent_pick_survives_json(result: StageResult) -> None:
    r = dataclasses.replace(result, parent_pick=7, picked=2)
    back = StageResult.from_json(r.to_json())
    assert back.parent_pick == 7 and back.picked == 2


def test_best_of_a_metric_that_is_no_objective_is_taken_on_the_front() -> None:
    """``best:S`` took the smallest S over the whole population once, a member another beat on both objectives
    (rehearsal 3: h_s and I four times smaller, S 0.001 points larger); the paper's X_i lie on the front. Off the
    front only when no front member is a candidate (a pick_where or next-stage mask that excludes them all): then on
    the candidates' own front (review of session 28: it took the smallest S of all candidates, a dominated one)."""
    from core.optimize.lineage import choose

    F2 = np.array([[1.0, 1.0], [2.0, 2.0], [0.5, 3.0], [3.0, 0.2]])
    cv = np.zeros(4)
    r = dataclasses.replace(small_result(), X=small_result().X[np.arange(4) % small_result().pop], F=F2,
                            G=np.zeros((4, 1)), cv=cv, constraints=("violation<=0.0",), picked=None,
                            metrics={"S": np.array([5.0, 1.0, 3.0, 4.0]), "I": np.array([1.0, 0.1, 9.0, 9.0])},
                            shortlist=decision.shortlist(F2, cv))
    assert set(r.front) == {0, 2, 3}  # member 1 is dominated by member 0
    assert r.choose("best:S") == 2  # the smallest S on the front, not member 1's 1.0
    assert choose(r, "best:S", mask=np.array([True, True, True, True])) == 2
    assert choose(r, "best:S", mask=np.array([True, True, False, True])) == 3
    assert choose(r, "best:S", mask=np.array([False, True, False, False])) == 1  # no front member to take
    # pick_where I <= 1: front member 0 meets it, so it is preferred to the dominated member 1 with a smaller S
    from core.optimize.problem import Constraint

    assert choose(r, "best:S", where=(Constraint("I", upper=1.0),), mask=np.array([True, True, False, True])) == 0


def test_best_of_a_metric_off_the_whole_front_is_taken_on_the_candidates_own_front() -> None:
    """0 is the whole front (and misses I <= 50); of the candidates 1 and 2, 2 beats 1 on both objectives, so
    ``best:S`` takes 2 though 1 has the smaller S, as the knee rule does on the same candidates."""
    from core.optimize.lineage import choose
    from core.optimize.problem import Constraint

    F2 = np.array([[0.0, 0.0], [3.0, 3.0], [2.0, 2.0], [1.0, 4.0]])
    cv = np.zeros(4)
    base = small_result()
    r = dataclasses.replace(base, X=base.X[np.arange(4) % base.pop], F=F2, G=np.zeros((4, 1)), cv=cv,
                            constraints=("violation<=0.0",), picked=None,
                            metrics={"S": np.array([5.0, 1.0, 1.5, 2.0]), "I": np.array([99.0, 1.0, 1.0, 1.0])},
                            shortlist=decision.shortlist(F2, cv))
    assert r.front == (0,)
    where = (Constraint("I", upper=50.0),)
    assert choose(r, "best:S", where=where) == 2  # the candidates' front is {2, 3}: S 1.5 and 2.0
    assert choose(r, "knee", where=where) in (2, 3)
    assert choose(r, "best:S", mask=np.array([False, True, False, False])) == 1  # a lone candidate is its front
