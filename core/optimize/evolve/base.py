"""``ArrayAlgorithm``: a pymoo ``Algorithm`` whose generation loop runs on arrays.

Subclasses implement ``_initialize_advance`` and ``_advance`` with :meth:`evaluate` and set
``self.arrays``; pymoo's ``pop`` and ``opt`` are built from those arrays only when something reads
them (the API boundary: ``minimize``'s result, a callback), so a generation pays no per-member
Python objects. Evaluations are counted on pymoo's evaluator, so ``("n_eval", k)`` terminations hold.
"""

from __future__ import annotations

import numbers
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymoo.core.algorithm import Algorithm
from pymoo.core.evaluator import Evaluator
from pymoo.core.individual import Individual
from pymoo.core.population import Population

F64 = NDArray[np.float64]
EQ_EPS = float(Individual.default_config()["cv_eq"]["eps"])  # pymoo's tolerance on an equality constraint (1e-4)


@dataclass(frozen=True)
class Arrays:
    """A population as arrays: X ``(n, d)``, F ``(n, m)``, G ``(n, k)``, cv ``(n,)`` (sum of positive G).

    G holds the problem's inequality constraints, then each equality constraint h as ``|h| - EQ_EPS``: the
    violation pymoo counts for it, and a column the per-constraint algorithms (MCCMO) read like any other.
    """

    X: F64
    F: F64
    G: F64
    cv: F64

    def __len__(self) -> int:
        return int(self.X.shape[0])

    def take(self, idx: NDArray[Any]) -> Arrays:
        return Arrays(self.X[idx], self.F[idx], self.G[idx], self.cv[idx])

    @staticmethod
    def concat(*parts: Arrays) -> Arrays:
        return Arrays(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("X", "F", "G", "cv")))

    def population(self, n_ieq: int | None = None, extra: dict[str, F64] | None = None) -> Population:
        """The pymoo Population of these members (F, G, CV and feasibility set as pymoo reads them). With
        ``n_ieq``, the columns of G past it are equality constraints: H gets |h| (its sign is not kept). ``extra``:
        more per-member values by name (NSGA-II's ``rank`` and ``crowding``, as pymoo's sets them)."""
        n_ieq = self.G.shape[1] if n_ieq is None else n_ieq
        G, H = self.G[:, :n_ieq], self.G[:, n_ieq:] + EQ_EPS
        more = [v for k, a in (extra or {}).items() for v in (k, a)]
        pop = Population.new("X", self.X, "F", self.F, "G", G, "H", H, *more)
        cv = self.cv[:, None]
        for ind, c in zip(pop, cv, strict=True):
            ind._CV = c
            ind.evaluated.update(("F", "G", "H", "CV"))
        return pop


class Trace(list[dict[str, float]]):
    """The per-generation trace rows (each written once, never changed): a deep copy (pymoo's ``save_history`` takes
    one of the algorithm each generation) shares the rows, so a snapshot costs a pointer per row, not a dict copy
    (which made a 600-generation run with its history ~2x slower: quadratic in the generations)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> Trace:
        twin = memo[id(self)] = Trace(self)
        return twin


class Initialization:
    """Holds the initial sample: ``sampling`` may be an ``(n, d)`` array (the stage sets one) or None."""

    def __init__(self) -> None:
        self.sampling: F64 | None = None


class _AskTell:
    """pymoo's ask-and-tell on an array algorithm: a generation runs in a worker thread, and each evaluation it
    makes is handed out by ``ask`` and waits for ``tell``. A generation may evaluate more than once (CMOEMT's and
    MOEA/D-CMT's children in batches, CMOES's two populations): it ends at the ``tell`` after its last one."""

    def __init__(self) -> None:
        self.to_user: queue.Queue[tuple[str, Any]] = queue.Queue()
        self.to_worker: queue.Queue[tuple[F64, F64, F64]] = queue.Queue()
        self.worker: threading.Thread | None = None
        self.pending: F64 | None = None  # the members ask() handed out, not told yet
        self.counted = 0  # the evaluator's count when they were handed out

    def start(self, generation: Any) -> None:
        def work() -> None:
            try:
                generation()
                self.to_user.put(("done", None))
            except BaseException as e:  # noqa: BLE001 - raised again in the caller's thread
                self.to_user.put(("error", e))

        self.worker = threading.Thread(target=work, name="ask-tell generation", daemon=True)
        self.worker.start()

    def request(self) -> F64 | None:
        """The worker's next members to evaluate, or None when its generation ended."""
        kind, value = self.to_user.get()
        if kind == "eval":
            return value
        self.worker = None
        if kind == "error":
            raise value
        return None


