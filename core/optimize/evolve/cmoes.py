"""CMOES (Ming, Gong, Jin, IEEE/CAA JAS 11(2), 2024) on arrays, as the spec (§3) describes PlatEMO's version.

Stage 1 (no feasible member yet, or the first 20 % of the generations): an NSGA-II-CDP main population (P1)
and an unconstrained SPEA2 helper (P2) share their offspring. Stage 2: a SPEA2-CDP main population and two
helpers confined to the *promising region* (what no feasible member of P1 dominates): P2 keeps the region's
unconstrained non-dominated members, P3 its members with CV <= maxCV (1 - tau)^2. Evaluations per generation:
3N in stage 1 (GA mode: P1's 2N children and P2's N), N + |P2| + |P3| in stage 2; 2N initially.

Decisions (docs/algorithms.md): on entering stage 2, the helpers returned by EvenSearch are adopted (PlatEMO
keeps the old ones with the new fitness values, misaligned for one generation; spec pitfall 2); the region is
judged against the feasible members of the *updated* P1 (PlatEMO applies the previous P1's mask; pitfall 3).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.base import ArrayAlgorithm, Arrays, largest_violation
from core.optimize.evolve.nsga2 import rank_and_crowding
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.variation import de_rand_1, ga

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
STAGE1_SHARE = 0.2


def in_region(F: F64, R: F64) -> NDArray[np.bool_]:
    """``(n,)`` True where no row of R (the feasible members of P1) Pareto-dominates the row of F; all True
    when R is empty. A member equal to one of R is in."""
    F = np.where(np.isnan(F), np.inf, np.asarray(F, dtype=np.float64))
    if len(R) == 0 or len(F) == 0:
        return np.ones(len(F), dtype=bool)
    return _in_region(np.ascontiguousarray(F), np.ascontiguousarray(np.asarray(R, dtype=np.float64).T))


@numba.njit(cache=True)
def _in_region(F: F64, RT: F64) -> NDArray[np.bool_]:  # pragma: no cover - compiled
    # Per member, how many objectives of each R row (RT is (m, k)) are <= and < its own, counted over R's
    # contiguous columns (the loops vectorize; stopping at the first dominating row did not): dominated where
    # a row has all m <= and at least one <. A NaN in R is never <=, so never dominates.
    n, m = F.shape
    k = RT.shape[1]
    out = np.ones(n, dtype=np.bool_)
    le = np.empty(k, dtype=np.int32)
    lt = np.empty(k, dtype=np.int32)
    for i in range(n):
        le[:], lt[:] = 0, 0
        for q in range(m):
            f, row = F[i, q], RT[q]
            for r in range(k):
                le[r] += row[r] <= f
                lt[r] += row[r] < f
        hit = 0
        for r in range(k):
            hit += (le[r] == m) & (lt[r] > 0)
        out[i] = hit == 0
    return out


def even_search(pool: Arrays, R: F64, n: int, tau: float, max_cv: float,
                cuts: spea2.Cuts | None = None) -> tuple[Arrays, F64, Arrays, F64, int]:
    """EvenSearch (spec §3): P2 (the region's unconstrained non-dominated members, at most n, not filled up),
    their fitness; P3 (the region's members with CV <= maxCV (1 - tau)^2, at most n), their CV; and |Q|.
    ``cuts``: truncations made earlier in the generation (P1's selection, when its members are the same)."""
    Q = pool.take(np.flatnonzero(in_region(pool.F, R)))
    nd, fit, _ = spea2.select(Q.F, n, fill=False, cuts=cuts)
    ok = np.flatnonzero(Q.cv <= max_cv * (1.0 - tau) ** 2)
    if len(ok) > n:
        ok = ok[spea2.truncate(Q.F[ok], n, cuts)]
    return Q.take(nd), fit, Q.take(ok), Q.cv[ok], len(Q)


class CMOES(ArrayAlgorithm):
    """CMOES; the output population is the main one (P1).

    Args:
        pop_size: N.
        operator: ``ga`` (PlatEMO's type 1: SBX pc 1, eta_c 20; polynomial mutation 1/D, eta_m 20) or ``de``
            (type 2: DE/rand/1, F 0.5, CR 1, then polynomial mutation).
    """

    NAME, MIN_POP, EVEN_POP = "cmoes", 4, False

    def __init__(self, pop_size: int = 100, operator: str = "ga", **kwargs: Any) -> None:
        if operator not in ("ga", "de"):
            raise ValueError(f"cmoes operator must be 'ga' or 'de', got {operator!r}")
        super().__init__(pop_size=pop_size, **kwargs)
        self.variant = 1 if operator == "ga" else 2

    # Reproduction ------------------------------------------------------------------------------

    def _children(self, X: F64, keys: tuple[F64 | I64, ...], n_parents: int, half: bool) -> F64:
        """PlatEMO's GA/GAhalf on a tournament pool of ``n_parents`` (first half with second half), or in DE
        mode one child per member of X (in its stored order) with differences from the two pool halves."""
        rng = self.random_state
        if self.variant == 2:
            k = len(X)
            pool = tournament(keys, 2 * k, rng)
            return de_rand_1(X, X[pool[:k]], X[pool[k:]], self.xl, self.xu, rng)
        pool = tournament(keys, n_parents, rng)
        h = n_parents // 2
        return ga(X[pool[:h]], X[pool[h : 2 * h]], self.xl, self.xu, rng, half=half)

    # The loop ------------------------------------------------------------------------------------

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, p = self.pop_size, self.problem
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        p1 = self.evaluate(self.initial_X())
        p2 = self.evaluate(self.repaired(self.random_state.uniform(self.xl, self.xu, size=(n, p.n_var))))
        self.max_fe = self.budget(3 * n, 2 * n)
        self.budget_changed()
        order, self.front, self.crowd = rank_and_crowding(p1, n)
        self.arrays = p1.take(order)
        self.p2, self.fit2 = p2, spea2.fitness(p2.F)
        self.p3, self.key3 = self.arrays, self.arrays.cv.copy()
        self.fit1 = spea2.fitness(self.arrays.F, self.arrays.cv)
        self.max_cv = largest_violation(p1.cv, p2.cv)
        self.stage2 = False
        self._log(1, 0.0, float("nan"), len(self.arrays), 0)

    def budget_changed(self) -> None:
        self.max_gen = math.ceil(self.max_fe / self.pop_size)

    def _log(self, stage: int, tau: float, eps: float, q: int, fe: int) -> None:
        p1 = self.arrays
        assert p1 is not None
        self.log(stage=float(stage), tau=tau, eps=eps, max_cv=self.max_cv, R=float((p1.cv <= 0).sum()),
                 Q=float(q), P2=float(len(self.p2)), P3=float(len(self.p3)), fe_generation=float(fe),
                 feasible_ratio_P1=float((p1.cv <= 0).mean()),
                 feasible_ratio_P2=float((self.p2.cv <= 0).mean()) if len(self.p2) else float("nan"))

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        n = self.pop_size
        p1 = self.arrays
        assert p1 is not None
        gen = math.ceil(self.evaluator.n_eval / n)
        if not self.stage2 and ((p1.cv <= 0).sum() == 0 or gen <= STAGE1_SHARE * self.max_gen):
            self._stage1(p1, n)
        else:
            self._stage2(p1, n, gen)

    def _stage1(self, p1: Arrays, n: int) -> None:
        o1 = self._children(p1.X, (self.front, -self.crowd), 2 * n, half=False)
        o2 = self._children(self.p2.X, (self.fit2,), 2 * n, half=True)
        off = self.evaluate(self.repaired(np.vstack([o1, o2])))
        pool1 = Arrays.concat(p1, off)
        order, self.front, self.crowd = rank_and_crowding(pool1, n)
        self.arrays = pool1.take(order)
        pool2 = Arrays.concat(self.p2, off)
        order2, self.fit2, _ = spea2.select(pool2.F, n, None)
        self.p2 = pool2.take(order2)
        self.p3, self.key3 = self.p2, self.p2.cv.copy()
        self.max_cv = max(self.max_cv, largest_violation(self.arrays.cv, self.p2.cv))
        self._log(1, 0.0, float("nan"), len(self.arrays), len(off))

    def _stage2(self, p1: Arrays, n: int, gen: int) -> None:
        tau = min(gen / self.max_gen, 1.0)
        union = Arrays.concat(p1, self.p2, self.p3)
        self.max_cv = largest_violation(union.cv)
        if not self.stage2:
            self.p2, self.fit2, self.p3, self.key3, _ = even_search(union, p1.F[p1.cv <= 0], n, tau, self.max_cv)
            self.fit1 = spea2.fitness(p1.F, p1.cv)
            self.stage2 = True
        parts = [self._children(p1.X, (self.fit1,), 2 * n, half=True)]
        if len(self.p2):
            parts.append(self._children(self.p2.X, (self.fit2,), 2 * len(self.p2), half=True))
        if len(self.p3):
            parts.append(self._children(self.p3.X, (self.key3,), 2 * len(self.p3), half=True))
        off = self.evaluate(self.repaired(np.vstack(parts)))
        pool = Arrays.concat(union, off)
        cuts: spea2.Cuts = {}
        order, self.fit1, _ = spea2.select(pool.F, n, pool.cv, cuts=cuts)
        self.arrays = pool.take(order)
        R = self.arrays.F[self.arrays.cv <= 0]
        self.p2, self.fit2, self.p3, self.key3, q = even_search(pool, R, n, tau, self.max_cv, cuts)
        self._log(2, tau, self.max_cv * (1.0 - tau) ** 2, q, len(off))
