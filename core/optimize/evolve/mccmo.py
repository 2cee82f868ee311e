"""MCCMO (Zou et al., IEEE TEVC 28(1), 2024) on arrays, as the spec (§6) describes PlatEMO's version.

C + 2 populations share one offspring pool: the archive A (the output) under constraint domination over all
constraints, P0 with no constraints (the unconstrained front), and one Q_i per constraint under that
constraint alone. Activation dormancy detection (ADD): a Q_i makes no children until its objective sum
settles; combine occasion detection (COD): Q's that settle behind the others are merged into one population
under the union of their constraints (or re-initialised when none of their members satisfies any of them).
Evaluations per generation: N (A) + N/2 (P0 while it searches, or A x P0 pairs once it settled) + N/2 per
active Q; initially N for P0 and N per Q.

Decisions (docs/algorithms.md): the offspring pool is cleared every generation (PlatEMO's GA branch re-adds
the previous children of a dormant Q: spec pitfall 1); the merge test is PlatEMO's "some entry of the
population's constraint columns is satisfied" (pitfall 4); with no constraint (pymoo's unconstrained
problems) one all-zero constraint column stands in, as PlatEMO adds one, so C = 0 behaves as C = 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.sorting import nd_ranks
from core.optimize.evolve.variation import de_rand_1, ga

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
THRESHOLD = 1e-2


def subset_cv(G: F64, S: tuple[int, ...]) -> F64:
    """``(n,)`` violation of the constraints in S (sum of positive G over those columns; NaN counts as +inf)."""
    if not S:
        return np.zeros(len(G))
    v = np.maximum(G[:, list(S)], 0.0).sum(axis=1)
    return np.where(np.isnan(v), np.inf, v)


def is_stable(h: dict[int, float], gen: int, F: F64, n: int, nd_required: bool) -> bool:
    """Spec §6: the population's objective sum h moved by at most 1e-2 |h(gen)| / (N M) 10^(M-2) since the last
    generation and, if ``nd_required``, all N members are non-dominated."""
    if gen - 1 not in h or gen not in h:
        return False
    m = F.shape[1]
    nc = int((nd_ranks(F) == 0).sum()) if nd_required else n
    now, before = h[gen], h[gen - 1]
    return bool(nc == n and abs(now - before) <= THRESHOLD * abs(now) / (n * m) * 10.0 ** (m - 2))


@dataclass
class Sub:
    """One Q population: its members (sorted by fitness), fitness, constraint set and flags."""

    pop: Arrays
    fit: F64
    S: tuple[int, ...]
    dormant: bool = True
    stable: bool = False
    h: dict[int, float] = field(default_factory=dict)


class MCCMO(ArrayAlgorithm):
    """MCCMO; the output population is the archive A. ``operator``: ``ga`` (PlatEMO's choice for MW, C-DTLZ and
    the CLM problems) or ``de`` (its choice for DAS-CMOP, LIR-CMOP, DOC)."""

    NAME, MIN_POP, EVEN_POP = "mccmo", 4, True

    def __init__(self, pop_size: int = 100, operator: str = "ga", **kwargs: Any) -> None:
        if operator not in ("ga", "de"):
            raise ValueError(f"mccmo operator must be 'ga' or 'de', got {operator!r}")
        super().__init__(pop_size=pop_size, **kwargs)
        self.operator = operator

    # Helpers -------------------------------------------------------------------------------------

    def _G(self, a: Arrays) -> F64:
        return a.G if a.G.shape[1] else np.zeros((len(a), 1))

    def _select(self, pool: Arrays, S: tuple[int, ...] | None,
                cuts: spea2.Cuts | None = None) -> tuple[Arrays, F64]:
        """SPEA2 selection of N: unconstrained (S None), or under constraint domination over the set S. ``cuts``:
        the generation's truncations (A and P0 cut the same members when every one is feasible)."""
        cv = None if S is None else subset_cv(self._G(pool), S)
        order, fit, _ = spea2.select(pool.F, self.pop_size, cv, cuts=cuts)
        return pool.take(order), fit

    def _random(self) -> Arrays:
        p = self.problem
        return self.evaluate(self.repaired(self.random_state.uniform(self.xl, self.xu, size=(self.pop_size, p.n_var))))

    def _children(self, X: F64, fit: F64, n_parents: int, half: bool, other: tuple[F64, F64] | None = None) -> F64:
        """GA/GAhalf on a tournament pool (the first half paired with the second), or DE (one child per base)."""
        rng, n = self.random_state, self.pop_size
        if self.operator == "de":
            k = n_parents // 2 if half else len(X)
            base = X[:k]  # the best k by fitness
            if other is None:
                pool = tournament((fit,), 2 * k, rng)
                return de_rand_1(base, X[pool[:k]], X[pool[k:]], self.xl, self.xu, rng)
            Xo, fo = other
            a, b = tournament((fit,), k, rng), tournament((fo,), k, rng)
            return de_rand_1(base, X[a], Xo[b], self.xl, self.xu, rng)
        if other is None:
            pool = tournament((fit,), n_parents, rng)
            h = n_parents // 2
            return ga(X[pool[:h]], X[pool[h : 2 * h]], self.xl, self.xu, rng, half=half)
        Xo, fo = other
        a, b = tournament((fit,), n // 2, rng), tournament((fo,), n // 2, rng)
        return ga(X[a], Xo[b], self.xl, self.xu, rng, half=True)

    # The loop ------------------------------------------------------------------------------------

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        p = self.problem
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        p0 = self.evaluate(self.initial_X())
        self.n_con = max(int(p.n_ieq_constr) + int(p.n_eq_constr), 1)  # an equality is a column of G too
        self.Q: list[Sub] = []
        for i in range(self.n_con):
            fresh = self._random()
            fit = spea2.fitness(fresh.F)
            o = np.argsort(fit, kind="stable")
            self.Q.append(Sub(fresh.take(o), fit[o], (i,)))
        fit0 = spea2.fitness(p0.F)
        o = np.argsort(fit0, kind="stable")
        self.p0, self.fit0 = p0.take(o), fit0[o]
        self.arrays, self.fit_a = self._select(Arrays.concat(p0, *(q.pop for q in self.Q)), tuple(range(self.n_con)))
        self.upf = self.dupf = self.reinit = False
        self.gen = 1
        self.h0 = {1: float(np.abs(self.p0.F).sum())}
        for sub in self.Q:
            sub.h[1] = float(sub.pop.F.sum())
        self.merges = self.reinits = 0
        self._log(0)

    def _log(self, fe: int) -> None:
        a = self.arrays
        assert a is not None
        self.log(fe_generation=float(fe), n_Q=float(len(self.Q)), dormant=float(sum(q.dormant for q in self.Q)),
                 stable=float(sum(q.stable for q in self.Q)), largest_set=float(max((len(q.S) for q in self.Q),
                                                                                    default=0)),
                 UPF=float(self.upf), dUPF=float(self.dupf), reinit=float(self.reinit), merges=float(self.merges),
                 reinitialised=float(self.reinits), h0=self.h0.get(self.gen, float("nan")),
                 feasible_ratio_A=float((a.cv <= 0).mean()), feasible_ratio_P0=float((self.p0.cv <= 0).mean()))

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, a = self.pop_size, self.arrays
        assert a is not None
        self.gen += 1
        gen, every = self.gen, tuple(range(self.n_con))
        parts = []
        several = len(self.Q) > 1
        if several:
            parts += [self._children(q.pop.X, q.fit, n, half=True) for q in self.Q if not q.dormant]
        if not self.upf or not self.dupf:
            parts.append(self._children(self.p0.X, self.fit0, n, half=True))
        elif self.dupf and self.reinit:
            parts.append(self._children(self.p0.X, self.fit0, n, half=True, other=(a.X, self.fit_a)))
        parts.append(self._children(a.X, self.fit_a, n, half=False))
        off = self.evaluate(self.repaired(np.vstack(parts)))
        cuts: spea2.Cuts = {}
        self.arrays, self.fit_a = self._select(Arrays.concat(off, a), every, cuts)
        self.p0, self.fit0 = self._select(Arrays.concat(self.p0, off), None, cuts)
        self.h0[gen] = float(np.abs(self.p0.F).sum())
        if several:
            for q in self.Q:
                q.pop, q.fit = self._select(Arrays.concat(q.pop, off), q.S, cuts)
                q.h[gen] = float(q.pop.F.sum())
                q.stable = is_stable(q.h, gen, q.pop.F, n, nd_required=not q.dormant)
                if q.stable and q.dormant:  # ADD: a settled dormant population wakes up
                    q.dormant = q.stable = False
        if not self.upf:
            self.upf = is_stable(self.h0, gen, self.p0.F, n, False)
        else:
            self.dupf = is_stable(self.h0, gen, self.p0.F, n, False)
        if self.dupf:
            self.reinit = bool((self.p0.cv <= 0).any())
        if several:
            self._combine(gen)
        self._log(len(off))

    def _combine(self, gen: int) -> None:
        """COD: flag the Q's that settled behind the others; merge them (or re-initialise the hopeless)."""
        a = self.arrays
        assert a is not None
        parts = [q.pop for q in self.Q] + ([a] if self.upf and self.dupf else [])
        U = Arrays.concat(*parts)
        fronts = nd_ranks(U.F)
        bounds = np.cumsum([0] + [len(p) for p in parts])
        lo = [int(fronts[bounds[k]:bounds[k + 1]].min()) for k in range(len(parts))]
        hi = [int(fronts[bounds[k]:bounds[k + 1]].max()) for k in range(len(parts))]
        k_q = len(self.Q)
        if self.upf and self.dupf:
            for j in range(k_q):
                if hi[j] < lo[k_q]:
                    self.Q[j].stable = True
        for i in range(k_q):
            if self.Q[i].stable:
                for j in range(k_q):
                    if j != i and hi[j] < lo[i]:
                        self.Q[j].stable = True
        merge = []
        for p, q in enumerate(self.Q):
            if not q.stable:
                continue
            if (self._G(q.pop)[:, list(q.S)] <= 0).any():
                merge.append(p)
            else:  # none of its members satisfies any of its constraints: start it again
                fresh = self._random()
                q.fit = spea2.fitness(fresh.F, subset_cv(self._G(fresh), q.S))
                o = np.argsort(q.fit, kind="stable")
                q.pop, q.fit = fresh.take(o), q.fit[o]
                self.reinits += 1
        if len(merge) > 1:
            s = self.Q[merge[0]]
            s.S = tuple(sorted({c for p in merge for c in self.Q[p].S}))
            s.pop, s.fit = self._select(Arrays.concat(U, a), s.S)
            s.stable = s.dormant = False
            s.h[gen] = float(s.pop.F.sum())
            self.Q = [q for q in self.Q if not q.stable]
            self.merges += 1
        if len(self.Q) == 1:
            self.arrays, self.fit_a = self._select(Arrays.concat(a, self.Q[0].pop), tuple(range(self.n_con)))
