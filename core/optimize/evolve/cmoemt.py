"""CMOEMT (Ming, Gong, Wang, Gao, IEEE TEVC 28(1), 2024) on arrays, as the spec (§2) describes PlatEMO's version.

Three tasks: the main one (P1, the output; SPEA2 under constraint domination), an epsilon-relaxed MOEA/D task
(P2; DE children evaluated and placed one at a time by Tchebycheff replacement, first ignoring constraints
(push), then under an improved epsilon rule (pull) once P2's ideal and nadir points stop moving), and an
unconstrained SPEA2 task (P3). First half of the budget: P1 and P3 select from themselves and all offspring;
second half: from all three populations and all offspring. 2N evaluations per generation (N/2 + N + N/2),
3N initially; the effective N is the number of Das-Dennis weight vectors.

Decisions (docs/algorithms.md): PlatEMO's version is the default; ``variant = "author_repo"`` takes the
authors' repository's two differences (task 2 selected by SPEA2 under epsilon-relaxed CDP instead of in-place
replacement; in the second half, P1 takes the other populations and offspring only from the auxiliary task
that contributed more survivors to a trial selection; P3 selects as in PlatEMO's version). The history
warm-up and the unreachable Tc are kept as in PlatEMO (spec pitfalls 2 and 4); epsilon's starting level is
the largest *finite* violation in P2 (an undefined member's infinite one would set no level at all).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.ahead import DE, Ahead, draw_pools, make_children, numbers, stale
from core.optimize.evolve.base import ArrayAlgorithm, Arrays, largest_violation
from core.optimize.evolve.moead import fmin_into, tchebycheff_replace
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.variation import ga
from core.optimize.evolve.weights import OnePerWeight, neighbours

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
DELTA, NR, ROUNDS, WINDOW, CHANGE, TAU, ALPHA, CP = 0.9, 2, 5, 20, 0.1, 0.05, 0.95, 2.0
VARIANTS = ("platemo", "author_repo")


def change_rate(ideal: dict[int, F64], nadir: dict[int, F64], gen: int) -> float:
    """PPS's change of P2's ideal and nadir points over the last 20 generations (history entries never written
    count as zeros, as in PlatEMO: spec pitfall 4)."""
    m = len(ideal[gen])
    zero = np.zeros(m)
    i0, n0 = ideal.get(gen - WINDOW + 1, zero), nadir.get(gen - WINDOW + 1, zero)
    with np.errstate(invalid="ignore"):
        a = np.abs(ideal[gen] - i0) / np.maximum(i0, 1e-6)
        b = np.abs(nadir[gen] - n0) / np.maximum(n0, 1e-6)
    r = float(np.nanmax(np.concatenate([a, b])))
    return r if math.isfinite(r) else math.inf


@numba.njit(cache=True)
def _place(j0: int, j1: int, pools: I64, offs: I64, X: F64, F: F64, G: F64, cv: F64, W: F64, z: F64, eps: float,
           pull: bool, replace: bool, YX: F64, YF: F64, YG: F64, Ycv: F64, stamps: I64, at: I64, pp: I64,
           pi: I64) -> int:  # pragma: no cover - compiled
    """Task 2's children ``j0 .. j1 - 1`` (rows of Y) in order: the ideal point ``z`` (in place), then Tchebycheff
    replacement (when ``replace``); returns the first child out of date (see :class:`~core.optimize.evolve.ahead.
    Ahead`), or ``j1``."""
    for j in range(j0, j1):
        if stale(j, at[j], pp, pi, stamps):
            return j
        fmin_into(z, YF[j])
        if replace:
            tchebycheff_replace(X, F, G, cv, W, pools[offs[j]:offs[j + 1]], YX[j:j + 1], YF[j:j + 1], YG[j:j + 1],
                                Ycv[j], z, eps, pull, NR, stamps[0], j + 1)
    return j1


class CMOEMT(OnePerWeight, ArrayAlgorithm):
    """CMOEMT; the output population is the main task's (P1).

    Args:
        pop_size: requested N (the effective N is the number of Das-Dennis vectors, e.g. 91 for 100 at M = 3).
        variant: ``platemo`` (default) or ``author_repo`` (see the module doc).
        ahead: make and evaluate task 2's children in one batch ahead of its sequential loop, with the same
            results (:mod:`core.optimize.evolve.ahead`); False evaluates them one at a time.
    """

    NAME, MIN_POP, EVEN_POP = "cmoemt", 10, False

    def __init__(self, pop_size: int = 100, variant: str = "platemo", ahead: bool = True, **kwargs: Any) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"cmoemt variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
        super().__init__(pop_size=pop_size, **kwargs)
        self.variant, self.ahead = variant, ahead

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        p, rng = self.problem, self.random_state
        self.W = self.weights(p.n_obj, "cmoemt")
        n = len(self.W)
        self.n = n
        self.B = neighbours(self.W, max(2, math.ceil(n / 10))) if p.n_obj > 1 else \
            (np.arange(n)[:, None] + np.arange(max(2, math.ceil(n / 10)))[None, :]) % n
        self.extremes = np.flatnonzero((self.W < 1e-3).sum(axis=1) == p.n_obj - 1)[: p.n_obj]
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        X1 = self.initial_X()[:n]
        if len(X1) < n:
            X1 = np.vstack([X1, rng.uniform(self.xl, self.xu, size=(n - len(X1), p.n_var))])
        p1 = self.evaluate(X1)
        p2 = self.evaluate(self.repaired(rng.uniform(self.xl, self.xu, size=(n, p.n_var))))
        p3 = self.evaluate(self.repaired(rng.uniform(self.xl, self.xu, size=(n, p.n_var))))
        self.P2 = Arrays(*(np.array(v) for v in (p2.X, p2.F, p2.G, p2.cv)))  # updated in place
        self.z = np.fmin.reduce(self.P2.F, axis=0)  # MATLAB's min skips NaN (fmin_into too, later)
        self.fit1, self.fit3 = spea2.fitness(p1.F, p1.cv), spea2.fitness(p3.F)
        self.p3 = p3
        self.arrays = p1
        self.max_fe = self.budget(2 * n, 3 * n)
        self.budget_changed()
        self.pull, self.eps, self.eps0, self.r = False, 0.0, 0.0, math.inf
        self.ideal: dict[int, F64] = {}
        self.nadir: dict[int, F64] = {}
        self.log(pull=0.0, eps=0.0, eps0=0.0, rf=float((self.P2.cv <= 1e-6).mean()), r=math.inf, transfer=0.0,
                 feasible_ratio_P1=float((p1.cv <= 0).mean()), feasible_ratio_P2=float((self.P2.cv <= 0).mean()),
                 feasible_ratio_P3=float((p3.cv <= 0).mean()))

    def budget_changed(self) -> None:
        self.Tc = 0.9 * math.ceil(self.max_fe / self.n)

    # Task 2: MOEA/D with push and pull -------------------------------------------------------------

    def _epsilon(self, gen: int) -> None:
        rf = float((self.P2.cv <= 1e-6).mean())
        self.ideal[gen] = self.z.copy()
        self.nadir[gen] = self.P2.F.max(axis=0)
        if gen >= WINDOW:
            self.r = change_rate(self.ideal, self.nadir, gen)
        if gen < self.Tc:
            if self.r <= CHANGE and not self.pull:
                self.pull = True
                self.eps0 = largest_violation(self.P2.cv)
                self.eps = self.eps0
            if self.pull:
                self.eps = (1 - TAU) * self.eps if rf < ALPHA else self.eps0 * (1 - gen / self.Tc) ** CP
        else:
            self.eps = 0.0
        self.rf = rf

    def _subset(self) -> I64:
        n, rng = self.n, self.random_state
        fixed = np.concatenate([self.extremes, [n // 2 - 1 if n >= 2 else 0]]).astype(np.int64)
        k = n // 5
        extra = rng.integers(0, n, max(k - len(fixed), 0))
        return np.concatenate([fixed, extra])[: max(k, 1)]

    def _draw(self) -> tuple[I64, I64, I64, I64, F64]:
        """Task 2's children's numbers, in the published loop's order: per round the subproblems, then per child
        its pool (neighbourhood or population, permuted) and its DE numbers. Returns the pools (flat, offsets), the
        parents (population 0 = P2; member: the subproblem's, then the pool's first two) and the numbers."""
        rng, n, d = self.random_state, self.n, self.problem.n_var
        subsets: list[I64] = []
        flats: list[I64] = []
        ends = [np.zeros(1, dtype=np.int64)]
        nums = np.empty((ROUNDS * max(n // 5, 1), numbers(DE, d)))
        m = 0
        for _ in range(ROUNDS):
            members = self._subset()
            flat, offs = draw_pools(rng, self.B, members, n, DELTA, nums[m : m + len(members)])
            ends.append(offs[1:] + ends[-1][-1])
            subsets.append(members)
            flats.append(flat)
            m += len(members)
        base, flat, offs = np.concatenate(subsets), np.concatenate(flats), np.concatenate(ends)
        pp = np.zeros((m, 3), dtype=np.int64)
        pi = np.stack([base.astype(np.int64), flat[offs[:-1]], flat[offs[:-1] + 1]], 1)
        return flat, offs, pp, pi, nums[:m]

    def _task2(self) -> tuple[Arrays, int]:
        n, P = self.n, self.P2
        flat, offs, pp, pi, nums = self._draw()
        m = len(pi)
        stamps = np.zeros((1, n), dtype=np.int64)
        replace = self.variant != "author_repo"  # the author's variant selects task 2 with the others below

        def make(ks: I64) -> F64:
            return make_children(DE, ks, pp, pi, P.X, P.X, nums, nums, nums, self.xl, self.xu)

        def place(j0: int, j1: int, Y: Arrays, at: I64) -> int:
            return int(_place(j0, j1, flat, offs, P.X, P.F, P.G, P.cv, self.W, self.z, float(self.eps),
                              bool(self.pull), replace, Y.X, Y.F, Y.G, Y.cv, stamps, at, pp, pi))

        return Ahead(self, self.ahead).run(m, pp, pi, stamps, make, place)

    # The loop ------------------------------------------------------------------------------------

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, rng = self.n, self.random_state
        p1 = self.arrays
        assert p1 is not None
        gen = math.ceil(self.evaluator.n_eval / (2 * n))
        self._epsilon(gen)
        transfer = self.evaluator.n_eval >= self.max_fe / 2
        h = n // 2
        pool1 = tournament((self.fit1,), 2 * h, rng)
        o1 = self.evaluate(self.repaired(ga(p1.X[pool1[:h]], p1.X[pool1[h:]], self.xl, self.xu, rng, half=True)))
        o2, missed = self._task2()
        mates3 = tournament((self.fit3,), 2 * h, rng)
        o3 = self.evaluate(self.repaired(ga(self.p3.X[mates3[:h]], self.p3.X[mates3[h:]], self.xl, self.xu, rng,
                                           half=True)))
        P2 = Arrays(*(np.array(v) for v in (self.P2.X, self.P2.F, self.P2.G, self.P2.cv)))
        if self.variant == "author_repo":
            P2 = self._select_task2(P2, o2)
        offspring = Arrays.concat(o1, o2, o3)
        if not transfer:
            pool = Arrays.concat(p1, offspring)
            sources = np.repeat([0, 3, 4, 5], [len(p1), len(o1), len(o2), len(o3)])
        elif self.variant == "author_repo":
            pool, sources = self._trial(p1, P2, o1, o2, o3)
        else:
            pool = Arrays.concat(p1, P2, self.p3, offspring)
            sources = np.repeat([0, 1, 2, 3, 4, 5], [len(p1), len(P2), len(self.p3), len(o1), len(o2), len(o3)])
        cuts: spea2.Cuts = {}  # all feasible: P1's and P3's selections cut the same members
        order, self.fit1, _ = spea2.select(pool.F, n, pool.cv, cuts=cuts)
        new1 = pool.take(order)
        if not transfer:
            pool3 = Arrays.concat(self.p3, offspring)
        else:  # P3 selects with the P1 just selected (PlatEMO assigns in order: spec pitfall 7)
            pool3 = Arrays.concat(new1, P2, self.p3, offspring)
        order3, self.fit3, _ = spea2.select(pool3.F, n, None, cuts=cuts)
        self.p3 = pool3.take(order3)
        self.arrays = new1
        if self.variant == "author_repo":
            self.P2 = P2
        came = np.bincount(sources[order], minlength=6).astype(float)
        self.log(pull=float(self.pull), eps=self.eps, eps0=self.eps0, rf=self.rf, r=self.r, transfer=float(transfer),
                 feasible_ratio_P1=float((new1.cv <= 0).mean()), feasible_ratio_P2=float((self.P2.cv <= 0).mean()),
                 feasible_ratio_P3=float((self.p3.cv <= 0).mean()), from_P1=came[0], from_P2=came[1],
                 from_P3=came[2], from_O1=came[3], from_O2=came[4], from_O3=came[5],
                 evaluated_ahead_unused=float(missed))

    # The authors' repository's variant -------------------------------------------------------------

    def _select_task2(self, P2: Arrays, o2: Arrays) -> Arrays:
        """Task 2 by SPEA2 under epsilon-relaxed constraint domination (every CV <= epsilon counts as 0)."""
        pool = Arrays.concat(P2, o2)
        relaxed = np.where(pool.cv <= self.eps, 0.0, pool.cv)
        order, _, _ = spea2.select(pool.F, self.n, relaxed)
        return pool.take(order)

    def _trial(self, p1: Arrays, P2: Arrays, o1: Arrays, o2: Arrays, o3: Arrays) -> tuple[Arrays, I64]:
        """Second half: a trial selection over everything counts survivors from task 2 and task 3; P1 then takes
        population and offspring only from the task that contributed more."""
        trial = Arrays.concat(p1, o1, P2, o2, self.p3, o3)
        mask = spea2.survivors(trial.F, self.n, trial.cv)
        a = len(p1) + len(o1)
        from2 = int(mask[a : a + len(P2) + len(o2)].sum())
        from3 = int(mask[a + len(P2) + len(o2) :].sum())
        if from2 >= from3:
            pool = Arrays.concat(p1, o1, P2, o2)
            src = np.repeat([0, 3, 1, 4], [len(p1), len(o1), len(P2), len(o2)])
        else:
            pool = Arrays.concat(p1, o1, self.p3, o3)
            src = np.repeat([0, 3, 2, 5], [len(p1), len(o1), len(self.p3), len(o3)])
        return pool, src
