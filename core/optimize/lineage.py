"""Stages one after another: the start metrics that resolve relative limits, the pick handed to the next
stage, and multi-start blocks whose chains run in worker processes (``core.optimize.workers``)."""

from __future__ import annotations

import inspect
import threading
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.design import Design
from core.optimize import decision
from core.optimize import problem as problem_registry
from core.optimize.design_config import DesignConfig, StageConfig, placeholder
from core.optimize.multistart import SEED_STRIDE, Chain, MultiStart, Starts, rank_chains, select_chain
from core.optimize.pipeline import Pipeline
from core.optimize.problem import Constraint, ProblemSpec, make_problem
from core.optimize.result import PickRule, StageResult, best_on_front
from core.optimize.stage import Progress, StageSpec, derived_seed
from core.optimize.subtasks import LIMIT_METRICS, resolve_limits
from core.optimize.workers import resolve as resolve_workers
from core.optimize.workers import run as run_jobs
from core.optimize.workers import start_method

F64 = NDArray[np.float64]


def start_metrics(stage: StageConfig, design: Design) -> dict[str, F64]:
    """The metrics of a stage's start design under that stage's problem (to resolve relative limits)."""
    return dict(make_problem(stage.problem, **placeholder(stage.options)).evaluate_metrics(design))


def resolved_spec(stage: StageConfig, start: Design, seed: int) -> StageSpec:
    """A stage's spec with relative limits resolved against its start design.

    A relative limit on a metric the start does not have (it does not assemble) falls back to
    the problem's default (the paper's absolute threshold, sized to the target: ``core.optimize.scale``).
    """
    opts = dict(stage.options)
    relative = [k for k, v in opts.items() if isinstance(v, (str, list)) and k in LIMIT_METRICS]
    if relative:
        metrics = start_metrics(stage, start)
        defaults = inspect.signature(problem_registry._FACTORIES[stage.problem]).parameters
        for k in relative:
            if not np.isfinite(metrics[LIMIT_METRICS[k]]).all():
                opts[k] = defaults[k].default
        opts = resolve_limits(opts, metrics)
    return stage.spec(seed, opts)


def misses(result: StageResult, constraints: tuple[Constraint, ...]) -> list[tuple[Constraint, NDArray[np.bool_]]]:
    """Per constraint of another stage on a metric this result measured, the ``(pop,)`` mask of the members that
    miss it (a NaN value misses). The assembly measure is left out: a feasible member here assembles."""
    out = []
    for c in constraints:
        v = result.metrics.get(c.metric)
        if v is None or c.metric in ("violation", "violation_mm"):
            continue
        with np.errstate(invalid="ignore"):
            out.append((c, ~(np.nan_to_num(c.value(v), nan=np.inf) <= 0.0)))
    return out


def next_feasible(result: StageResult, nxt: ProblemSpec | None) -> NDArray[np.bool_]:
    """``(pop,)`` members feasible here that also satisfy the next stage's constraints on shared metrics."""
    ok = result.feasible.copy()
    for _, missed in misses(result, () if nxt is None else nxt.constraints):
        ok &= ~missed
    return ok


def unmet_by(result: StageResult, i: int, constraints: tuple[Constraint, ...],
             labels: Mapping[str, str] | None = None) -> list[str]:
    """Member i's values that miss ``constraints`` (another stage's), in words (``I 30.2 > 20``), as
    :func:`misses` judges them; a metric by its ``labels`` name when it has one (``Eq. 29 crank HF (mm) 48.4 > 0``:
    "crank2 48.4 > 0" named it as no other place did)."""
    out = []
    names = labels or {}
    for c, missed in misses(result, constraints):
        if missed[i]:
            upper = c.upper is not None
            bound = float(c.upper if upper else c.lower)  # type: ignore[arg-type]
            value = float(result.metrics[c.metric][i])
            out.append(f"{names.get(c.metric, c.metric)} {value:.3g} {'>' if upper else '<'} {bound:.3g}")
    return out


