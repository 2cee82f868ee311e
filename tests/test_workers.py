"""Multi-start chains in worker processes: the same results as in one process, progress forwarded
and tagged by chain, cancellation and errors reach the caller, problems travel by name."""

from __future__ import annotations

import json
import pickle
import threading
from typing import Any

import numpy as np
import pytest
from test_multistart import CONFIG

from core.formats.config import parse_config
from core.optimize import workers
from core.optimize.pipeline import Pipeline
from core.optimize.problem import ASSEMBLY, ProblemSpec, make_problem
from core.optimize.result import dumps, encode
from core.optimize.run import run_design


def square(job: int, callback: Any, cancel: Any) -> int:
    if callback is not None:
        for k in range(3):
            callback((job, k))
    if job == 13:
        raise ValueError("job 13 fails")
    return job * job


def test_jobs_return_in_order_and_forward_their_progress_in_order() -> None:
    seen: list[tuple[int, int]] = []
    assert workers.run(square, [1, 2, 3, 4, 5], workers=2, callback=seen.append) == [1, 4, 9, 16, 25]
    assert sorted(seen) == [(j, k) for j in range(1, 6) for k in range(3)]
    for j in range(1, 6):
        assert [k for i, k in seen if i == j] == [0, 1, 2]  # one job's items arrive in order


def test_a_failing_job_raises_its_error_in_the_caller() -> None:
    with pytest.raises(ValueError, match="job 13 fails"):
        workers.run(square, [1, 13, 2], workers=2)
    with pytest.raises(ValueError, match="job 13 fails"):
        workers.run(square, [1, 13, 2], workers=1)


def test_worker_count_is_capped_by_the_jobs() -> None:
    assert workers.resolve(8, 3) == 3
    assert workers.resolve(None, 1) == 1
    assert workers.resolve(0, 64) == workers.available()


def test_registered_problems_pickle_by_name_and_options() -> None:
    p = make_problem("subtask3", f1_max=4.2, I_max=0.9, n_samples=72)
    back = pickle.loads(pickle.dumps(p))
    assert back.name == p.name and dict(back.options) == dict(p.options)
    assert back.constraints == p.constraints and back.objectives == p.objectives
    custom = ProblemSpec("mine", lambda d: {}, ("f1",), (ASSEMBLY,))
    with pytest.raises(TypeError, match="mine"):
        pickle.dumps(custom)


@pytest.fixture(scope="module")
def pair() -> tuple[Any, Any]:
    # Every chain tagged: record which chain reported each generation.
    tags: dict[int, list[Any]] = {1: [], 2: []}
    runs = {w: run_design(parse_config({**CONFIG, "workers": w}), callback=lambda p, w=w: tags[w].append(
        (p.chain, p.stage, p.generation))) for w in (1, 2)}
    return runs, tags


def test_chains_in_workers_equal_chains_in_one_process(pair: tuple[Any, Any]) -> None:
    runs, _ = pair
    a, b = runs[1], runs[2]
    assert (a.workers, b.workers) == (1, 2)
    assert a.multistart[0].chosen == b.multistart[0].chosen
    for ca, cb in zip(a.multistart[0].chains, b.multistart[0].chains, strict=True):
        assert (ca.seeds, ca.picks, ca.params, ca.status) == (cb.seeds, cb.picks, cb.params, cb.status)
        assert encode(ca.metrics) == encode(cb.metrics)
    for ra, rb in zip(a.results, b.results, strict=True):
        np.testing.assert_array_equal(ra.X, rb.X)
        np.testing.assert_array_equal(ra.F, rb.F)
        assert ra.picked == rb.picked


def test_progress_of_every_chain_reaches_the_caller_tagged(pair: tuple[Any, Any]) -> None:
    _, tags = pair
    n = CONFIG["stages"][0]["starts"]["n"]
    block = [(s, g) for c, s, g in tags[2] if c is not None]
    assert sorted(tags[1], key=repr) == sorted(tags[2], key=repr)  # the same generations, maybe interleaved
    for j in range(n):
        # chain j ran subtask1 (3 generations) then subtask2 (2) in order
        assert [(s, g) for c, s, g in tags[2] if c == j] == [("subtask1", g) for g in (1, 2, 3)] + [
            ("subtask2", g) for g in (1, 2)]
    assert len(block) == n * 5
    # after the block, the winner's subtask 3 runs untagged
    assert [(c, s) for c, s, _ in tags[2][-2:]] == [(None, "subtask3")] * 2


def test_cancelling_while_chains_run_in_workers_leaves_a_loadable_partial_result() -> None:
    cancel = threading.Event()

    def cb(p: Any) -> None:
        if p.stage == "subtask1" and p.generation == 2:
            cancel.set()

    out = run_design(parse_config({**CONFIG, "workers": 2}), callback=cb, cancel=cancel)
    assert out.status == "cancelled"
    (block,) = out.multistart
    chosen = next(c for c in block.chains if c.index == block.chosen)
    assert all(c.status in ("complete", "cancelled") for c in block.chains)
    # Which chains finished before the cancel reached them depends on timing: a finished one is kept if any.
    finished = any(c.status == "complete" for c in block.chains)
    assert chosen.status == ("complete" if finished else "cancelled")
    d = json.loads(dumps(out.to_dict()))
    back = Pipeline.from_dict(d["pipeline"])
    # A cancelled chain's partial stage is picked by its rule as a single chain's run is (session 36), unless it was
    # cancelled before its first population.
    assert (chosen.picks[-1] is None) == (back.lineage[-1].pop == 0)
    assert back.lineage[-1].picked == chosen.picks[-1]
    statuses = [r.status for r in back.lineage]
    assert statuses[-1] == ("complete" if finished else "cancelled") and set(statuses[:-1]) <= {"complete"}
    assert len(statuses) == len(chosen.picks)


@pytest.mark.parametrize("value", [0, -1, "many", 1.5, True])
def test_invalid_workers_name_the_key(value: Any) -> None:
    with pytest.raises(ValueError, match="workers"):
        parse_config({**CONFIG, "workers": value})


def test_workers_are_spawned_once_numbas_thread_pool_runs() -> None:
    from numba.np.ufunc import parallel

    was = parallel._is_initialized
    try:
        parallel._is_initialized = False
        assert workers.start_method() == "fork"
        parallel._is_initialized = True
        assert workers.start_method() == "spawn"
        # spawned workers import the job's module afresh and still return the same results
        assert workers.run(square, [3, 4], workers=2) == [9, 16]
    finally:
        parallel._is_initialized = was