PYMOO_KEYWORDS = frozenset({"termination", "output", "display", "callback", "archive", "return_least_infeasible",
                            "save_history", "verbose", "seed", "evaluator"})
"""The keywords pymoo's ``Algorithm`` itself takes."""


class ArrayAlgorithm(Algorithm):
    """Base of the array-based algorithms. ``self.arrays`` is the current (output) population."""

    is_initialized: bool
    # Its registry name (in messages) and the population it needs: checked once, here, for every subclass.
    NAME, MIN_POP, EVEN_POP = "array algorithm", 1, False
    max_fe: int  # the budget a subclass schedules over (see budget())

    def __init__(self, pop_size: int = 100, repair: Any = None, sampling: F64 | None = None, **kwargs: Any) -> None:
        # pymoo's Algorithm swallows any keyword: `popsize=20` ran at 100 and `crossover=SBX(...)` did nothing
        # (EMO rehearsal, session 33). Only its own are passed on; `sampling` is an (n, d) array of first members.
        unknown = sorted(set(kwargs) - PYMOO_KEYWORDS)
        if unknown:
            raise TypeError(f"{type(self).__name__} takes no keyword {', '.join(map(repr, unknown))}: its options are "
                            "its own constructor's (see its docstring and docs/algorithms.md), and pymoo's "
                            f"{', '.join(sorted(PYMOO_KEYWORDS))}")
        if sampling is not None and not isinstance(sampling, np.ndarray):
            raise TypeError(f"{type(self).__name__}'s sampling is an (n, d) array of first members, not a pymoo "
                            f"{type(sampling).__name__}: pass sampling.do(problem, n).get('X')")
        self._arrays: Arrays | None = None
        self._pop_cache: Population | None = None
        self._opt_cache: Population | None = None
        super().__init__(**kwargs)
        self.pop_size = population_size(self.NAME, pop_size, self.MIN_POP, self.EVEN_POP)
        self.repair = repair
        self.initialization = Initialization()
        self.initialization.sampling = sampling
        self.trace: list[dict[str, float]] = Trace()
        self._asktell: _AskTell | None = None

    def setup(self, problem: Any, verbose: bool = False, progress: bool = False, **kwargs: Any) -> Algorithm:
        """pymoo's setup, with pymoo's progress table for ``minimize(..., verbose=True)`` (none was set)."""
        if getattr(self, "output", None) is None:
            from pymoo.util.display.multi import MultiObjectiveOutput
            from pymoo.util.display.single import SingleObjectiveOutput

            self.output = SingleObjectiveOutput() if problem.n_obj == 1 else MultiObjectiveOutput()
        return super().setup(problem, verbose=verbose, progress=progress, **kwargs)

    def ask(self) -> Population | None:
        """pymoo's ask: the next members to evaluate, as a Population of X (None once terminated). Evaluate them
        (``algorithm.evaluator.eval(problem, pop)``, or by any means that sets F, and G and H if the problem has
        constraints) and pass them to :meth:`tell`. Asking again before telling gives the same members.

        A generation runs in a worker thread that waits at each evaluation: the same seed gives the same result
        as ``minimize``, and a generation that evaluates twice (CMOES, CMOEMT) asks twice."""
        at = self._asktell = self._asktell or _AskTell()
        while at.pending is None:
            if at.worker is None:  # else a generation is still on (a tell() interrupted by Ctrl-C): wait for it
                if not self.has_next():
                    return None
                at.start(super().next)  # pymoo's next: its first call starts the clock, then advance()
            at.pending = at.request()
            at.counted = self.evaluator.n_eval
        return Population.new("X", at.pending)

    def next(self) -> None:
        """pymoo's next (one generation, evaluated through the problem); refused while ask-and-tell has a
        generation half done (it ran a second one beside it: review of session 33)."""
        at = self._asktell
        if at is not None and at.worker is not None:
            raise RuntimeError(f"{type(self).__name__}: a generation is waiting for tell(); tell it the members "
                               "ask() gave before next() or run()")
        super().next()

    def tell(self, infills: Any = None, **kwargs: Any) -> Any:
        """pymoo's tell: the members :meth:`ask` gave, evaluated. Returns the result once terminated, else None."""
        at = self._asktell
        if at is None or at.pending is None:
            raise ValueError(f"{type(self).__name__}.tell takes the population ask() gave: ask first")
        n = len(at.pending)
        if infills is None or len(infills) != n:
            raise ValueError(f"tell takes the {n} members ask() gave, got {0 if infills is None else len(infills)}")
        p = self.problem
        F, G, H = (_told(infills, key, n, k) for key, k in (("F", p.n_obj), ("G", p.n_ieq_constr),
                                                             ("H", p.n_eq_constr)))
        X = _told(infills, "X", n, p.n_var)
        if X is None or not np.array_equal(X, at.pending):
            raise ValueError("tell takes the members ask() gave, in that order: their X differ from what ask() gave")
        missing = [f"{k} ({m} each)" for k, v, m in (("F", F, p.n_obj), ("G", G, p.n_ieq_constr),
                                                       ("H", H, p.n_eq_constr)) if v is None]
        if missing:
            raise ValueError(f"tell takes the members ask() gave, evaluated: {', '.join(missing)} missing or of "
                             f"another shape (the problem has {p.n_obj} objectives, {p.n_ieq_constr} inequality "
                             f"and {p.n_eq_constr} equality constraints)")
        assert F is not None and G is not None and H is not None
        if self.evaluator.n_eval == at.counted:  # not counted by algorithm.evaluator.eval: by another means
            self.evaluator.n_eval += n
        at.pending = None
        at.to_worker.put((F, G, H))
        at.pending = at.request()
        at.counted = self.evaluator.n_eval
        if at.pending is None and self.termination.has_terminated():
            return self.result()
        return None

    def __getstate__(self) -> dict[str, Any]:
        """Copies and pickles (``minimize`` deep-copies its algorithm) leave the ask-and-tell worker behind: between
        ``ask`` and ``tell`` a generation is half done in it, so that is refused."""
        at = self._asktell
        if at is not None and at.pending is not None:
            raise TypeError(f"{type(self).__name__} cannot be copied between ask() and tell(): tell first")
        return {**self.__dict__, "_asktell": None}

    # pymoo's pop/opt, built on demand from the arrays.
    @property
    def arrays(self) -> Arrays | None:
        return self._arrays

    @arrays.setter
    def arrays(self, value: Arrays | None) -> None:
        self._arrays = value
        self._pop_cache = self._opt_cache = None

    def member_values(self) -> dict[str, F64]:
        """Per-member values of the output population that pymoo's own algorithm sets on its members (none here)."""
        return {}

    @property
    def pop(self) -> Population | None:
        if self._pop_cache is None and self._arrays is not None:
            self._pop_cache = self._arrays.population(self.problem.n_ieq_constr, self.member_values())
        return self._pop_cache

    @pop.setter
    def pop(self, value: Population | None) -> None:
        self._pop_cache = value  # pymoo resets it to empty/None while initializing; the arrays stay the truth

    @property
    def opt(self) -> Population | None:
        if self._opt_cache is None and self._arrays is not None and len(self._arrays):
            idx = self.optimum_index()
            extra = {k: v[idx] for k, v in self.member_values().items()}
            self._opt_cache = self._arrays.take(idx).population(self.problem.n_ieq_constr, extra)
        return self._opt_cache

    @opt.setter
    def opt(self, value: Population | None) -> None:
        self._opt_cache = value

    def _set_optimum(self) -> None:
        self._opt_cache = None  # computed when read

    def optimum_index(self) -> NDArray[np.int64]:
        """The feasible non-dominated members of the output population (with one objective, the first best one,
        as pymoo's ``filter_optimum``: copies of the optimum are not a front), else the least infeasible ones."""
        from core.optimize.evolve.sorting import nd_ranks

        a = self._arrays
        assert a is not None
        feas = np.flatnonzero(a.cv <= 0.0)
        if feas.size and a.F.shape[1] == 1:
            return feas[[int(np.argmin(a.F[feas, 0]))]]
        if feas.size:
            return feas[nd_ranks(a.F[feas]) == 0]
        return np.flatnonzero(a.cv == a.cv.min())

    # Sampling, repair, evaluation.
    def initial_X(self) -> F64:
        s = self.initialization.sampling
        if s is not None and not isinstance(s, np.ndarray):
            raise TypeError("an array algorithm samples from an (n, d) array or uniformly (sampling=None)")
        if s is None:
            X = self.random_state.uniform(self.problem.xl, self.problem.xu, size=(self.pop_size, self.problem.n_var))
        else:
            X = np.asarray(s, dtype=np.float64)
        return self.repaired(X)

    def repaired(self, X: F64) -> F64:
        if self.repair is None or len(X) == 0:
            return X
        return np.asarray(self.repair._do(self.problem, X), dtype=np.float64)

    def evaluate(self, X: F64) -> Arrays:
        """Evaluate ``(n, d)`` members through the problem, counted on pymoo's evaluator (under ask-and-tell, by
        whoever evaluates what ask() handed out)."""
        X = np.asarray(X, dtype=np.float64)
        n = len(X)
        if n == 0:
            p = self.problem
            return Arrays(X.reshape(0, p.n_var), np.zeros((0, p.n_obj)), np.zeros((0, p.n_ieq_constr + p.n_eq_constr)),
                          np.zeros(0))
        at = self._asktell
        if at is not None and at.worker is threading.current_thread():
            at.to_user.put(("eval", X))
            return _arrays(X, *at.to_worker.get())
        ev = self.evaluator
        if type(ev) is not Evaluator or ev.callback is not None:  # a user's evaluator (spec §1.8): through it
            pop = ev.eval(self.problem, Population.new("X", X), algorithm=self)
            p = self.problem
            told = [_told(pop, k, n, m) for k, m in (("F", p.n_obj), ("G", p.n_ieq_constr), ("H", p.n_eq_constr))]
            if any(v is None for v in told):
                raise ValueError(f"{type(ev).__name__}.eval left members without F, G or H of the problem's shapes")
            return _arrays(X, *told)  # type: ignore[arg-type]
        out = self.problem.evaluate(X, return_as_dictionary=True, algorithm=self)  # as pymoo's algorithms pass it
        F = np.asarray(out["F"], dtype=np.float64).reshape(n, -1)
        G = np.asarray(out.get("G", np.zeros((n, 0))), dtype=np.float64).reshape(n, -1)
        H = np.asarray(out.get("H", np.zeros((n, 0))), dtype=np.float64).reshape(n, -1)
        self.evaluator.n_eval += n
        return _arrays(X, F, G, H)

    def budget(self, per_generation: int, initial: int) -> int:
        """The evaluations this run may spend, which schedules such as an epsilon need: the ``n_eval``
        termination's, or generations x ``per_generation`` plus the ``initial`` population(s) for an ``n_gen`` one;
        of several, the first to end (a collection, ``TerminateIfAny``, pymoo's default termination's caps) or the
        last (``TerminateIfAll``). A time termination in it is estimated again before each generation from the
        evaluations per second so far (:meth:`rebudget`); with nothing to go by, 100 generations."""
        self._per_generation, self._initial = per_generation, initial
        known = _evaluations(self.termination, per_generation, initial)
        return int(initial + 100 * per_generation) if known is None else known

    def rebudget(self) -> None:
        """Under a termination with a time in it: the budget estimated again, each time counted as the evaluations
        it allows at the evaluations per second so far (a schedule spans the run's time; with ``TerminateIfAny``
        of a time and a generation count, whichever ends first), then :meth:`budget_changed`."""
        per = getattr(self, "_per_generation", None)
        if per is None or self.start_time is None or not _timed(self.termination):
            return
        n_eval = int(self.evaluator.n_eval)
        spent = time.time() - self.start_time

        def at(seconds: float) -> int:  # the evaluations by then; all spent once the time is up
            return int(n_eval / min(max(spent / seconds, 1e-9), 1.0))

        est = _evaluations(self.termination, per, self._initial, at)
        if est is not None:
            self.max_fe = max(est, n_eval + per)
            self.budget_changed()

    def budget_changed(self) -> None:
        """Recompute what a subclass derives from ``max_fe`` (CMOES's generations, CMOEMT's Tc)."""

    def log(self, **values: float) -> None:
        """Append this generation's trace row (generation and evaluations added)."""
        self.trace.append({"gen": float(self.n_iter or 0), "n_eval": float(self.evaluator.n_eval), **values})

    # pymoo's loop: everything happens in advance(), nothing is handed to pymoo's evaluator.
    def advance(self, infills: Any = None, **kwargs: Any) -> Any:
        """pymoo's ``Algorithm.advance`` without building ``opt`` for its return value every generation
        (it returns the result once terminated, else None; an ask/tell user reads ``opt`` when needed)."""
        self.off = infills
        if not self.is_initialized:
            self.n_iter = 1
            self._initialize_advance(infills=infills, **kwargs)
            self.is_initialized = True
            self._post_advance()
        else:
            self.rebudget()
            val = self._advance(infills=infills, **kwargs)
            if val is None or val:
                self._post_advance()
        if self.termination.has_terminated():
            self.finalize()
            return self.result()
        return None

    def _initialize_infill(self) -> None:
        return None

    def _infill(self) -> None:
        return None


