"""IMTCMO (Qiao et al., IEEE TEVC 28(4), 2024) on arrays, as the spec (§5) describes PlatEMO's version.

Two populations exchange all offspring: the main one (P1, the output) by SPEA2 under constraint domination,
the auxiliary one (P2) under an epsilon constraint whose level falls from the initial maximum violation to
e^-6 over the budget: epsilon-feasible members rank by SPEA2 on [f, CV]. Reproduction is DE only: half the
children by a neighbour-pairing DE/rand/1 (two members close in objective direction), half by
DE/current-to-pbest/1, with F in {0.6, 0.8, 1.0} and CR in {0.1, 0.2, 1.0} drawn per child. 2N evaluations
per generation (N per population), 2N for the initial populations.

Decision (docs/algorithms.md): if the initial maximum violation is <= e^-6, the exponent cp of the schedule
would be negative and epsilon would grow; epsilon then stays at that initial value.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.base import ArrayAlgorithm, Arrays, largest_violation
from core.optimize.evolve.variation import polynomial_mutation

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
F_SET = np.array([0.6, 0.8, 1.0])
CR_SET = np.array([0.1, 0.2, 1.0])
N_NEIGHBOURS = 10
P_BEST = 0.1
EPS_END = math.exp(-6.0)


def epsilon_schedule(var0: float) -> tuple[float, float]:
    """(VAR0, cp) with VAR(X) = VAR0 (1 - X)^cp and VAR(0.5) = e^-6; cp = 0 (a constant level) when VAR0 <= e^-6."""
    var0 = var0 if var0 > 0 else 1.0
    if var0 <= EPS_END:
        return var0, 0.0
    return var0, (-math.log(var0) - 6.0) / math.log(0.5)


def aux_select(F: F64, cv: F64, n: int, var: float, cuts: spea2.Cuts | None = None) -> tuple[I64, F64, int]:
    """AuxSel (spec §5): the n survivors (best first), their fitness, and how many were epsilon-feasible.
    ``cuts``: truncations made earlier in the generation (P1's selection)."""
    feas = np.flatnonzero(cv <= var)
    infeas = np.flatnonzero(cv > var)
    if feas.size == 0:
        order, fit, _ = spea2.select(F, n, cv, cuts=cuts)
        return order, fit, 0
    aug = np.column_stack([F, cv])
    if feas.size > n:
        o, fit, _ = spea2.select(F[feas], n, None, fit_F=aug[feas], cuts=cuts)
        return feas[o], fit, n
    fit_f = spea2.fitness(aug[feas])
    o = np.argsort(fit_f, kind="stable")
    order, fit = feas[o], fit_f[o]
    rest = n - feas.size
    if rest > 0 and infeas.size:
        oi, fi, _ = spea2.select(F[infeas], rest, cv[infeas], cuts=cuts)
        order = np.concatenate([order, infeas[oi]])
        fit = np.concatenate([fit, fi + (fit_f.max() if fit_f.size else 0.0)])
    return order, fit, int(feas.size)


def _de_params(n: int, rng: np.random.Generator) -> tuple[F64, F64]:
    return F_SET[rng.integers(0, 3, n)][:, None], CR_SET[rng.integers(0, 3, n)][:, None]


@numba.njit(cache=True)
def _most_similar(cos: F64, k: int) -> I64:  # pragma: no cover - compiled
    # Per row, the k columns of largest value, largest first, ties to the lower column: the first k of a
    # stable argsort of -cos, without sorting whole rows (a row keeps a sorted list of k).
    n, N = cos.shape
    out = np.empty((n, k), dtype=np.int64)
    val = np.empty(k)
    for i in range(n):
        size = 0
        for j in range(N):
            v = cos[i, j]
            if size == k and v <= val[k - 1]:
                continue
            p = size if size < k else k - 1
            while p > 0 and val[p - 1] < v:
                val[p], out[i, p] = val[p - 1], out[i, p - 1]
                p -= 1
            val[p], out[i, p] = v, j
            if size < k:
                size += 1
    return out


def most_similar(cos: F64, k: int) -> I64:
    """``(n, k)``: each row's k columns of largest value, largest first, ties to the lower column."""
    return _most_similar(np.ascontiguousarray(cos, dtype=np.float64), int(k))


def neighbour_de(a: Arrays, z: F64, n: int, xl: F64, xu: F64, rng: np.random.Generator) -> F64:
    """n children by neighbour-pairing DE/rand/1: x_i + F (x_a - x_b), a and b among x_i's 10 nearest in
    direction (cosine of objectives translated by the ideal point z)."""
    N = len(a)
    pool = rng.permutation(N)
    with np.errstate(invalid="ignore", divide="ignore"):  # penalised members: inf - inf, 0 / 0
        U = a.F[pool] - z
        U = U / np.linalg.norm(U, axis=1, keepdims=True)
        cos = (U @ U.T)[:n]  # only the n parents' rows are used
    cos = np.where(np.isnan(cos), -np.inf, cos)
    cos[np.arange(n), np.arange(n)] = -np.inf
    k = min(N_NEIGHBOURS, N - 1)
    near = most_similar(cos, k)
    i = np.arange(n)
    ja = rng.integers(0, k, n)
    jb = (ja + rng.integers(1, k, n)) % k
    x, xa, xb = a.X[pool[i]], a.X[pool[near[i, ja]]], a.X[pool[near[i, jb]]]
    Fs, CRs = _de_params(n, rng)
    child = np.where(rng.random(x.shape) < CRs, x + Fs * (xa - xb), x)
    return polynomial_mutation(np.clip(child, xl, xu), xl, xu, rng)


def pbest_de(a: Arrays, fit: F64, n: int, xl: F64, xu: F64, rng: np.random.Generator) -> F64:
    """n children by DE/current-to-pbest/1: x + F (pbest - x + x_r1 - x_r2) on CR sites, clipped, mutated."""
    N = len(a)
    t = rng.permutation(N)[:n]
    r1 = (t + rng.integers(1, N, n)) % N
    r2 = rng.integers(0, N, n)
    bad = (r2 == t) | (r2 == r1)
    while bad.any():
        r2[bad] = rng.integers(0, N, int(bad.sum()))
        bad = (r2 == t) | (r2 == r1)
    best = np.argsort(fit, kind="stable")[: max(int(round(P_BEST * N)), 2)]
    pb = best[rng.integers(0, len(best), n)]
    Fs, CRs = _de_params(n, rng)
    x = a.X[t]
    child = np.where(rng.random(x.shape) < CRs, x + Fs * (a.X[pb] - x + a.X[r1] - a.X[r2]), x)
    return polynomial_mutation(np.clip(child, xl, xu), xl, xu, rng)


class IMTCMO(ArrayAlgorithm):
    """IMTCMO; the output population is the main task's (P1). ``pop_size`` must be even and >= 12."""

    NAME, MIN_POP, EVEN_POP = "imtcmo", 12, True

    def __init__(self, pop_size: int = 100, **kwargs: Any) -> None:
        super().__init__(pop_size=pop_size, **kwargs)

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, p = self.pop_size, self.problem
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        p1 = self.evaluate(self.initial_X())
        p2 = self.evaluate(self.repaired(self.random_state.uniform(self.xl, self.xu, size=(n, p.n_var))))
        self.max_fe = self.budget(2 * n, 2 * n)
        self.var0, self.cp = epsilon_schedule(largest_violation(p1.cv, p2.cv))
        self.x = 0.0
        self.fit1 = spea2.fitness(p1.F, p1.cv)
        self.fit2 = spea2.fitness(p2.F, p2.cv)
        self.z1, self.z2 = np.fmin.reduce(p1.F, axis=0), np.fmin.reduce(p2.F, axis=0)  # MATLAB's min skips NaN
        self.p2 = p2
        self.arrays = p1
        self.log(eps=self.var0, X=0.0, feasible_ratio_P1=float((p1.cv <= 0).mean()),
                 feasible_ratio_P2=float((p2.cv <= 0).mean()))

    def epsilon(self) -> float:
        # X past 1 (a time or pymoo's default termination runs past the assumed budget): 0, the schedule's end,
        # where (1 - X)^cp of a negative base was a complex number (EMO rehearsal, session 33)
        return self.var0 * (1.0 - min(self.x, 1.0)) ** self.cp if self.cp > 0 else self.var0

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, rng = self.pop_size, self.random_state
        p1, p2 = self.arrays, self.p2
        assert p1 is not None
        var = self.epsilon()
        h = n // 2
        x1 = np.vstack([neighbour_de(p1, self.z1, h, self.xl, self.xu, rng),
                        pbest_de(p1, self.fit1, n - h, self.xl, self.xu, rng)])
        x2 = np.vstack([neighbour_de(p2, self.z2, h, self.xl, self.xu, rng),
                        pbest_de(p2, self.fit2, n - h, self.xl, self.xu, rng)])
        off = self.evaluate(self.repaired(np.vstack([x1, x2])))
        o1, o2 = off.take(np.arange(n)), off.take(np.arange(n, 2 * n))
        # MATLAB's min skips NaN: a child with an undefined objective (pymoo's MW11 at x1 = sqrt(2), where DE's
        # clipping puts children) must not make the ideal point NaN, which left every direction undefined and
        # the neighbour pairing with no neighbours by direction for the rest of the run
        self.z1 = np.fmin(self.z1, np.fmin.reduce(o1.F, axis=0))
        self.z2 = np.fmin(self.z2, np.fmin.reduce(o2.F, axis=0))
        pool1 = Arrays.concat(p1, o1, o2)
        cuts: spea2.Cuts = {}  # all feasible: P1's and P2's pools cut the same members
        order, self.fit1, _ = spea2.select(pool1.F, n, pool1.cv, cuts=cuts)
        pool2 = Arrays.concat(p2, o2, o1)
        order2, self.fit2, n_feas = aux_select(pool2.F, pool2.cv, n, var, cuts)
        self.p2 = pool2.take(order2)
        self.arrays = pool1.take(order)
        self.x += n / self.max_fe
        self.log(eps=var, X=self.x, eps_feasible=float(n_feas),
                 feasible_ratio_P1=float((self.arrays.cv <= 0).mean()),
                 feasible_ratio_P2=float((self.p2.cv <= 0).mean()),
                 from_O1=float(((order >= n) & (order < 2 * n)).sum()), from_O2=float((order >= 2 * n).sum()))
