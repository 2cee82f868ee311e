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

from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.ahead import DE, GA_HALF, Ahead, draw_pools, make_children, numbers, powers, stale
from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.moead import cmt_differences, cmt_replace, fmin_into, pbi_replace
from core.optimize.evolve.weights import OnePerWeight, neighbours

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
DELTA, NR, RMP, LEARN, P_MIN, S_OBJ, THETA = 0.9, 2, 0.2, 0.3, 0.1, 0.3, 5.0


def task_probabilities(rwd: F64, fe: int, max_fe: int) -> F64:
    if fe <= LEARN * max_fe or rwd.sum() <= 0:
        return np.array([0.5, 0.5])
    p = P_MIN / 2 + (1 - P_MIN) * rwd / rwd.sum()
    return p / p.sum()


@numba.njit(cache=True)
def _place(j0: int, j1: int, pools: I64, offs: I64, X1: F64, F1: F64, G1: F64, cv1: F64, X2: F64, F2: F64, G2: F64,
           cv2: F64, W: F64, z1: F64, z2: F64, cmin: F64, s_cv: float, degenerate: float, YX: F64, YF: F64, YG: F64,
           Ycv: F64, stamps: I64, at: I64, pp: I64, pi: I64, reps: I64) -> int:  # pragma: no cover - compiled
    """Children ``j0 .. j1 - 1`` (rows of Y) update both tasks in order (see :class:`~core.optimize.evolve.ahead.
    Ahead`); returns the first one out of date, or ``j1``. ``z1``, ``z2``, ``cmin`` ``(1,)`` and ``reps`` (the
    replacements of each task) are updated in place."""
    for j in range(j0, j1):
        if stale(j, at[j], pp, pi, stamps):
            return j
        pool = pools[offs[j]:offs[j + 1]]
        yX, yF, yG, ycv = YX[j:j + 1], YF[j:j + 1], YG[j:j + 1], Ycv[j]
        # Task 1. MATLAB's min skips NaN: a child with an undefined objective (pymoo's MW11 at x1 = sqrt(2)) must
        # not turn the ideal point into NaN, which would stop every later replacement; its own g is NaN: it never
        # wins. An infinite violation normalises to NaN; the 1e-4 floor then compares that child on g alone, as
        # PlatEMO's code treats a NaN violation.
        fmin_into(z1, yF[0])
        if ycv < cmin[0]:
            cmin[0] = ycv
        cmax = cv1.max()
        if ycv > cmax:
            cmax = ycv
        dg, dc = cmt_differences(F1, cv1, W, pool, yF, ycv, z1, cmin[0], cmax)
        reps[0] += cmt_replace(X1, F1, G1, cv1, pool, yX, yF, yG, ycv, dg, dc, S_OBJ, s_cv, NR, stamps[0], j + 1)
        # Task 2: a point on the ideal point has an undefined cosine: NaN in PlatEMO's code, so such a child
        # replaces nothing and such a member is never replaced (`degenerate`).
        fmin_into(z2, yF[0])
        reps[1] += pbi_replace(X2, F2, G2, cv2, W, pool, yX, yF, yG, ycv, z2, THETA, degenerate, stamps[1], j + 1)
    return j1