def population_size(name: str, value: Any, minimum: int, even: bool = False) -> int:
    """``value`` as an algorithm's population size: a whole number (20.0, as JSON may write it, is 20) of at least
    ``minimum``, even if asked; anything else (20.5, "20", True, nan) refused, naming the algorithm."""
    whole = not isinstance(value, bool) and isinstance(value, numbers.Real) and float(value).is_integer()
    n = int(value) if whole else None
    if n is None or n < minimum or (even and n % 2):
        raise ValueError(f"{name} needs {'an even population' if even else 'a population'} of at least {minimum}, "
                         f"got {value!r}")
    return n


def largest_violation(*cvs: F64) -> float:
    """The largest finite violation among ``cvs`` (0 if none): where an epsilon schedule starts. An undefined
    member's infinite violation sets no level (an infinite start made epsilon inf, then NaN: session 33)."""
    cv = np.concatenate(cvs) if cvs else np.zeros(0)
    finite = cv[np.isfinite(cv)]
    return float(finite.max()) if len(finite) else 0.0


def _told(pop: Any, key: str, n: int, k: int) -> F64 | None:
    """``(n, k)`` values of ``key`` from a told population, None where they are missing or of another shape."""
    if k == 0:
        return np.zeros((n, 0))
    try:
        v = np.asarray(pop.get(key), dtype=np.float64)
    except (TypeError, ValueError):  # None for members nobody evaluated
        return None
    return v.reshape(n, k) if v.size == n * k else None