def where_mask(result: StageResult, where: tuple[Constraint, ...]) -> NDArray[np.bool_]:
    """``(pop,)`` members whose metrics meet every limit (a NaN metric never does)."""
    ok = np.ones(result.pop, dtype=bool)
    for c in where:
        with np.errstate(invalid="ignore"):
            ok &= np.nan_to_num(c.value(result.metrics[c.metric]), nan=np.inf) <= 0.0
    return ok


def choose(result: StageResult, rule: PickRule, mask: NDArray[np.bool_] | None = None,
           where: tuple[Constraint, ...] = ()) -> int:
    """A pick rule applied to the members in ``mask`` (all when None or when no member is in it).

    ``where`` (a stage's ``pick_where``) narrows the candidates first: the rule applies to the
    feasible members that meet it and are in ``mask``, else to those that meet it, else it is
    ignored. With no feasible member at all, the least-violation member among those that
    assemble (``violation == 0``: their metrics are defined, so the next stage can start from them).
    """
    if not isinstance(rule, (int, np.integer)) and not result.feasible.any() and "violation" in result.metrics:
        built = np.flatnonzero(result.metrics["violation"] == 0.0)
        if built.size:
            return int(built[np.argmin(result.cv[built])])
    if where and not isinstance(rule, (int, np.integer)):
        meets = where_mask(result, where) & result.feasible
        if meets.any():
            both = meets if mask is None else meets & mask
            mask = both if both.any() else meets
    if isinstance(rule, (int, np.integer)) or mask is None or not mask.any() or mask.all():
        return result.choose(rule)
    idx = np.flatnonzero(mask)
    F, cv = result.F[idx], result.cv[idx]
    if isinstance(rule, str) and rule.startswith("best:"):
        name = rule[5:]
        if name in result.objectives:
            j = decision.best_per_objective(F, cv)[result.objectives.index(name)]
            return int(idx[j])
        cand = mask & result.feasible
        front: tuple[int, ...] = result.front
        if not cand[list(front)].any():  # no member of the whole front is a candidate: the candidates' own front
            front = tuple(int(i) for i in idx[decision.pareto_front(F, cv)])
        best = best_on_front(result.metrics[name], cand, front, name) if name in result.metrics else None
        return best if best is not None else result.choose(rule)
    sl = decision.shortlist(F, cv)
    k = int(rule.split(":", 1)[1]) if isinstance(rule, str) and ":" in rule else 0
    return int(idx[sl.knees[min(k, len(sl.knees) - 1)]]) if sl.knees else result.choose(rule)


def run_stage(config: DesignConfig, pipe: Pipeline, k: int, pick: int | None, seed: int,
               callback: Callable[[Progress], None] | None, cancel: threading.Event | None,
               pick_cancelled: bool = False) -> StageResult:
    """Run stage k of ``pipe`` from member ``pick`` of stage k-1 with its automatic pick; record and return it.

    With ``pick_cancelled``, a cancelled stage (Ctrl-C) is picked by the same rule among the population it reached,
    as the studio's Stop picks (lab rehearsal: the CLI kept 569 generations that nothing could evaluate or export);
    otherwise (a multi-start chain, which keeps a finished chain instead), or cancelled before its first
    population, it is recorded without a pick. The run stops at a cancelled stage either way.
    """
    stage_cfg = config.stages[k]
    start, _ = pipe.parent(k, pick)
    spec = resolved_spec(stage_cfg, start, seed)
    res = pipe.stage(k, pick, spec=spec, callback=callback).run(cancel=cancel)
    done = ("complete", "stopped", "cancelled") if pick_cancelled else ("complete", "stopped")
    if res.status not in done or res.pop == 0:
        pipe.record(k, res)
        return res
    res = res.with_pick(stage_pick(config, k, res, spec.stop_below))
    pipe.record(k, res)
    return res


def stage_pick(config: DesignConfig, k: int, res: StageResult, stop_below: tuple[float, ...] | None = None) -> int:
    """Stage k's automatic pick in ``res`` by its config's rule and limits (:func:`auto_pick`)."""
    nxt = None
    if k + 1 < len(config.stages):
        # The next stage's absolute thresholds steer the pick (relative ones hold for every candidate).
        s = config.stages[k + 1]
        nxt = make_problem(s.problem, **placeholder(s.options, absolute=True))
    return auto_pick(res, config.stages[k].pick, stop_below, nxt, config.stages[k].pick_where)