class MOEADCMT(OnePerWeight, ArrayAlgorithm):
    """MOEA/D-CMT; the effective population is the number of Das-Dennis vectors (<= pop_size; all of it for
    one objective).

    Args:
        ahead: make and evaluate each generation's children in one batch ahead of the sequential loop, with the
            same results (:mod:`core.optimize.evolve.ahead`); False evaluates them one at a time.
    """

    NAME, MIN_POP, EVEN_POP = "moead_cmt", 2, False

    def __init__(self, pop_size: int = 100, ahead: bool = True, **kwargs: Any) -> None:
        super().__init__(pop_size=pop_size, **kwargs)
        self.ahead = ahead

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        p = self.problem
        # One objective: N equal subproblems (the lattice would give one); DE needs two neighbours at least.
        self.W = self.weights(p.n_obj, "moead_cmt")
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
        self.z1, self.z2 = np.fmin.reduce(self.P1.F, axis=0), np.fmin.reduce(self.P2.F, axis=0)  # NaN skipped
        self.cmin = float(self.P1.cv.min())
        self.rwd = np.zeros(2)
        self.max_fe = self.budget(n, 2 * n)
        self.arrays = self.P1.take(np.arange(n))  # the archive: a copy (P1 is updated in place)
        self.log(task=0.0, p1=0.5, feasible_ratio_P1=float((self.P1.cv <= 0).mean()), cmin=self.cmin)

    def _draw(self, k: int) -> tuple[I64, I64, I64, I64, F64]:
        """Each child's numbers, in the published loop's order: its pool (neighbourhood or population, permuted),
        then the operator's (the source population's draw first). Returns the pools (flat, offsets), the parents
        (population 0 = P1, 1 = P2; member) and the operator's numbers."""
        rng, n, d = self.random_state, len(self.W), self.problem.n_var
        op = DE if k == 0 else GA_HALF
        nums = np.empty((n, 1 + numbers(op, d)))
        flat, offs = draw_pools(rng, self.B, np.arange(n), n, DELTA, nums)
        a, b = flat[offs[:-1]], flat[offs[:-1] + 1]
        near = nums[:, 0] < RMP  # the mate's source: the child's own task's population
        src = np.where(near, 0, 1) if k == 0 else np.where(near, 1, 0)
        if k == 0:  # DE on base P1[i]
            pp, pi = np.stack([np.zeros(n, dtype=np.int64), src, src], 1), np.stack([np.arange(n), a, b], 1)
        else:  # SBX of two mates
            pp, pi = np.stack([src, src, np.full(n, -1)], 1), np.stack([a, b, np.zeros(n, dtype=np.int64)], 1)
        return flat, offs, pp.astype(np.int64), pi.astype(np.int64), np.ascontiguousarray(nums[:, 1:])

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        rng, n = self.random_state, len(self.W)
        fr = float((self.P1.cv <= 0).mean())
        s_cv = 10.0 * fr
        prob = task_probabilities(self.rwd, int(self.evaluator.n_eval), self.max_fe)
        k = int(rng.random() >= prob[0])
        pools, offs, pp, pi, nums = self._draw(k)
        op, d = (DE if k == 0 else GA_HALF), self.problem.n_var
        below, above = powers(nums, d) if op == GA_HALF else (nums, nums)
        stamps, reps = np.zeros((2, n), dtype=np.int64), np.zeros(2, dtype=np.int64)
        cmin = np.array([self.cmin])
        # One objective (our extension; PlatEMO's is for M >= 2): a point on the ideal point counts as on the
        # weight line (PBI), else a new best could never enter P2.
        degenerate = 1.0 if self.P1.F.shape[1] == 1 else np.nan
        P1, P2 = self.P1, self.P2

        def make(ks: I64) -> F64:
            return make_children(op, ks, pp, pi, P1.X, P2.X, nums, below, above, self.xl, self.xu)

        def place(j0: int, j1: int, Y: Arrays, at: I64) -> int:
            return int(_place(j0, j1, pools, offs, P1.X, P1.F, P1.G, P1.cv, P2.X, P2.F, P2.G, P2.cv, self.W,
                              self.z1, self.z2, cmin, s_cv, degenerate, Y.X, Y.F, Y.G, Y.cv, stamps, at, pp, pi,
                              reps))

        Q, missed = Ahead(self, self.ahead).run(n, pp, pi, stamps, make, place)
        self.cmin = float(cmin[0])
        rep1, rep2 = int(reps[0]), int(reps[1])
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
                 from_children=float(from_q), feasible_ratio_P1=fr, sigma_cv=s_cv, cmin=self.cmin,
                 replaced_task1=float(rep1),
                 replaced_task2=float(rep2), feasible_ratio_archive=float((self.arrays.cv <= 0).mean()),
                 evaluated_ahead_unused=float(missed))
