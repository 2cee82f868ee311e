"""MOEA/D-CMT (Chu, Ming, Gong, IEEE TEVC 29(3), 2025) on arrays, as the spec (§7) describes PlatEMO's code.

Two MOEA/D tasks share one set of weight vectors and compete for each generation's N children:
task 1 (Tchebycheff with a soft, logistic comparison of objective improvement and normalised violation,
whose sharpness follows P1's feasible ratio) reproduces by DE, task 2 (unconstrained PBI, theta 5) by
SBX; every child updates both populations at once (sequential replacement, one evaluation per child).
The task is drawn by roulette: equal odds for the first 30 % of the budget, then in proportion to each
task's cumulative reward (the share of its children that enter a SPEA2-CDP archive of size N), with a
floor. The output is the archive. N evaluations per generation, 2N initially.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.ahead import Ahead
from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.moead import cmt_differences, cmt_exponents, cmt_replace, pbi_replace
from core.optimize.evolve.variation import de_rand_1, ga
from core.optimize.evolve.weights import das_dennis, neighbours

F64 = NDArray[np.float64]
DELTA, NR, RMP, LEARN, P_MIN, S_OBJ, THETA = 0.9, 2, 0.2, 0.3, 0.1, 0.3, 5.0


def task_probabilities(rwd: F64, fe: int, max_fe: int) -> F64:
    if fe <= LEARN * max_fe or rwd.sum() <= 0:
        return np.array([0.5, 0.5])
    p = P_MIN / 2 + (1 - P_MIN) * rwd / rwd.sum()
    return p / p.sum()


class MOEADCMT(ArrayAlgorithm):
    """MOEA/D-CMT; the effective population is the number of Das-Dennis vectors (<= pop_size; all of it for
    one objective).

    Args:
        ahead: make and evaluate each generation's children in one batch ahead of the sequential loop, with the
            same results (:mod:`core.optimize.evolve.ahead`); False evaluates them one at a time.
    """

    def __init__(self, pop_size: int = 100, ahead: bool = True, **kwargs: Any) -> None:
        super().__init__(pop_size=pop_size, **kwargs)
        self.ahead = ahead

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        p = self.problem
        # One objective: N equal subproblems (the lattice would give one); DE needs two neighbours at least.
        self.W = das_dennis(self.pop_size, p.n_obj) if p.n_obj > 1 else np.ones((self.pop_size, 1))
        n = len(self.W)
        T = max(2, int(np.ceil(n / 10)))
        self.B = neighbours(self.W, T) if p.n_obj > 1 else (np.arange(n)[:, None] + np.arange(T)[None, :]) % n
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        X1 = self.initial_X()[:n]
        if len(X1) < n:
            X1 = np.vstack([X1, self.random_state.uniform(self.xl, self.xu, size=(n - len(X1), p.n_var))])
        self.P1 = self.evaluate(X1)
        self.P2 = self.evaluate(self.repaired(self.random_state.uniform(self.xl, self.xu, size=(n, p.n_var))))
        self.P1 = Arrays(*(np.array(v) for v in (self.P1.X, self.P1.F, self.P1.G, self.P1.cv)))
        self.P2 = Arrays(*(np.array(v) for v in (self.P2.X, self.P2.F, self.P2.G, self.P2.cv)))
        self.z1, self.z2 = self.P1.F.min(axis=0), self.P2.F.min(axis=0)
        self.cmin = float(self.P1.cv.min())
        self.rwd = np.zeros(2)
        self.max_fe = self.budget(n, 2 * n)
        self.arrays = self.P1.take(np.arange(n))  # the archive: a copy (P1 is updated in place)
        self.log(task=0.0, p1=0.5, feasible_ratio_P1=float((self.P1.cv <= 0).mean()))

    def _child(self, k: int, i: int, pool: NDArray[np.int64]) -> tuple[F64, Callable[[], bool]]:
        rng, a, b = self.random_state, int(pool[0]), int(pool[1])
        if k == 0:
            src, ch = (self.P1, self.changed1) if rng.random() < RMP else (self.P2, self.changed2)
            x = de_rand_1(self.P1.X[i:i + 1], src.X[pool[:1]], src.X[pool[1:2]], self.xl, self.xu, rng)
            c1 = self.changed1
            return x, lambda: bool(c1[i] or ch[a] or ch[b])
        src, ch = (self.P2, self.changed2) if rng.random() < RMP else (self.P1, self.changed1)
        return ga(src.X[pool[:1]], src.X[pool[1:2]], self.xl, self.xu, rng, half=True), lambda: bool(ch[a] or ch[b])

    def _update_task1(self, y: Arrays, pool: NDArray[np.int64], s_cv: float) -> int:
        P = self.P1
        # MATLAB's min skips NaN: a child with an undefined objective (pymoo's MW11 at x1 = sqrt(2)) must not
        # turn the ideal point into NaN, which would stop every later replacement. Its own g is NaN: never wins.
        self.z1 = np.fmin(self.z1, y.F[0])
        self.cmin = min(self.cmin, float(y.cv[0]))
        cmax = float(max(P.cv.max(), y.cv[0]))
        # An infinite violation normalises to NaN; the 1e-4 floor (np.fmax, MATLAB's max) then compares that
        # child on g alone, as PlatEMO's code treats a NaN violation. inf - inf for penalised members: NaN,
        # which never wins.
        dg, dc = cmt_differences(P.F, P.cv, self.W, pool, y.F, float(y.cv[0]), self.z1, self.cmin, cmax)
        s = s_cv if s_cv > 0 else 1.0  # a step when s_cv is 0: the exponentials go unused
        e = cmt_exponents(dg, dc, S_OBJ, s)
        with np.errstate(over="ignore", invalid="ignore"):  # numpy's exp, so the numbers are numpy's
            np.exp(e, out=e)
        return int(cmt_replace(P.X, P.F, P.G, P.cv, pool, y.X, y.F, y.G, float(y.cv[0]), dg, dc, e, S_OBJ, s_cv,
                               NR, self.changed1))

    def _update_task2(self, y: Arrays, pool: NDArray[np.int64]) -> int:
        P = self.P2
        self.z2 = np.fmin(self.z2, y.F[0])
        # A point on the ideal point (|d| = 0) has an undefined cosine: NaN in PlatEMO's code, so such a child
        # replaces nothing and such a member is never replaced. One objective (our extension; PlatEMO's is
        # for M >= 2) keeps the direction as on the weight line, else a new best could never enter P2.
        degenerate = 1.0 if P.F.shape[1] == 1 else np.nan
        return int(pbi_replace(P.X, P.F, P.G, P.cv, self.W, pool, y.X, y.F, y.G, float(y.cv[0]), self.z2, THETA,
                               degenerate, self.changed2))

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        rng, n = self.random_state, len(self.W)
        fr = float((self.P1.cv <= 0).mean())
        s_cv = 10.0 * fr
        prob = task_probabilities(self.rwd, int(self.evaluator.n_eval), self.max_fe)
        k = int(rng.random() >= prob[0])
        kids, rep1, rep2 = [], 0, 0
        self.changed1, self.changed2 = np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_)
        ahead, pools = Ahead(self, self.ahead), []
        for i in range(n):
            pools.append(rng.permutation(self.B[i]) if rng.random() < DELTA else rng.permutation(n))
            ahead.add(partial(self._child, k, i, pools[i]))
        for i, pool in enumerate(pools):
            y = ahead.take(i)
            kids.append(y)
            rep1 += self._update_task1(y, pool, s_cv)
            rep2 += self._update_task2(y, pool)
        missed = ahead.close()
        Q = Arrays.concat(*kids)
        archive = self.arrays
        assert archive is not None
        size = len(archive)
        pool_a = Arrays.concat(archive, Q)
        order, _, mask = spea2.select(pool_a.F, n, pool_a.cv)
        from_q = int(mask[size:].sum())
        if size >= n:
            self.rwd[k] += from_q / n
        self.arrays = pool_a.take(order)
        self.log(task=float(k + 1), p1=float(prob[0]), rwd1=float(self.rwd[0]), rwd2=float(self.rwd[1]),
                 from_children=float(from_q), feasible_ratio_P1=fr, sigma_cv=s_cv, replaced_task1=float(rep1),
                 replaced_task2=float(rep2), feasible_ratio_archive=float((self.arrays.cv <= 0).mean()),
                 evaluated_ahead_unused=float(missed))