def auto_pick(res: StageResult, rule: PickRule, stop_below: tuple[float, ...] | None, nxt: ProblemSpec | None,
              where: tuple[Constraint, ...] = ()) -> int:
    """A finished stage's automatic pick (``clm design``'s and the studio's): ``rule`` among the members that also
    meet the next stage's constraints (``nxt``), narrowed by ``where`` (see :func:`choose`); after an early stop,
    among the members that met its thresholds."""
    mask = next_feasible(res, nxt)
    if res.status == "stopped" and stop_below is not None:
        # The stage stopped because members met its thresholds: pick among those.
        met = res.feasible & (res.F <= np.asarray(stop_below)).all(axis=1)
        mask = mask & met if (mask & met).any() else met
    return choose(res, rule, mask, where)


class _Chain:
    """A chain of a multi-start block being run: its own pipeline and what it picked so far."""

    def __init__(self, config: DesignConfig, pipe: Pipeline, first: int, last: int, j: int) -> None:
        self.config, self.j = config, j
        self.pipe = Pipeline(pipe.stages, pipe.start, pipe.results[:first])  # shares the stages before the block
        self.seeds = tuple(derived_seed(config.seed, k + SEED_STRIDE * j) for k in range(first, last + 1))
        self.first, self.last = first, last
        self.picks: list[int | None] = []
        self.metrics: list[dict[str, float]] = []
        self.params: list[dict[str, float]] = []
        self.time = 0.0
        self.evals = 0
        self.status = "running"
        self.feasible = False

    def run(self, upto: int, pick: int | None, callback: Callable[[Progress], None] | None,
            cancel: threading.Event | None) -> bool:
        """Run the chain's next stages up to stage ``upto``; False if one was cancelled."""
        if self.picks:
            pick = self.picks[-1]
        tagged = None if callback is None else _tag(callback, self.j)
        for k in range(self.first + len(self.picks), upto + 1):
            res = run_stage(self.config, self.pipe, k, pick, self.seeds[k - self.first], tagged, cancel)
            self.time += float(res.timings["total"])
            self.evals += int(res.n_evals)
            pick = res.picked
            self.picks.append(pick)
            if pick is None:
                self.metrics.append({})
                self.params.append({})
                self.status = "cancelled"
                return False
            self.metrics.append({})
            self.params.append({})
            self._note(res, pick)
            self.feasible = bool(res.feasible[pick])
        if upto == self.last:
            self.status = "complete"
        return True

    def pick_stopped(self) -> None:
        """Pick the stage the chain was cancelled in by its rule among the population it reached, as a single chain's
        run picks it (QA, session 36: a stopped multi-start run kept no design after 237 generations)."""
        k = self.first + len(self.picks) - 1
        if not self.picks or self.picks[-1] is not None:
            return
        res = self.pipe.results[k] if k < len(self.pipe.results) else None
        if res is None or res.pop == 0 or res.status != "cancelled":
            return
        res = res.with_pick(stage_pick(self.config, k, res))
        self.pipe.record(k, res)
        pick = int(res.picked)  # type: ignore[arg-type]
        self.picks[-1] = pick
        self._note(res, pick)

    def _note(self, res: StageResult, pick: int) -> None:
        """The last stage's pick's metrics and parameters, as the chain's record shows them."""
        self.metrics[-1] = {n: float(v[pick]) for n, v in res.metrics.items()}
        self.params[-1] = res.named(pick)

    def reached(self, upto: int) -> bool:
        """Whether the chain has a pick at stage ``upto``."""
        return len(self.picks) == upto - self.first + 1 and self.picks[-1] is not None

    def record(self) -> Chain:
        # A chain still running when the run stopped counts as cancelled.
        status = "cancelled" if self.status == "running" else self.status
        return Chain(self.j, self.seeds, status, tuple(self.picks), tuple(self.metrics), tuple(self.params),
                     self.feasible and status == "complete", self.time, self.evals)


def _tag(callback: Callable[[Progress], None], j: int) -> Callable[[Progress], None]:
    return lambda p: callback(replace(p, chain=j))


