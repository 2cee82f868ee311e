"""Runs a stage on a worker thread: one generation at a time, recorded into the study, cancellable."""

from __future__ import annotations

import math
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from core.kinematics.kernel_cache import CompileTimer
from core.optimize.result import encode
from core.optimize.stage import Progress
from studio.study import RunPlan, RunStatus, Study, done_at, status_text, studio_pick

LIVE_PERIOD = 0.25
"""Seconds between the live results a run records and announces (the Pareto chart redraws every 0.5 s). A result
re-evaluates the population's metrics and knee points: made after every generation it cost 2.4 ms against a
4 ms generation (subtask 2, pop 100), so a run took 1.6 times its compute time."""


COMPILE_TICK = 0.5  # s between the status's compile-time updates before the first generation


class Runner:
    """Runs one stage at a time in a worker thread.

    Args:
        lock: the session lock guarding ``study``.
        study: returns the current study (it may be replaced by a session load between runs).
        on_generation: called in the worker after a generation whose result was recorded (None: before the first,
            when the status has news: the time compiling).
        on_finish: called in the worker when the run ends (recorded, status updated).
        live_period: seconds between recorded generations (the first is recorded at once, the last by the
            run's end); 0 records every one (a studio with a session file saves each to disk).
    """

    def __init__(self, lock: threading.RLock, study: Callable[[], Study],
                 on_generation: Callable[[Progress | None], None], on_finish: Callable[[], None],
                 live_period: float = LIVE_PERIOD) -> None:
        self._lock = lock
        self._live_period = live_period
        self._study = study
        self._on_generation = on_generation
        self._on_finish = on_finish
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def busy(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self, plan_fn: Callable[[Study], RunPlan]) -> RunPlan:
        """Plan and start a run under the lock; ValueError if one is running or the plan fails."""
        with self._lock:
            study = self._study()
            if study.status.running or self.busy:
                raise ValueError("a stage is already running; wait for it or press Stop")
            plan = plan_fn(study)
            study.begin(plan)
            self._cancel = threading.Event()
            self._thread = threading.Thread(target=self._work, args=(study, plan, self._cancel),
                                            name=f"clm-studio-{plan.stage.name}", daemon=True)
            self._thread.start()
            return plan

    def stop(self) -> bool:
        """Ask the run to stop after the current generation; False if nothing runs."""
        if self.busy:
            self._cancel.set()  # first, without waiting for the lock: the worker checks it between generations
        with self._lock:
            study = self._study()
            if not study.status.running:
                return False
            self._cancel.set()
            study.status = replace(study.status, state="stopping", message="stopping after this generation")
            study.touch()
            return True

    def join(self, timeout: float | None = None) -> None:
        t = self._thread
        if t is not None:
            t.join(timeout)

    def _work(self, study: Study, plan: RunPlan, cancel: threading.Event) -> None:
        # A fresh install's first run compiles numba's kernels (~30 s), which the status counted as the run's
        # compute without a word ("29.2 s compute" for a 0.1 s predesign): the time spent compiling is told apart.
        with CompileTimer() as timer:
            self._run(study, plan, cancel, timer)

    def _run(self, study: Study, plan: RunPlan, cancel: threading.Event, timer: CompileTimer) -> None:
        pipe, k = plan.pipeline, plan.index
        message, ok = "", True
        n_gen = plan.spec.n_gen  # a stage that stops on its target is done there: its bar ends full
        first = threading.Event()  # set once the first generation is in
        threading.Thread(target=self._compiling, args=(study, timer, first, cancel), daemon=True).start()
        try:
            stage = pipe.stage(k, pick=plan.pick, spec=plan.spec)
            stage.setup()
            recorded = -math.inf
            while stage.has_next() and not cancel.is_set():
                progress = stage.next()
                fresh = time.monotonic() - recorded >= self._live_period
                result = stage.result() if fresh else None
                with self._lock:
                    if result is not None:
                        pipe.record(k, result)
                    study.live = progress
                    study.status = replace(study.status, generation=progress.generation, elapsed=progress.elapsed,
                                           message=f"generation {progress.generation}/{progress.n_gen}",
                                           compiled=timer.seconds)
                    study.touch()
                first.set()
                if fresh:
                    recorded = time.monotonic()
                    self._on_generation(progress)
            if cancel.is_set():
                stage.cancel()
            result = stage.result()
            # A stopped run is picked as a finished one is: History's pick column stayed blank while the editor
            # showed its first candidate.
            if result.status in ("complete", "stopped", "cancelled") and result.pop > 0:
                result = result.with_pick(studio_pick(result, plan))
            with self._lock:
                pipe.record(k, result)
            message = status_text(result)
            if result.pop and not result.feasible.any():  # its least violating member goes to the editor all the same
                message += "; the editor shows its least violating member (Undo: the design before)"
            n_gen = done_at(result)
        except Exception as exc:  # noqa: BLE001 - a failing problem must not kill the studio
            ok = False
            message = f"failed: {exc}"
            traceback.print_exc()
        finally:
            first.set()
            with self._lock:
                study.live = None
                study.status = RunStatus("idle", plan.stage.name, study.status.generation, n_gen, message, ok,
                                         study.status.elapsed, timer.seconds)
                study.touch()
            self._on_finish()


    def _compiling(self, study: Study, timer: CompileTimer, first: threading.Event, cancel: threading.Event) -> None:
        """Until the first generation is in, say every half second how long numba has been compiling: a fresh
        install's first run read "generation 0/150 (< 0.01 s compute)" for 41 s, which looked hung (rehearsal 7)."""
        while not first.wait(COMPILE_TICK) and not cancel.is_set():
            seconds = timer.seconds
            if seconds <= 0.0:
                continue
            with self._lock:
                if study.status.state == "running" and study.status.generation == 0:
                    study.status = replace(study.status, compiled=seconds)
                    study.touch()
            self._on_generation(None)


def progress_dict(p: Progress) -> dict[str, Any]:
    """A Progress as plain data (tests, debugging)."""
    return encode({"stage": p.stage, "generation": p.generation, "n_gen": p.n_gen, "F": p.F, "cv": p.cv})
