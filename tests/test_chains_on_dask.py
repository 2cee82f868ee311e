"""Multi-start chains on a Dask cluster (clm design --scheduler): the same chains and picks as local processes,
and a cancel reaches them through a distributed Event."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from distributed import LocalCluster
from test_multistart import CONFIG

from core.formats.config import parse_config
from core.optimize import workers
from core.optimize.run import run_design


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as c:
        yield c


def slow_square(job: int, callback, cancel) -> int:
    import time

    for _ in range(200):
        if cancel is not None and cancel.is_set():
            return -job
        time.sleep(0.01)
    return job * job


def test_jobs_run_on_the_cluster_in_order(cluster):
    assert workers.run(slow_square, [1, 2, 3], scheduler=cluster.scheduler_address) == [1, 4, 9]


def test_a_cancel_reaches_jobs_on_the_cluster(cluster):
    cancel = threading.Event()
    threading.Timer(0.3, cancel.set).start()
    out = workers.run(slow_square, [1, 2], scheduler=cluster.scheduler_address, cancel=cancel)
    assert out == [-1, -2]  # each job saw the flag between its steps and stopped


def test_a_design_gives_the_same_chains_on_a_cluster_as_in_local_processes(cluster):
    local = run_design(parse_config({**CONFIG, "workers": 1}))
    remote = run_design(replace(parse_config(CONFIG), scheduler=cluster.scheduler_address))
    a, b = local.multistart[0], remote.multistart[0]
    assert a.chosen == b.chosen and [c.picks for c in a.chains] == [c.picks for c in b.chains]
    for ra, rb in zip(local.results, remote.results, strict=True):
        np.testing.assert_array_equal(ra.X, rb.X)
