"""Running a design configuration (``clm design``, the studio, studies): the validated configuration's
objects, and the run itself.

Running (:func:`run_design`): stages run in order; between stages the automatic pick applies
the stage's rule (``knee``, ``knee:k``, ``best:<metric>`` or an index) to the members that
meet its ``pick_where`` limits and also satisfy the next stage's absolute constraints (so the
next stage starts feasible when it can) and, for a stage that stopped early, its
``stop_below`` thresholds; relative limits (``"start+0.5"``) are resolved against each
stage's start. A stage with a ``starts`` table runs, with the stages up to ``starts.until``,
as several chains with other seeds, and the best chain goes on (``core.optimize.multistart``).
The file format that produces a :class:`DesignConfig` is ``core.formats.config``.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.optimize.baselines import DP_METHODS, BaselineResult, run_baseline
from core.optimize.design_config import DesignConfig, placeholder
from core.optimize.lineage import run_block, run_stage
from core.optimize.multistart import MultiStart
from core.optimize.pipeline import Pipeline
from core.optimize.result import StageResult
from core.optimize.stage import Progress, derived_seed
from core.optimize.workers import resolve as resolve_workers

RESULT_FORMAT = "clm-design"  # result.json's "format": what clm compare, clm-charts and --overwrite accept

F64 = NDArray[np.float64]


@dataclass
class DesignRun:
    """The outcome of :func:`run_design`.

    Attributes:
        config: the configuration.
        pipeline: the stages' lineage (hierarchical / single_level), else None.
        baseline: the DP baseline result, else None.
        status: ``complete``, ``cancelled`` or ``failed`` (a stage raised: see :class:`StageFailed`).
        wall_time: seconds from start to end (setup and between-stage work included).
        multistart: the record of each multi-start block (every chain's picks; the pipeline
            holds the winning chain's results).
        workers: processes the chains ran in (1 without a multi-start block).
        error: what failed (``failed``): the stage, the exception and its traceback.
        compile_time: seconds of ``wall_time`` this process spent compiling numba kernels (set by ``clm design``;
            multi-start worker processes compile their own, not counted): a first run on a machine, whose stage
            times are mostly that (rehearsal 8: 16 s, then 0.17 s for the same run).
    """

    config: DesignConfig
    pipeline: Pipeline | None = None
    baseline: BaselineResult | None = None
    status: str = "complete"
    wall_time: float = 0.0
    multistart: tuple[MultiStart, ...] = ()
    workers: int = 1
    error: str = ""
    compile_time: float = 0.0

    @property
    def compute_time(self) -> float:
        """Compute time of every stage run (s): the lineage's and the losing chains'."""
        return float(sum(r.timings["total"] for r in self.results) + sum(m.time for m in self.multistart))

    @property
    def compute_evals(self) -> int | None:
        """Function evaluations of every stage run, as :attr:`compute_time` counts (None: a chain's not kept)."""
        lost = [m.evals for m in self.multistart]
        if any(e is None for e in lost):
            return None
        return int(sum(r.n_evals for r in self.results) + sum(e for e in lost if e is not None))

    @property
    def results(self) -> list[StageResult]:
        return [] if self.pipeline is None else self.pipeline.lineage

    def final(self) -> tuple[StageResult, int] | None:
        """The last stage result that has a pick, and the pick."""
        for r in reversed(self.results):
            if r.picked is not None:
                return r, r.picked
        return None

    def rows(self) -> list[dict[str, Any]]:
        """Summary rows for ``clm compare``: label, time (s) and the chosen designs' metrics."""
        c = self.config
        if self.baseline is not None:
            b = self.baseline
            return [{"label": f"{c.name}: {b.to_dict()['title']}", "method": b.method, "time": b.time,
                     "status": b.status, **b.metrics}]
        total = self.compute_time
        out: list[dict[str, Any]] = []
        if c.method == "single_level" and self.results:
            r = self.results[-1]
            # Appendix B-4: the designs with the smallest MSE, h_s and I.
            shown: list[str] = [o for o in ("f1", "h_s", "I") if o in r.objectives] or list(r.objectives)
            for obj in shown:
                if r.shortlist.best:
                    i = r.choose(f"best:{obj}")
                    out.append(_row(f"{c.name}: single-level, smallest {obj}", c.method, total, r, i, self.status,
                                    self.compute_evals))
            return out
        fin = self.final()
        if fin is not None:
            r, i = fin
            out.append(_row(f"{c.name}: {r.name} pick", c.method, total, r, i, self.status, self.compute_evals))
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": RESULT_FORMAT,
            "format_version": 1,
            "name": self.config.name,
            "method": self.config.method,
            # The seed that ran: `clm design --seed 2` recorded the file's seed 1, and clm compare labelled it so
            # (rehearsal 8); rerunning this config gives this result.
            "config": {**dict(self.config.source), "seed": self.config.seed},
            "config_path": self.config.path,
            "status": self.status,
            "wall_time": self.wall_time,
            "compile_time": self.compile_time,
            "rows": self.rows(),
            "pipeline": None if self.pipeline is None else self.pipeline.to_dict(),
            "baseline": None if self.baseline is None else self.baseline.to_dict(),
            "multistart": [m.to_dict() for m in self.multistart],
            "workers": self.workers,
            **({"error": self.error} if self.error else {}),
        }


class StageFailed(RuntimeError):
    """A stage raised. ``run`` holds what was done before it (status ``failed``), so that a caller can keep the
    finished stages; the stage's exception is the ``__cause__``."""

    def __init__(self, run: DesignRun, stage: str, cause: Exception) -> None:
        super().__init__(f"stage {stage!r} failed: {type(cause).__name__}: {cause}")
        self.run, self.stage = run, stage


def _failed(config: DesignConfig, pipe: Pipeline, blocks: list[MultiStart], used: int, t0: float, k: int,
            e: Exception) -> StageFailed:
    """StageFailed for stage k's exception, carrying the stages finished before it."""
    name = config.stages[k].name
    trace = "".join(traceback.format_exception(e))
    run = DesignRun(config, pipe, status="failed", wall_time=time.perf_counter() - t0, multistart=tuple(blocks),
                    workers=used, error=f"stage {name!r}: {type(e).__name__}: {e}\n{trace}")
    return StageFailed(run, name, e)


ROW_METRICS = ("mse", "S", "I", "h_s", "f2", "f3", "h6", "h4", "dh6", "dh4")


def _row(label: str, method: str, total: float, r: StageResult, i: int, status: str,
         evals: int | None) -> dict[str, Any]:
    row: dict[str, Any] = {"label": label, "method": method, "time": total, "evals": evals, "status": status,
                           "stage": r.name, "member": i, "feasible": bool(r.feasible[i]), "params": r.named(i)}
    for k in ROW_METRICS:
        if k in r.metrics:
            row[k] = float(r.metrics[k][i])
    return row


def run_design(config: DesignConfig, callback: Callable[[Progress], None] | None = None,
               cancel: threading.Event | None = None) -> DesignRun:
    """Run a configuration headless.

    Args:
        config: the validated configuration.
        callback: after every generation (stages, and the GA of the DP baselines).
        cancel: checked between generations; the run then stops with a valid partial result.
    """
    t0 = time.perf_counter()
    if config.method in DP_METHODS:
        b = run_baseline(config.method, config.mechanism, config.start.output, config.baseline, config.seed,
                         callback, cancel)
        return DesignRun(config, baseline=b, status=b.status, wall_time=time.perf_counter() - t0)
    placeholders = [s.spec(derived_seed(config.seed, k), placeholder(s.options)) for k, s in enumerate(config.stages)]
    pipe = Pipeline(placeholders, config.start)
    blocks: list[MultiStart] = []
    used = max([resolve_workers(config.workers, s.starts.n) for s in config.stages if s.starts] or [1])
    pick: int | None = None
    k = 0
    while k < len(config.stages):
        starts = config.stages[k].starts
        if starts is None:
            try:
                res = run_stage(config, pipe, k, pick, derived_seed(config.seed, k), callback, cancel,
                                pick_cancelled=True)
            except Exception as e:
                raise _failed(config, pipe, blocks, used, t0, k, e) from e
            if res.picked is None or res.status == "cancelled":  # a cancelled stage has its pick, and ends the run
                return DesignRun(config, pipe, status="cancelled", wall_time=time.perf_counter() - t0,
                                 multistart=tuple(blocks), workers=used)
            pick, k = res.picked, k + 1
            continue
        try:
            block, pipe, done = run_block(config, pipe, k, pick, starts, callback, cancel)
        except Exception as e:
            raise _failed(config, pipe, blocks, used, t0, k, e) from e
        blocks.append(block)
        if not done:
            return DesignRun(config, pipe, status="cancelled", wall_time=time.perf_counter() - t0,
                             multistart=tuple(blocks), workers=used)
        pick, k = block.chains[block.chosen].picks[-1], block.last + 1
    return DesignRun(config, pipeline=pipe, status="complete", wall_time=time.perf_counter() - t0,
                     multistart=tuple(blocks), workers=used)
