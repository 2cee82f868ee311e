"""Multi-start blocks: chains with offset seeds, the winner by the select rule, picks by any metric, JSON."""

from __future__ import annotations

import copy
import json
import math
import threading
from typing import Any

import numpy as np
import pytest

from core.formats.config import parse_config
from core.optimize.lineage import choose, stage_pick
from core.optimize.multistart import (
    SEED_STRIDE,
    Chain,
    MultiStart,
    Screen,
    Starts,
    rank_chains,
    select_chain,
    shortfalls,
)
from core.optimize.problem import Constraint
from core.optimize.result import dumps, encode
from core.optimize.run import DesignRun, run_design

CONFIG: dict[str, Any] = {
    "name": "tiny multi-start",
    "preset": "stephenson1/X0",
    "seed": 5,
    "n_samples": 72,
    "algorithm": {"name": "nsga2", "pop_size": 12},
    "stages": [
        {"name": "subtask1", "box": "subtask1", "n_gen": 3, "pick": "best:f1",
         "starts": {"n": 3, "until": "subtask2", "select": "best:S", "where": {"I_max": 1e6}}},
        {"name": "subtask2", "box": "subtask2", "n_gen": 2, "pick": "best:h_s",
         "options": {"f1_max": "start+1.0", "place": "extent"}},
        {"name": "subtask3", "box": "subtask3", "n_gen": 2, "pick": "best:S", "pick_where": {"I_max": 50.0},
         "options": {"f1_max": "start+0.2", "h_s_max": "start*1.05", "I_max": "start+5"}},
    ],
}


