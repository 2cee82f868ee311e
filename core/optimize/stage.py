"""One optimization stage: a problem over a search box, an algorithm, a seed; stepped or run.

Stepping (what the studio does, in a worker thread)::

    stage = Stage(spec, start)             # start: a one-member Design (the previous pick)
    stage.setup()
    while stage.has_next() and not cancel.is_set():
        progress = stage.next()            # one generation; also passed to stage.callback
    result = stage.result()                # valid at any time, also after a cancel

    if cancel.is_set():
        stage.cancel()                     # marks the partial result "cancelled"

Headless: ``stage.run(callback, cancel)``. A generation is never interrupted: cancelling
takes effect between generations, and the result holds the last completed generation.

Threading: a Stage is not thread-safe. One thread (the worker) calls its methods; the
callback runs in that thread. Other threads communicate only through a
``threading.Event`` (cancel) and through what the worker hands out: :class:`Progress`
objects (fresh arrays) and :class:`StageResult` s (immutable), which they may keep and read
freely. An exception raised by the problem or the callback propagates out of ``next``/``run``;
the last completed generation is still available from ``result()``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymoo.core.algorithm import Algorithm

from core.kinematics import checks
from core.kinematics.design import Design
from core.optimize import decision
from core.optimize.algorithms import AlgorithmSpec, make_algorithm, validate
from core.optimize.box import Box, global_box, search_box
from core.optimize.problem import BoxRepair, DesignProblem, ProblemSpec, make_problem
from core.optimize.result import PickRule, StageResult, versions

F64 = NDArray[np.float64]


def derived_seed(seed: int, offset: int) -> int:
    """The seed ``offset`` places after ``seed`` (a stage's, a chain's), wrapped into numpy's [0, 2**32 - 1]: a run
    seed near the top of the range gives valid seeds to every stage instead of failing at the first past it."""
    return (int(seed) + int(offset)) % 2**32


@dataclass(frozen=True)
class StageSpec:
    """Everything that defines a stage except its starting design.

    Attributes:
        name: stage name (``predesign``, ``subtask1``, ...).
        problem: what to optimize.
        s, d: box rule ``x ± max(s|x|, d)`` around the start (spec §6); ``s = None``: the
            mechanism's global bounds.
        algorithm: pymoo algorithm, population and options.
        n_gen: generations (the first one evaluates the initial population).
        max_evals: function evaluations; the stage ends at whichever of ``n_gen`` and ``max_evals`` comes
            first (None: generations only). Algorithms spend N to 3N evaluations a generation, so a budget
            that is fair across them is one in evaluations (studies).
        seed: seed of the algorithm and of the initial sample.
        fixed: parameters held at the start value.
        seed_start: put the start design into the initial population (the rest is uniform
            in the box), so a stage never loses a feasible start.
        stop_below: stop early once a feasible member has every objective <= these values
            (RTCLM's [0.5, 0.5]); None: run all generations.
        pick: automatic pick rule for headless pipelines (see ``StageResult.choose``).
    """

    name: str
    problem: ProblemSpec
    s: float | None = None
    d: float = 0.0
    algorithm: AlgorithmSpec = field(default_factory=AlgorithmSpec)
    n_gen: int = 100
    seed: int = 0
    max_evals: int | None = None
    fixed: tuple[str, ...] = ()
    seed_start: bool = True
    stop_below: tuple[float, ...] | None = None
    pick: PickRule = "knee"

    def __post_init__(self) -> None:
        where = f"stage {self.name!r}"
        if not isinstance(self.problem, ProblemSpec):
            raise TypeError(f"{where}: problem must be a ProblemSpec, got {type(self.problem).__name__}")
        object.__setattr__(self, "fixed", tuple(self.fixed))
        object.__setattr__(self, "d", checks.real(self.d, f"{where}: box d (mm)", nonnegative=True))
        if self.s is not None:
            object.__setattr__(self, "s", checks.real(self.s, f"{where}: box s", positive=True))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed <= 2**32 - 1:
            raise ValueError(f"{where}: seed must be an integer in [0, 2**32 - 1], got {self.seed!r}")
        if self.stop_below is not None:
            limits = tuple(checks.real(v, f"{where}: stop_below") for v in self.stop_below)
            object.__setattr__(self, "stop_below", limits)
            if len(self.stop_below) != self.problem.n_obj:
                raise ValueError(f"stage {self.name!r}: stop_below needs {self.problem.n_obj} values")
        if not isinstance(self.n_gen, int) or isinstance(self.n_gen, bool) or self.n_gen < 1:
            raise ValueError(f"stage {self.name!r}: n_gen must be an integer >= 1, got {self.n_gen!r}")
        if self.max_evals is not None and (not isinstance(self.max_evals, int) or isinstance(self.max_evals, bool)
                                           or self.max_evals < 1):
            raise ValueError(f"stage {self.name!r}: max_evals must be an integer >= 1 or None, got {self.max_evals!r}")
        validate(self.algorithm)

    def box(self, start: Design) -> Box:
        """The search box around a one-member start design."""
        center = np.asarray(start.params[0])
        k = self.problem.scale
        if self.s is None:
            return global_box(start.mechanism, center, self.fixed, scale=k)
        return search_box(start.mechanism, center, self.s, self.d, self.fixed, scale=k)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "problem": {"name": self.problem.name, "options": dict(self.problem.options)},
            "objectives": list(self.problem.objectives),
            "constraints": [c.to_dict() for c in self.problem.constraints],
            "s": self.s,
            "d": self.d,
            "algorithm": self.algorithm.to_dict(),
            "n_gen": self.n_gen,
            "max_evals": self.max_evals,
            "seed": self.seed,
            "fixed": list(self.fixed),
            "seed_start": self.seed_start,
            "stop_below": None if self.stop_below is None else list(self.stop_below),
            "pick": self.pick,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> StageSpec:
        """Rebuild a spec; the problem comes from the registry (``make_problem``)."""
        p = d["problem"]
        stop = d.get("stop_below")
        return cls(
            name=str(d["name"]),
            problem=make_problem(p["name"], **p.get("options", {})),
            s=None if d.get("s") is None else float(d["s"]),
            d=float(d.get("d", 0.0)),
            algorithm=AlgorithmSpec.from_dict(d.get("algorithm", {})),
            n_gen=int(d.get("n_gen", 100)),
            max_evals=None if d.get("max_evals") is None else int(d["max_evals"]),
            seed=int(d.get("seed", 0)),
            fixed=tuple(d.get("fixed", ())),
            seed_start=bool(d.get("seed_start", True)),
            stop_below=None if stop is None else tuple(float(v) for v in stop),
            pick=d.get("pick", "knee"),
        )


@dataclass(frozen=True)
class Progress:
    """What the callback gets after every generation (arrays are fresh copies).

    Attributes:
        stage, index: stage name and position in the pipeline.
        generation, n_gen: generations completed and planned; ``fraction`` = their ratio, or the share
            of ``max_evals`` spent when that is larger.
        elapsed: compute time of this stage so far (s), pauses between steps excluded.
        n_evals: designs evaluated so far.
        X: ``(pop, n_params)`` current population's parameter vectors (mm, rad).
        F: ``(pop, n_obj)`` objectives (+inf where undefined); G: ``(pop, n_con)``; cv: ``(pop,)``.
        feasible: ``(pop,)``; front: indices of the feasible non-dominated members.
        shortlist: knee candidates of the current population.
        objectives: objective names (F's columns).
        chain: the multi-start chain this generation belongs to (None outside a multi-start
            block); chains may run at once in worker processes, so their progress interleaves.

    ``front`` and ``shortlist`` are computed on first use (a headless run never needs them, and
    for a population of 200 they cost about as much as a tenth of a generation).
    """

    stage: str
    index: int
    generation: int
    n_gen: int
    elapsed: float
    n_evals: int
    X: F64
    F: F64
    G: F64
    cv: F64
    feasible: NDArray[np.bool_]
    objectives: tuple[str, ...]
    chain: int | None = None
    max_evals: int | None = None

    @property
    def fraction(self) -> float:
        done = self.generation / self.n_gen
        if self.max_evals:
            done = max(done, self.n_evals / self.max_evals)
        return min(1.0, done)

    @cached_property
    def shortlist(self) -> decision.Shortlist:
        return decision.shortlist(self.F, self.cv)

    @cached_property
    def front(self) -> NDArray[np.intp]:
        return np.asarray(self.shortlist.front, dtype=np.intp)


Callback = Callable[[Progress], None]


class Stage:
    """A stage in progress: owns its pymoo problem and algorithm; one thread drives it.

    Args:
        spec: the stage definition.
        start: one-member Design to build the box around (and to seed the population).
        index: position in the pipeline (reported in Progress and the result).
        callback: called after every generation with a :class:`Progress`.
        parent_pick: member of the previous stage's result that ``start`` is (recorded only).
    """

    def __init__(self, spec: StageSpec, start: Design, index: int = 0, callback: Callback | None = None,
                 parent_pick: int | None = None) -> None:
        if start.pop != 1:
            raise ValueError(f"a stage starts from one design, got pop = {start.pop}")
        try:
            spec.problem.check_fits(start.mechanism)
        except ValueError as e:
            raise ValueError(f"stage {spec.name!r}: {e}") from None
        self.spec, self.start, self.index, self.callback = spec, start, index, callback
        self.parent_pick = parent_pick
        self.box = spec.box(start)
        self.problem = DesignProblem(spec.problem, start.mechanism, self.box, start.output)
        self.algorithm: Algorithm | None = None
        self.status = "not started"
        self.generation = 0
        self.times: list[float] = []
        self._cached: StageResult | None = None

    @property
    def n_gen(self) -> int:
        return self.spec.n_gen

    @property
    def elapsed(self) -> float:
        return float(sum(self.times))

    def initial_population(self, n: int) -> F64:
        """``(n, n_var)`` initial variables: the start (if ``seed_start``) then uniform in the box."""
        rng = np.random.default_rng(np.random.SeedSequence([self.spec.seed, 0x5EED]))
        X = rng.uniform(self.box.xl, self.box.xu, size=(n, self.box.n_var))
        if self.spec.seed_start and n > 0:
            X[0] = np.clip(self.box.encode(self.start.params)[0], self.box.xl, self.box.xu)
        return X

    def setup(self) -> None:
        """Build the algorithm (idempotent). Nothing is evaluated yet."""
        if self.algorithm is not None:
            return
        t = time.perf_counter()
        repair = BoxRepair(self.problem) if self.spec.problem.repair is not None else None
        alg = make_algorithm(self.spec.algorithm, self.spec.problem.n_obj, self.spec.seed, repair)
        alg.initialization.sampling = self.initial_population(int(alg.pop_size))
        alg.setup(self.problem, termination=self.termination(), seed=self.spec.seed, verbose=False)
        self.algorithm = alg
        self.times.append(time.perf_counter() - t)
        self.status = "running"

    def termination(self) -> Any:
        """pymoo's termination: ``n_gen`` generations, or whichever of them and ``max_evals`` comes first."""
        if self.spec.max_evals is None:
            return ("n_gen", self.spec.n_gen)
        from pymoo.termination import get_termination
        from pymoo.termination.collection import TerminationCollection

        return TerminationCollection(get_termination("n_gen", self.spec.n_gen),
                                     get_termination("n_eval", self.spec.max_evals))

    def has_next(self) -> bool:
        """True while generations remain and the stage has not stopped or been cancelled."""
        if self.status in ("complete", "stopped", "cancelled"):
            return False
        return self.algorithm is None or bool(self.algorithm.has_next())

    def next(self) -> Progress:
        """Run one generation, call the callback, return the progress.

        Raises:
            RuntimeError: no generation left.
        """
        self.setup()
        if not self.has_next():
            raise RuntimeError(f"stage {self.spec.name!r} has no generation left ({self.status})")
        assert self.algorithm is not None
        t = time.perf_counter()
        # NaN and inf are part of a generation (unassemblable designs, pymoo's SPEA2 normalising a front whose
        # nadir equals its ideal): the algorithms read them as penalties, and numpy's warnings would only clutter
        # the console of the studio, the CLI and the study workers.
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            self.algorithm.next()
        self.generation += 1
        self._cached = None
        X, F, G, cv = self._population()
        if self.spec.stop_below is not None and _reached(F, cv, self.spec.stop_below):
            self.status = "stopped"
        elif not self.algorithm.has_next():
            self.status = "complete"
        self.times.append(time.perf_counter() - t)
        progress = Progress(
            stage=self.spec.name, index=self.index, generation=self.generation, n_gen=self.spec.n_gen,
            elapsed=self.elapsed, n_evals=int(self.algorithm.evaluator.n_eval), X=X, F=F, G=G, cv=cv,
            feasible=decision.usable(F, cv), objectives=self.spec.problem.objectives,
            max_evals=self.spec.max_evals,
        )
        if self.callback is not None:
            self.callback(progress)
        return progress

    def cancel(self) -> None:
        """Mark the stage cancelled (call between generations, from the driving thread)."""
        if self.status in ("not started", "running"):
            self.status = "cancelled"
            self._cached = None

    def run(self, callback: Callback | None = None, cancel: threading.Event | None = None) -> StageResult:
        """Run the remaining generations; stop between generations once ``cancel`` is set.

        A stage whose run was cancelled through the event can be continued by calling
        ``run`` again with a cleared event.
        """
        if callback is not None:
            self.callback = callback
        if self.status == "cancelled" and (self.algorithm.has_next() if self.algorithm is not None
                                           else self.generation < self.spec.n_gen):
            self.status = "running" if self.algorithm is not None else "not started"
        while self.has_next():
            if cancel is not None and cancel.is_set():
                self.cancel()
                break
            self.next()
        return self.result()

    def _population(self) -> tuple[F64, F64, F64, F64]:
        n_con = len(self.spec.problem.constraints)
        arrays = getattr(self.algorithm, "arrays", None)
        if arrays is not None:  # an array-based algorithm: no pymoo Population needed
            return (self.box.decode(arrays.X), np.array(arrays.F, dtype=np.float64),
                    np.array(arrays.G, dtype=np.float64).reshape(len(arrays), n_con), arrays.cv.copy())
        pop = None if self.algorithm is None else self.algorithm.pop
        if pop is None or len(pop) == 0:
            n = self.start.mechanism.n_params
            return np.zeros((0, n)), np.zeros((0, self.spec.problem.n_obj)), np.zeros((0, n_con)), np.zeros(0)
        X = self.box.decode(pop.get("X"))
        F = np.array(pop.get("F"), dtype=np.float64)
        G = np.array(pop.get("G"), dtype=np.float64).reshape(len(pop), n_con)
        cv = np.maximum(G, 0.0).sum(axis=1)
        return X, F, G, cv

    def result(self) -> StageResult:
        """The current population as a :class:`StageResult` (partial unless complete/stopped)."""
        if self._cached is not None:
            return self._cached
        X, F, G, cv = self._population()
        t = time.perf_counter()
        metrics = self.problem.metrics(X)
        t_metrics = time.perf_counter() - t
        n_evals = 0 if self.algorithm is None else int(self.algorithm.evaluator.n_eval)
        self._cached = StageResult(
            name=self.spec.name,
            index=self.index,
            mechanism=self.start.mechanism,
            output=self.start.output,
            objectives=self.spec.problem.objectives,
            constraints=self.spec.problem.constraint_names,
            X=X,
            F=F,
            G=G,
            cv=cv,
            metrics=metrics,
            shortlist=decision.shortlist(F, cv),
            box=self.box,
            settings=self.spec.to_dict(),
            seed=self.spec.seed,
            status=self.status,
            generation=self.generation,
            n_gen=self.spec.n_gen,
            n_evals=n_evals,
            timings={"total": self.elapsed, "generations": list(self.times[1:]), "setup": self.times[0] if self.times
                     else 0.0, "metrics": t_metrics},
            versions=versions(),
            parent_pick=self.parent_pick,
            trace=tuple(dict(row) for row in getattr(self.algorithm, "trace", ())),
        )
        return self._cached


def _reached(F: F64, cv: F64, limits: Iterable[float]) -> bool:
    ok = decision.usable(F, cv)
    return bool((ok & (F <= np.asarray(tuple(limits))).all(axis=1)).any())
