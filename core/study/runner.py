"""Run a study's cells on Dask distributed: a LocalCluster (one worker process per core) or a scheduler.

Re-running the same command resumes: finished cells are skipped, failed ones run again (their
attempts counted); finished cells whose settings changed are refused, or run again on request. Only this
client writes the store, as each task completes.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TextIO

from core.formats.study import Study, effective_settings, settings_change
from core.optimize.workers import connect
from core.study.cell import check_cells, run_cell, warm_cells, warm_up
from core.study.provenance import code_digest, code_version
from core.study.store import DIGEST, Store, settings_digest, study_lock


class StudyChanged(ValueError):
    """The study directory holds finished cells run with other settings than the study file's now."""


@dataclass
class Summary:
    """What one invocation did: cells in the study, skipped as finished, run now, failed now, wall time (s)."""

    total: int
    skipped: int
    ran: int
    failed: int
    wall_time: float


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


@contextmanager
def client_for(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A Dask client: connected to ``scheduler`` if given, else to a new LocalCluster on 127.0.0.1."""
    from distributed import Client, LocalCluster

    # CRITICAL: a lost scheduler is said in one line (below); its ERROR lines were a 51-line traceback.
    for name in ("distributed", "distributed.worker", "distributed.nanny", "distributed.scheduler",
                 "distributed.client"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    if scheduler:
        client = connect(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or default_workers()
    # CRITICAL: a cell's failure comes back as data, and a worker's death through its futures; the workers'
    # own ERROR lines (heartbeats to a cluster that is closing) only buried the one line that says what happened.
    # The scheduler's HTTP server on a free local port: None still asked for 8787, and with another cluster there
    # every run, --quiet too, printed "Port 8787 is already in use" (rehearsal 6).
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL) as cluster, \
            Client(cluster) as client:
        client.run(ignore_sigint)
        yield client


def ignore_sigint() -> None:
    """In a local worker: Ctrl-C reaches the whole process group, and the client stops the cluster itself (each
    worker printed a KeyboardInterrupt traceback, ~70 lines in all)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Progress:
    """``cells done/total, failures, ETA`` on one self-overwriting stderr line (a plain line when not a tty)."""

    def __init__(self, total: int, done: int, stream: TextIO | None) -> None:
        self.total, self.done, self.start_done = total, done, done
        self.failed = 0
        self.stream = stream
        self.t0 = time.perf_counter()

    def step(self, failed: bool) -> None:
        self.done += 1
        self.failed += int(failed)
        if self.stream is None:
            return
        ran = self.done - self.start_done
        rate = ran / max(time.perf_counter() - self.t0, 1e-9)
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        tty = getattr(self.stream, "isatty", lambda: False)()
        line = f"cells {self.done}/{self.total}, {self.failed} failed, ETA {eta:.0f} s"
        self.stream.write(("\r" + line + ("\n" if self.done == self.total else "")) if tty else line + "\n")
        self.stream.flush()


def run_study(study: Study, out: str, scheduler: str | None = None, workers: int | None = None,
              stream: TextIO | None = sys.stderr, task: Callable[[dict[str, Any]], dict[str, Any]] = run_cell,
              limit: int | None = None, rerun_changed: bool = False, mixed_code: bool = False) -> Summary:
    """Run every unfinished cell of ``study`` and keep the results in ``out``.

    Args:
        study: the decoded study.
        out: the study directory (created if needed).
        scheduler: a Dask scheduler address (``tcp://host:8786``); None starts a LocalCluster.
        workers: LocalCluster worker processes (default: one per core).
        stream: where the progress line goes (None: silent).
        task: the function a cell runs (tests swap in one that fails).
        limit: run at most this many cells now (the rest wait for the next invocation).
        rerun_changed: run again the finished cells whose settings changed since (budget, population, options,
            the case config's contents), or whose code did (``core.study.provenance``); without it such a study is
            refused (StudyChanged), never reused.
        mixed_code: keep finished cells another version of the code ran (or whose code was not recorded); the
            report then counts the runs of each version.
    """
    t0 = time.perf_counter()
    check_cells(study)
    cells = study.cells()
    with study_lock(out):
        return _run(study, cells, out, scheduler, workers, stream, task, limit, rerun_changed, mixed_code, t0)


def _run(study: Study, cells: list[dict[str, Any]], out: str, scheduler: str | None, workers: int | None,
         stream: TextIO | None, task: Callable[[dict[str, Any]], dict[str, Any]], limit: int | None,
         rerun_changed: bool, mixed_code: bool, t0: float) -> Summary:
    from distributed import as_completed

    store = Store(out)
    try:
        kept = store.finished()
        changed = [c for c in cells if kept.get(c["key"]) is not None
                   and effective_settings(kept[c["key"]] or "") != effective_settings(c["settings"])]
        if changed and not rerun_changed:
            first = changed[0]
            was, now = (effective_settings(x) for x in (kept[first["key"]] or "", first["settings"]))
            raise StudyChanged(
                f"{out} holds {len(changed)} finished cell(s) run with other settings, e.g. {first['key']}: "
                f"{settings_change(was, now)}; pass --rerun-changed to run them again, or choose another --out")
        other = study.name != (store.meta("study") or {}).get("name", study.name)
        if other:  # rehearsal 6: another study's directory was taken over, its report overwritten
            raise StudyChanged(f"{out} holds the study {store.meta('study')['name']!r}, not {study.name!r}; choose "
                               "another --out")
        codes, here = store.codes(), code_digest()
        stale = [c for c in cells if c["key"] in kept and c not in changed and codes.get(c["key"]) != here]
        if stale and not (rerun_changed or mixed_code):
            versions = sorted({str(codes.get(c["key"]) or "not recorded") for c in stale})
            raise StudyChanged(
                f"{out} holds {len(stale)} finished cell(s) run with other code (core digest {', '.join(versions)}; "
                f"this code: {here}): pass --rerun-changed to run them again with this code, --mixed-code to keep "
                "them (the report counts the runs of each version), or choose another --out")
        if rerun_changed:
            changed += [c for c in stale if c not in changed]
        store.set_meta("code", code_version())
        store.set_meta("study", {"name": study.name, "path": study.path, "reference": study.reference,
                                 "algorithms": [a.name for a in study.algorithms],
                                 "labels": {a.name: a.title for a in study.algorithms},
                                 "cases": [c.name for c in study.cases], "seeds": list(study.seeds),
                                 "best": {c.name: c.best for c in study.cases},
                                 # The cells the report covers: rows of removed seeds or old settings are not.
                                 "cells": {c["key"]: settings_digest(c["settings"]) for c in cells},
                                 "digest": DIGEST})
        finished = set(kept) - {c["key"] for c in changed}
        waiting = [dict(c, threads=1) for c in cells if c["key"] not in finished]
        skipped = len(cells) - len(waiting)  # finished before this invocation (not those ``limit`` leaves waiting)
        todo = waiting if limit is None else waiting[:limit]
        progress = Progress(len(cells), skipped, stream)
        failed = 0
        if todo:
            with client_for(scheduler, workers) as client:
                if task is run_cell:  # a worker running other code (a --scheduler's, started before an edit) would
                    # record its own digest, and the study would pool two versions: refused before any cell runs
                    theirs = {str(d) for d in client.run(code_digest).values()}
                    if theirs - {here}:
                        raise StudyChanged(f"the cluster's workers run other code (core digest "
                                           f"{', '.join(sorted(theirs - {here}))}; this code: {here}): restart them "
                                           "with this code")
                if task is run_cell:  # every worker loads the kernels before any cell is timed
                    try:
                        client.run(warm_up, warm_cells(todo))
                    except Exception:  # noqa: BLE001 - a worker lost here is the cells' to report, not the warm-up's
                        pass
                futures = client.map(task, todo, pure=False, key=[f"cell-{c['key']}-{os.getpid()}" for c in todo])
                by_key = {f.key: c for f, c in zip(futures, todo, strict=True)}
                lost = 0
                for fut in as_completed(futures):
                    cell = by_key[fut.key]
                    if fut.status == "cancelled":  # the scheduler went away: the cell never ran
                        lost += 1
                        fut.release()
                        continue
                    if fut.status == "finished":
                        record = fut.result()
                    else:  # the worker died or the task could not run at all
                        exc = fut.exception()
                        record = {"key": cell["key"], "algorithm": cell["algorithm"]["name"],
                                  "case": cell["case"]["name"], "seed": cell["seed"], "status": "failed",
                                  "error": f"{type(exc).__name__}: {exc}"}
                    # A task that does not say which code ran it (a test's stand-in) ran this process's.
                    store.save(dict(record, settings=cell["settings"], code=record.get("code") or here))
                    failed += record["status"] != "done"
                    progress.step(record["status"] != "done")
                    fut.release()
                if lost:
                    raise ValueError(f"the Dask cluster went away: {lost} cell(s) did not run (the {len(todo) - lost} "
                                     f"that ended are kept in {out}); run the same command again to resume")
        return Summary(len(cells), skipped, len(todo), failed, time.perf_counter() - t0)
    finally:
        store.close()