def without_starts(cfg: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(cfg)
    for s in out["stages"]:
        s.pop("starts", None)
    return out


@pytest.fixture(scope="module")
def run() -> DesignRun:
    return run_design(parse_config(CONFIG))


def test_every_chain_runs_the_block_with_offset_seeds_from_the_same_start(run: DesignRun) -> None:
    (block,) = run.multistart
    assert (block.first, block.last, block.stages) == (0, 1, ("subtask1", "subtask2"))
    assert [c.index for c in block.chains] == [0, 1, 2]
    for c in block.chains:
        assert c.seeds == (5 + SEED_STRIDE * c.index, 6 + SEED_STRIDE * c.index)
        assert c.status == "complete" and len(c.picks) == 2 and all(p is not None for p in c.picks)
    # Other seeds, other searches: the chains do not all end at the same design.
    assert len({tuple(c.params[-1].values()) for c in block.chains}) > 1
    # The pipeline holds the winner's results, with the winner's seeds and picks.
    won = block.chains[block.chosen]
    s1, s2, s3 = run.results
    assert (s1.seed, s2.seed, s3.seed) == (*won.seeds, 7)
    assert (s1.picked, s2.picked) == won.picks
    assert s2.parent_pick == s1.picked and s3.parent_pick == s2.picked
    assert won.params[-1] == s2.named(s2.picked)
    assert won.metrics[-1]["S"] == s2.metrics["S"][s2.picked]


def test_the_winner_is_the_best_chain_by_the_select_rule(run: DesignRun) -> None:
    (block,) = run.multistart
    ok = [c for c in block.chains if c.feasible]
    assert block.chains[block.chosen].last["S"] == min(c.last["S"] for c in ok)
    assert block.chosen == select_chain([c.last for c in block.chains], [c.feasible for c in block.chains],
                                        "best:S", (Constraint("I", upper=1e6),))


def test_chain_zero_is_the_single_start_run(run: DesignRun) -> None:
    single = run_design(parse_config(without_starts(CONFIG)))
    chain0 = run.multistart[0].chains[0]
    assert [r.picked for r in single.results[:2]] == list(chain0.picks)
    assert single.results[1].named(single.results[1].picked) == chain0.params[-1]
    assert single.multistart == ()


def test_one_start_gives_the_same_result_as_none() -> None:
    cfg = copy.deepcopy(CONFIG)
    cfg["stages"][0]["starts"]["n"] = 1
    one = run_design(parse_config(cfg))
    none = run_design(parse_config(without_starts(CONFIG)))
    assert [r.picked for r in one.results] == [r.picked for r in none.results]
    for a, b in zip(one.results, none.results, strict=True):
        np.testing.assert_array_equal(a.X, b.X)
    assert len(one.multistart) == 1 and one.multistart[0].chosen == 0


def test_same_seed_gives_the_same_chains_and_winner(run: DesignRun) -> None:
    again = run_design(parse_config(CONFIG))
    a, b = again.multistart[0], run.multistart[0]
    assert a.chosen == b.chosen
    for ca, cb in zip(a.chains, b.chains, strict=True):
        assert (ca.seeds, ca.picks, ca.params) == (cb.seeds, cb.picks, cb.params)
        assert encode(ca.metrics) == encode(cb.metrics)
    for ra, rb in zip(again.results, run.results, strict=True):
        np.testing.assert_array_equal(ra.X, rb.X)
        assert ra.picked == rb.picked


def test_json_round_trip_keeps_the_multi_start_record(run: DesignRun) -> None:
    d = json.loads(dumps(run.to_dict()))
    (saved,) = d["multistart"]
    back = MultiStart.from_dict(saved)
    assert dumps(back.to_dict()) == dumps(run.multistart[0].to_dict())
    assert back.starts == run.multistart[0].starts
    assert back.chosen == run.multistart[0].chosen
    assert saved["starts"] == {"n": 3, "until": "subtask2", "select": "best:S", "where": {"I_max": 1e6}}
    assert d["rows"][0]["stage"] == "subtask3"


def test_reported_time_counts_the_losing_chains(run: DesignRun) -> None:
    (block,) = run.multistart
    lineage = sum(r.timings["total"] for r in run.results)
    assert run.compute_time == pytest.approx(lineage + sum(c.time for c in block.chains if c.index != block.chosen))
    # Evaluations are counted the same way, every chain's (clm compare's column).
    assert all(c.evals is not None and c.evals > 0 for c in block.chains)
    spent = sum(r.n_evals for r in run.results) + sum(c.evals or 0 for c in block.chains if c.index != block.chosen)
    assert run.compute_evals == spent and run.rows()[0]["evals"] == spent
    assert Chain.from_dict({**block.chains[0].to_dict(), "evals": None}).evals is None  # an older result
    assert run.rows()[0]["time"] == pytest.approx(run.compute_time)


def test_cancelling_inside_a_chain_stops_the_run_with_a_partial_record() -> None:
    cancel = threading.Event()

    def cb(p) -> None:  # type: ignore[no-untyped-def]
        if p.stage == "subtask1" and p.generation == 2 and seen.count("subtask1") >= 4:
            cancel.set()
        seen.append(p.stage)

    seen: list[str] = []
    out = run_design(parse_config({**CONFIG, "workers": 1}), callback=cb, cancel=cancel)
    assert out.status == "cancelled"
    (block,) = out.multistart
    assert [c.status for c in block.chains] == ["complete", "cancelled"]
    assert block.chains[1].picks == (None,)
    # The chain that finished is kept, with its picks, not the one stopped half-way.
    assert block.chosen == 0 and [r.status for r in out.results] == ["complete", "complete"]
    assert [r.picked for r in out.results] == list(block.chains[0].picks)
    json.loads(dumps(out.to_dict()))  # still writable


def test_cancelling_before_any_chain_completes_keeps_the_first_cancelled_chain() -> None:
    cancel = threading.Event()

    def cb(p) -> None:  # type: ignore[no-untyped-def]
        if p.stage == "subtask1" and p.generation == 2:
            cancel.set()

    config = parse_config({**CONFIG, "workers": 1})
    out = run_design(config, callback=cb, cancel=cancel)
    (block,) = out.multistart
    assert [c.status for c in block.chains] == ["cancelled"]
    assert block.chosen == 0 and [r.status for r in out.results] == ["cancelled"]
    # Its stage is picked by the stage's rule among the population it reached, as a single chain's run is (QA,
    # session 36: a stopped multi-start run kept no design to evaluate or export, even after 237 generations).
    (r,) = out.results
    assert r.picked is not None and r.picked == stage_pick(config, 0, r)
    assert block.chains[0].picks == (r.picked,) and block.chains[0].metrics[0]["f1"] == float(r.F[r.picked, 0])


def test_cancelling_keeps_the_best_of_the_completed_chains() -> None:
    cfg = copy.deepcopy(CONFIG)
    cfg["stages"][0]["starts"]["n"] = 4
    full = run_design(parse_config({**cfg, "workers": 1}))
    cancel = threading.Event()

    def cb(p) -> None:  # type: ignore[no-untyped-def]
        if p.stage == "subtask1" and p.chain == 3:
            cancel.set()

    out = run_design(parse_config({**cfg, "workers": 1}), callback=cb, cancel=cancel)
    (block,), (ref,) = out.multistart, full.multistart
    assert [c.status for c in block.chains] == ["complete"] * 3 + ["cancelled"]
    done = block.chains[:3]
    best = select_chain([c.last for c in done], [c.feasible for c in done], "best:S", block.starts.where)
    assert block.chosen == best
    assert out.results[-1].picked == ref.chains[best].picks[-1]  # the same chain as in the run not stopped


def test_a_screen_sends_only_the_best_chains_on() -> None:
    cfg = copy.deepcopy(CONFIG)
    cfg["stages"][0]["starts"] = {"n": 4, "until": "subtask2", "select": "best:S",
                                  "screen": {"after": "subtask1", "keep": 2, "by": "best:f1"}}
    out = run_design(parse_config(cfg))
    (block,) = out.multistart
    assert block.starts.screen == Screen("subtask1", 2, "best:f1")
    done = [c for c in block.chains if c.status == "complete"]
    dropped = [c for c in block.chains if c.status == "dropped"]
    assert len(done) == 2 and len(dropped) == 2
    assert all(len(c.picks) == 2 for c in done) and all(len(c.picks) == 1 for c in dropped)
    assert not any(c.feasible for c in dropped)
    # The kept chains are the two with the smallest f1 at subtask 1 (feasible first).
    at1 = [c.metrics[0] for c in block.chains]
    kept = rank_chains(at1, [True] * 4, "best:f1")[:2]
    assert sorted(c.index for c in done) == sorted(kept)
    assert block.chosen in kept
    # The dropped chains' time still counts.
    assert out.compute_time == pytest.approx(sum(r.timings["total"] for r in out.results)
                                             + sum(c.time for c in block.chains if c.index != block.chosen))
    back = MultiStart.from_dict(json.loads(dumps(block.to_dict())))
    assert back.starts == block.starts and [c.status for c in back.chains] == [c.status for c in block.chains]


def test_a_screen_with_limits_keeps_the_best_chains_that_meet_them() -> None:
    # The screen ranks as select_chain does: chains that meet its limits first, then the metric. Here the limit
    # (f1 at least the third smallest chain's) excludes the two chains the metric alone would keep.
    cfg = copy.deepcopy(CONFIG)
    screen: dict[str, Any] = {"after": "subtask1", "keep": 2, "by": "best:f1"}
    cfg["stages"][0]["starts"] = {"n": 4, "until": "subtask2", "select": "best:S", "screen": screen}
    plain = run_design(parse_config(cfg)).multistart[0]
    f1 = [c.metrics[0]["f1"] for c in plain.chains]
    floor = sorted(f1)[2]
    screen["where"] = {"f1_min": floor}
    (block,) = run_design(parse_config(cfg)).multistart
    assert block.starts.screen == Screen("subtask1", 2, "best:f1", (Constraint("f1", lower=floor),))
    assert [c.metrics[0]["f1"] for c in block.chains] == f1  # the same chains up to the screen
    kept = sorted(c.index for c in block.chains if c.status == "complete")
    assert kept == sorted(j for j in range(4) if f1[j] >= floor)
    assert kept != sorted(c.index for c in plain.chains if c.status == "complete")
    back = MultiStart.from_dict(json.loads(dumps(block.to_dict())))
    assert back.starts == block.starts


def test_pick_where_and_best_metric_steer_the_final_pick(run: DesignRun) -> None:
    r = run.results[2]
    ok = r.feasible & (r.metrics["I"] <= 50.0)
    if ok.any():
        assert ok[r.picked]
        on = np.zeros(r.pop, dtype=bool)
        on[list(r.front)] = True
        among = ok & on if (ok & on).any() else ok  # the front first (the paper's X_i lie on it)
        assert among[r.picked] and r.metrics["S"][r.picked] == np.min(r.metrics["S"][among])
    else:
        assert r.picked == r.choose("best:S")


# --- the pieces, on made-up data ---------------------------------------------------------

def test_select_chain_prefers_feasible_then_the_limits_then_the_metric() -> None:
    picks = [{"S": 1.0, "I": 5.0}, {"S": 2.0, "I": 0.5}, {"S": 1.5, "I": 0.8}, {"S": 0.5, "I": 0.1}]
    where = (Constraint("I", upper=1.0),)
    assert select_chain(picks, [True] * 4, "best:S") == 3
    assert select_chain(picks, [True, True, True, False], "best:S") == 0
    assert select_chain(picks, [True, True, True, False], "best:S", where) == 2
    # Nobody meets the limit: the one missing it least, relatively.
    far = [{"S": 1.0, "I": 3.0}, {"S": 2.0, "I": 1.5}]
    assert select_chain(far, [True, True], "best:S", where) == 1
    # Limits count in the order given: meeting the first beats missing it by a little, however far
    # the second is missed.
    two = (Constraint("mse", upper=4.0), Constraint("I", upper=1.0))
    far = [{"S": 1.0, "I": 1.2, "mse": 4.1}, {"S": 2.0, "I": 90.0, "mse": 3.9}, {"S": 3.0, "I": 80.0, "mse": 3.95}]
    assert select_chain(far, [True] * 3, "best:S", two) == 2
    assert select_chain(far, [True] * 3, "best:S", two[::-1]) == 0
    # NaN ranks last; ties go to the lower chain.
    assert select_chain([{"S": math.nan}, {"S": 2.0}, {"S": 2.0}], [True] * 3, "best:S") == 1
    with pytest.raises(ValueError, match="use 'best:<metric>'"):
        select_chain(picks, [True] * 4, "knee")
    assert rank_chains(picks, [True] * 4, "best:S") == [3, 0, 2, 1]


def test_shortfalls_are_relative_per_limit() -> None:
    where = (Constraint("I", upper=2.0), Constraint("S", lower=1.0))
    assert shortfalls({"I": 2.0, "S": 1.0}, where) == (0.0, 0.0)
    assert shortfalls({"I": 1.0, "S": 3.0}, where) == (0.0, 0.0)
    assert shortfalls({"I": 3.0, "S": 1.0}, where) == (pytest.approx(0.5), 0.0)
    assert shortfalls({"I": 3.0, "S": 0.5}, where) == (pytest.approx(0.5), pytest.approx(0.5))
    assert shortfalls({"S": 1.0}, where) == (math.inf, 0.0)


def test_records_survive_json() -> None:
    c = Chain(1, (1001, 1002), "complete", (3, None), ({"S": 1.5, "I": math.nan}, {}), ({"r1": 50.0}, {}), True, 1.25)
    m = MultiStart(Starts(2, "b", "best:S", (Constraint("I", upper=1.0), Constraint("S", lower=0.1))), ("a", "b"),
                   0, 1, (c,), 1)
    back = MultiStart.from_dict(json.loads(dumps(m.to_dict())))
    assert back.starts == m.starts and back.chosen == 1 and back.stages == ("a", "b")
    (bc,) = back.chains
    assert (bc.seeds, bc.picks, bc.params, bc.feasible, bc.time) == (c.seeds, c.picks, c.params, True, 1.25)
    assert bc.metrics[0]["S"] == 1.5 and math.isnan(bc.metrics[0]["I"])


def test_choose_by_any_metric_with_a_where_filter(run: DesignRun) -> None:
    r = run.results[1]
    feas = r.feasible
    assert r.choose("best:S") == int(np.flatnonzero(feas)[np.argmin(r.metrics["S"][feas])])
    with pytest.raises(ValueError, match="no objective or metric 'speed'"):
        r.choose("best:speed")
    cut = float(np.median(r.metrics["I"][feas]))
    i = choose(r, "best:S", None, (Constraint("I", upper=cut),))
    assert r.metrics["I"][i] <= cut
    ok = feas & (r.metrics["I"] <= cut)
    assert r.metrics["S"][i] == np.min(r.metrics["S"][ok])
    # A limit nobody meets is ignored.
    assert choose(r, "best:S", None, (Constraint("I", upper=-1.0),)) == r.choose("best:S")


def test_a_chains_last_pick_skips_a_stage_a_cancel_left_without_one() -> None:
    # The chain table read "pick at subtask2" with every metric blank for a chain cancelled inside subtask 2.
    m = {"S": 2.0}
    c = Chain(1, (1, 2, 3, 4), "cancelled", (1, 1, 1, None), (m, m, {"S": 2.5}, {}), ({}, {}, {}, {}), False, 5.0)
    assert c.last_pick() == (2, {"S": 2.5})
    assert Chain(0, (1,), "cancelled", (None,), ({},), ({},), False, 0.0).last_pick() is None