def _arrays(X: F64, F: F64, G: F64, H: F64) -> Arrays:
    """Evaluated members as Arrays: each equality constraint h a column |h| - EQ_EPS of G, cv the sum of positive G
    (NaN read as +inf)."""
    if H.shape[1]:
        G = np.concatenate([G, np.abs(H) - EQ_EPS], axis=1)
    with np.errstate(invalid="ignore"):
        cv = np.maximum(G, 0.0).sum(axis=1)
    cv = np.where(np.isnan(cv), np.inf, cv)
    return Arrays(X, F, G, cv)


def _evaluations(t: Any, per_generation: int, initial: int, at: Callable[[float], int] | None = None) -> int | None:
    """The evaluations termination ``t`` allows (generations counted as ``initial`` then ``per_generation`` each),
    None if it sets no such limit (a tolerance; a time unless ``at`` converts seconds into evaluations)."""
    evals, gens = getattr(t, "n_max_evals", None), getattr(t, "n_max_gen", None)
    if evals is not None:  # pymoo's defaults are inf: no limit (int(inf) raised)
        return int(evals) if np.isfinite(evals) else None
    if gens is not None:
        return int(initial + (int(gens) - 1) * per_generation) if np.isfinite(gens) else None
    if getattr(t, "max_time", None) is not None:
        return at(float(t.max_time)) if at is not None else None
    inner = getattr(t, "termination", None)  # RobustTermination: its inner one's limit, held for its window
    if inner is not None:
        b = _evaluations(inner, per_generation, initial, at)
        history = getattr(t, "history", None)
        window = getattr(history, "size", 1) if history is not None else 1
        if window is None:  # period=None: the minimum over the whole run, which never reaches the end
            return None
        return None if b is None else b + (int(window) - 1) * per_generation
    parts = _parts(t)
    if not parts:
        return None
    known = [b for b in (_evaluations(c, per_generation, initial, at) for c in parts) if b is not None]
    if type(t).__name__ == "TerminateIfAll":  # the last to end: every part must have a limit
        return max(known) if len(known) == len(parts) else None
    return min(known) if known else None  # the first to end


def _timed(t: Any) -> bool:
    """Whether a time termination is in ``t``."""
    if getattr(t, "max_time", None) is not None:
        return True
    inner = getattr(t, "termination", None)
    return any(_timed(c) for c in ([inner] if inner is not None else _parts(t)))


def _parts(t: Any) -> list[Any]:
    """The terminations a combined one holds: a TerminationCollection's, TerminateIfAny/All's and pymoo's default
    termination's criteria; none for a single one."""
    return list(getattr(t, "terminations", None) or getattr(t, "criteria", None) or [])