def _chain_job(job: tuple[_Chain, int, int | None], callback: Callable[[Progress], None] | None,
               cancel: Any) -> _Chain:
    """Run one chain up to a stage (in a worker process, or here); the chain as it then is."""
    chain, upto, pick = job
    if cancel is None or not cancel.is_set():  # a chain not started before the cancel stays unrecorded
        chain.run(upto, pick, callback, cancel)
    return chain


def _run_chains(chains: list[_Chain], upto: int, pick: int | None, workers: int,
                callback: Callable[[Progress], None] | None, cancel: threading.Event | None,
                scheduler: str | None = None) -> list[_Chain]:
    if not scheduler and resolve_workers(workers, len(chains)) > 1 and start_method() == "fork":
        _compile_here(chains[0], upto, pick)
    return run_jobs(_chain_job, [(c, upto, pick) for c in chains], workers, callback, cancel, scheduler)


def _compile_here(chain: _Chain, upto: int, pick: int | None) -> None:
    """Evaluate (and repair) the chain's start design under each of its stages' problems here, so
    that forked workers inherit every numba kernel the chains use (on a cold cache each worker
    would otherwise compile them all itself)."""
    start, _ = chain.pipe.parent(chain.first + len(chain.picks), pick if not chain.picks else chain.picks[-1])
    for stage in chain.config.stages[chain.first + len(chain.picks) : upto + 1]:
        spec = stage.problem_spec()
        spec.evaluate_metrics(start)
        if spec.repair is not None:
            spec.repair(start)


def run_block(config: DesignConfig, pipe: Pipeline, first: int, pick: int | None, starts: Starts,
               callback: Callable[[Progress], None] | None,
               cancel: threading.Event | None) -> tuple[MultiStart, Pipeline, bool]:
    """A multi-start block from stage ``first``: its record, the pipeline to go on with, and
    whether it completed (else that pipeline is the best of the chains that completed the block, or if none did,
    the first cancelled chain's).

    The chains run in ``config.workers`` processes. After a cancel, the record holds the chains
    that had started (the cancelled ones with their partial picks).
    """
    names = [s.name for s in config.stages]
    last = names.index(starts.until, first)
    upto = last if starts.screen is None else names.index(starts.screen.after, first)
    chains = [_Chain(config, pipe, first, last, j) for j in range(starts.n)]

    def stopped(run: list[_Chain], k: int) -> tuple[MultiStart, Pipeline, bool] | None:
        # Unless every chain of this round reached stage k: the best chain that completed the block is chosen
        # (a designer who stops a run keeps its best finished design), else the first cancelled one.
        short = sorted((c.status != "cancelled", c.j) for c in run if not c.reached(k))
        if not short:
            return None
        done = [x for x in chains if x.status == "complete"]
        if done:
            c = done[select_chain([x.metrics[-1] for x in done], [x.feasible for x in done], starts.select,
                                  starts.where)]
        else:
            c = next(x for x in run if x.j == short[0][1])
            c.pick_stopped()
        records = tuple(x.record() for x in chains if x.picks)
        return MultiStart(starts, tuple(names[first : last + 1]), first, last, records, c.j), c.pipe, False

    chains = _run_chains(chains, upto, pick, config.workers, callback, cancel, config.scheduler)
    if (out := stopped(chains, upto)) is not None:
        return out
    going = chains
    if starts.screen is not None:
        order = rank_chains([c.metrics[-1] for c in chains], [c.feasible for c in chains], starts.screen.by,
                            starts.screen.where)
        kept = set(order[: starts.screen.keep])
        going = [c for c in chains if c.j in kept]
        for c in chains:
            if c.j not in kept:
                c.status = "dropped"
        going = _run_chains(going, last, None, config.workers, callback, cancel, config.scheduler)
        chains = [next((g for g in going if g.j == c.j), c) for c in chains]
        if (out := stopped(going, last)) is not None:
            return out
    won = going[select_chain([c.metrics[-1] for c in going], [c.feasible for c in going], starts.select,
                             starts.where)]
    record = MultiStart(starts, tuple(names[first : last + 1]), first, last, tuple(c.record() for c in chains), won.j)
    return record, won.pipe, True


