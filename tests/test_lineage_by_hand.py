"""Which members the next stage accepts, and pick_where against that mask, on a hand-made population."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from core.optimize import decision
from core.optimize.lineage import choose, next_feasible, unmet_by
from core.optimize.problem import Constraint, ProblemSpec
from core.optimize.result import StageResult

sys.path.insert(0, str(Path(__file__).parent))
from test_optimize_results_json import small_result  # noqa: E402

# Six members, two objectives, all feasible but 5. Front: 0 (best f1) .. 3 (best f2); 4 is dominated.
F = np.array([[0.0, 10.0], [1.0, 5.0], [2.0, 2.0], [5.0, 1.0], [6.0, 6.0], [-1.0, -1.0]])
CV = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 2.0])
# The next stage's limit is width <= 200: member 1 sits exactly on it, member 2 cannot be measured (NaN).
WIDTH = np.array([100.0, 200.0, np.nan, 250.0, 150.0, 100.0])


@pytest.fixture(scope="module")
def result() -> StageResult:
    r = small_result()
    idx = np.arange(6)
    metrics = {"f1": F[:, 0], "f2": F[:, 1], "width": WIDTH, "violation": np.zeros(6)}
    return dataclasses.replace(r, X=r.X[idx % r.pop], F=F, G=CV[:, None], cv=CV, metrics=metrics,
                               shortlist=decision.shortlist(F, CV), picked=None)


def test_the_next_stage_accepts_a_member_on_its_limit_and_refuses_an_unmeasured_one(result: StageResult) -> None:
    nxt = ProblemSpec("next", None, ("f1", "f2"), (Constraint("width", upper=200.0),))  # type: ignore[arg-type]
    assert np.flatnonzero(next_feasible(result, nxt)).tolist() == [0, 1, 4]
    # Without a next stage, the members feasible here.
    assert np.flatnonzero(next_feasible(result, None)).tolist() == [0, 1, 2, 3, 4]


def test_a_member_s_misses_in_words_are_the_mask_s(result: StageResult) -> None:
    # Another stage's limits: width <= 200 (1 on it, 2 unmeasured, 3 over), f1 >= 1, a metric this stage did not
    # measure (not judged) and the assembly measure (a feasible member assembles: not judged either).
    cons = (Constraint("width", upper=200.0), Constraint("f1", lower=1.0), Constraint("h_s", upper=1.0),
            Constraint("violation", upper=-1.0))
    words = [unmet_by(result, i, cons) for i in range(6)]
    assert words == [["f1 0 < 1"], [], ["width nan > 200"], ["width 250 > 200"], [], ["f1 -1 < 1"]]
    # By the name the stage gives the metric (rehearsal 5 read "crank2 48.4 > 0" where the stage said "Eq. 29 ...").
    assert unmet_by(result, 3, cons, {"width": "path width (mm)"}) == ["path width (mm) 250 > 200"]
    nxt = ProblemSpec("next", None, ("f1", "f2"), cons)  # type: ignore[arg-type]
    ok = next_feasible(result, nxt)
    assert [bool(ok[i]) for i in range(6)] == [not w and bool(result.feasible[i]) for i, w in enumerate(words)]


def test_pick_where_beats_the_next_stage_mask_when_they_share_no_member(result: StageResult) -> None:
    mask = np.array([True, True, False, False, False, False])  # what the next stage would accept
    where = (Constraint("f2", upper=2.0),)  # met by 2 and 3 (and 5, which violates)
    # No member is in both: the pick follows pick_where (best f1 among 2 and 3), not the mask (member 0).
    assert choose(result, "best:f1", mask, where) == 2
    # With a member in both, that one.
    mask[3] = True
    assert choose(result, "best:f1", mask, where) == 3


def test_the_kth_knee_among_the_mask(result: StageResult) -> None:
    # Among members 0-3 the knees are 2 (the bulge of the front) then 1; k past the end clamps to the last.
    mask = np.array([True, True, True, True, False, False])
    assert [choose(result, r, mask) for r in ("knee", "knee:1", "knee:9")] == [2, 1, 1]


STAGE3 = {"name": "subtask3", "box": "subtask3", "n_gen": 1,
          "options": {"f1_max": "start+0.5", "h_s_max": "start*1.05", "I_max": 30.0}}


def test_relative_limits_hold_the_start_or_fall_back_to_the_papers_thresholds() -> None:
    from core.formats.config import parse_config
    from core.kinematics.design import Design
    from core.kinematics.presets import get
    from core.optimize.lineage import resolved_spec
    from core.optimize.problem import make_problem

    cfg = parse_config({"name": "x", "preset": "stephenson1/X1", "n_samples": 72,
                        "algorithm": {"name": "nsga2", "pop_size": 8}, "stages": [STAGE3]})
    x1 = get("stephenson1/X1").design()
    start = make_problem("subtask3", n_samples=72).evaluate_metrics(x1)
    upper = {c.metric: c.upper for c in resolved_spec(cfg.stages[0], x1, 1).problem.constraints}
    assert upper["f1"] == pytest.approx(start["f1"][0] + 0.5) and upper["h_s"] == pytest.approx(start["h_s"][0] * 1.05)
    assert upper["I"] == 30.0
    # A start that does not assemble (crank r1 = 500 mm) has no f1 or h_s to be relative to: Eqs. 22-23's 6 and 6.5.
    p = np.array(x1.params, dtype=np.float64).reshape(-1)
    p[list(x1.mechanism.param_names).index("r1")] = 500.0
    bad = Design(x1.mechanism, p[None], x1.output)
    assert make_problem("subtask3", n_samples=72).evaluate_metrics(bad)["violation"][0] > 0
    upper = {c.metric: c.upper for c in resolved_spec(cfg.stages[0], bad, 1).problem.constraints}
    assert (upper["f1"], upper["h_s"], upper["I"]) == (6.0, 6.5, 30.0)


class _Stage:
    def __init__(self, res: StageResult) -> None:
        self.res = res

    def run(self, cancel: object = None) -> StageResult:
        return self.res


class _Pipe:
    """A pipeline whose stage returns a hand-made result (run_stage's own logic is what is tested)."""

    def __init__(self, res: StageResult) -> None:
        self.res, self.recorded = res, {}

    def parent(self, k: int, pick: int | None) -> tuple[object, None]:
        from core.kinematics.presets import get

        return get("stephenson1/X1").design(), None

    def stage(self, k: int, pick: int | None, spec: object = None, callback: object = None) -> _Stage:
        return _Stage(self.res)

    def record(self, k: int, res: StageResult) -> None:
        self.recorded[k] = res


def test_a_stopped_stage_picks_among_the_members_that_met_its_thresholds_even_against_the_next_stage() -> None:
    from core.formats.config import parse_config
    from core.optimize.lineage import run_stage

    cfg = parse_config({"name": "x", "preset": "stephenson1/X1", "n_samples": 72,
                        "algorithm": {"name": "nsga2", "pop_size": 8},
                        "stages": [{"name": "subtask2", "box": "subtask2", "n_gen": 1, "pick": "best:h_s",
                                    "stop_below": [2.0, 2.0]},
                                   {"name": "subtask3", "box": "subtask3", "n_gen": 1, "options": {"I_max": 1.5}}]})
    # (h_s, I); the stage stopped below (2, 2). A is the only member the next stage (I <= 1.5) accepts but it did
    # not meet the thresholds; B meets them with I exactly 2 (met: <=) and beats C on h_s; D met nothing.
    F4 = np.array([[3.0, 1.0], [1.0, 2.0], [1.5, 1.9], [0.2, 9.0]])
    r = small_result()
    res = dataclasses.replace(r, X=r.X[:4], objectives=("h_s", "I"), F=F4, G=np.zeros((4, 1)), cv=np.zeros(4),
                              metrics={"h_s": F4[:, 0], "I": F4[:, 1], "violation": np.zeros(4)},
                              shortlist=decision.shortlist(F4, np.zeros(4)), picked=None, status="stopped")
    pipe = _Pipe(res)
    out = run_stage(cfg, pipe, 0, None, 1, None, None)  # type: ignore[arg-type]
    assert out.picked == 1 and pipe.recorded[0].picked == 1
