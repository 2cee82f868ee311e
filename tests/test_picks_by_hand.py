"""Pick rules on a hand-made population, checked against indices worked out by hand: best per objective, the
k-th knee, a pick among the members the next stage accepts (indices into the whole population, not the
subset), pick_where, and the least-violation fallback (the pipeline tests compare a pick with the same code)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from core.optimize import decision
from core.optimize.lineage import choose, next_feasible
from core.optimize.problem import Constraint, ProblemSpec
from core.optimize.result import StageResult

sys.path.insert(0, str(Path(__file__).parent))
from test_optimize_results_json import small_result  # noqa: E402

# Ten members, two objectives. 0-4 are a convex front with its bulge at 2; 5 and 6 are dominated; 7 is the best
# f1 but violates; 8 the best f2 but with f2 only; 9 assembles nowhere.
F = np.array([[0.0, 10.0], [1.0, 5.0], [2.0, 2.0], [5.0, 1.0], [10.0, 0.5], [6.0, 6.0], [3.0, 9.0],
              [-1.0, 0.0], [12.0, 0.2], [np.inf, np.inf]])
CV = np.array([0, 0, 0, 0, 0, 0, 0, 3.0, 0, 9.0])
WIDTH = np.array([100.0, 250.0, 150.0, 160.0, 300.0, 100.0, 120.0, 100.0, 100.0, np.nan])


@pytest.fixture(scope="module")
def result() -> StageResult:
    r = small_result()
    assert r.pop == 10 and r.objectives == ("f1", "f2")
    metrics = {**r.metrics, "f1": F[:, 0], "f2": F[:, 1], "width": WIDTH,
               "violation": np.where(np.arange(10) == 9, 5.0, 0.0)}
    return dataclasses.replace(r, F=F, G=CV[:, None], cv=CV, metrics=metrics, shortlist=decision.shortlist(F, CV),
                               picked=None)


def test_best_per_objective_is_the_feasible_argmin_of_that_column(result: StageResult) -> None:
    assert result.choose("best:f1") == 0 and result.choose("best:f2") == 8
    assert result.choose("best:width") == 0  # a metric: the smallest feasible value, ties by index


def test_the_kth_knee_is_the_shortlists_kth(result: StageResult) -> None:
    knees = result.shortlist.knees
    assert knees[0] == 2 and len(knees) >= 2
    assert result.choose("knee") == 2 and result.choose("knee:1") == knees[1]
    assert result.choose("knee:99") == knees[-1]


def test_a_pick_among_the_next_stages_members_is_an_index_into_the_population(result: StageResult) -> None:
    nxt = ProblemSpec("next", None, ("f1", "f2"), (Constraint("width", upper=200.0),))  # type: ignore[arg-type]
    mask = next_feasible(result, nxt)
    assert np.flatnonzero(mask).tolist() == [0, 2, 3, 5, 6, 8]  # feasible here, width <= 200 there
    assert choose(result, "best:f1", mask) == 0 and choose(result, "best:f2", mask) == 8
    sub = [0, 2, 3, 5, 6, 8]
    assert choose(result, "knee", mask) == sub[decision.shortlist(F[sub], CV[sub]).knees[0]] == 2
    wide = np.zeros(10, dtype=bool)
    wide[[1, 4, 5]] = True  # f2 best among them: member 4, the subset's index 1
    assert choose(result, "best:f2", wide) == 4 and choose(result, "best:f1", wide) == 1


def test_pick_where_narrows_to_feasible_members_that_meet_it(result: StageResult) -> None:
    where = (Constraint("f2", upper=1.0),)  # 3, 4, 7 (infeasible) and 8
    assert choose(result, "best:f1", None, where) == 3
    # only the violating member 7 meets f1 <= -0.5: the limit is ignored, not used to pick a violating start
    assert choose(result, "best:f1", None, (Constraint("f1", upper=-0.5),)) == 0


def test_with_no_feasible_member_the_least_violation_that_assembles_starts_the_next_stage(
        result: StageResult) -> None:
    cv = np.array([4.0, 2.0, 3.0, 5.0, 6.0, 7.0, 8.0, 2.5, 9.0, 1.0])  # 9 violates least but does not assemble
    r = dataclasses.replace(result, cv=cv, G=cv[:, None], shortlist=decision.shortlist(F, cv))
    assert not r.feasible.any()
    assert choose(r, "knee") == 1 and choose(r, "best:f2") == 1
