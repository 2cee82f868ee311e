"""NSGA-II on arrays: binary tournament on (front, -crowding), SBX + polynomial mutation, exact-duplicate
elimination, and rank-and-crowding survival under constraint domination (Deb et al. 2002).

Options are the names the stage configs use (``core.optimize.algorithms.GA_OPTIONS``), with pymoo's NSGA-II
defaults and operators: bounded SBX (probability 0.9 per pair, η 15), polynomial mutation (probability 0.9 per
member, 1/d per variable, η 20).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.sorting import cdp_ranks, crowding
from core.optimize.evolve.variation import polynomial_mutation, sbx_bounded

F64 = np.ndarray
MAX_REFILLS = 100


def fresh_rows(C: F64, existing: F64) -> np.ndarray:
    """``(n,)`` mask of the rows of C that equal no row of ``existing`` and no earlier row of C."""
    seen = {row.tobytes() for row in np.ascontiguousarray(existing)}
    keep = np.zeros(len(C), dtype=bool)
    for i, row in enumerate(np.ascontiguousarray(C)):
        b = row.tobytes()
        if b not in seen:
            seen.add(b)
            keep[i] = True
    return keep


def rank_and_crowding(a: Arrays, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The n survivors (indices, best first) by front under constraint domination, then crowding; with the
    survivors' fronts and crowding distances (computed in the pool)."""
    rank = cdp_ranks(a.F, a.cv)
    cd = crowding(a.F, rank)
    order = np.lexsort((-cd, rank))[:n]
    return order, rank[order], cd[order]


class NSGA2(ArrayAlgorithm):
    def __init__(self, pop_size: int = 100, crossover_prob: float = 0.9, crossover_eta: float = 15.0,
                 mutation_prob: float = 0.9, mutation_prob_var: float | None = None, mutation_eta: float = 20.0,
                 eliminate_duplicates: bool = True, **kwargs: Any) -> None:
        super().__init__(pop_size=pop_size, **kwargs)
        self.crossover_prob, self.crossover_eta = float(crossover_prob), float(crossover_eta)
        self.mutation_prob, self.mutation_eta = float(mutation_prob), float(mutation_eta)
        self.mutation_prob_var = None if mutation_prob_var is None else float(mutation_prob_var)
        self.eliminate_duplicates = bool(eliminate_duplicates)
        self.rank = np.zeros(0, dtype=np.int64)
        self.crowd = np.zeros(0)

    def _survive(self, pool: Arrays) -> None:
        order, self.rank, self.crowd = rank_and_crowding(pool, self.pop_size)
        self.arrays = pool.take(order)
        self.log(feasible_ratio=float((self.arrays.cv <= 0.0).mean()))

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        self._survive(self.evaluate(self.initial_X()))

    def offspring(self) -> F64:
        """``(pop_size, d)`` new members: mated, varied, repaired, and (by default) unlike any member so far."""
        a, rng, p = self.arrays, self.random_state, self.problem
        assert a is not None
        xl, xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        n = self.pop_size
        out: list[F64] = []
        have = 0
        for _ in range(MAX_REFILLS):
            k = (n - have + 1) // 2 + (n - have) // 20 + 1  # a few spare pairs: duplicates rarely need a refill
            par = tournament((self.rank, -self.crowd), 2 * k, rng)
            c1, c2 = sbx_bounded(a.X[par[0::2]], a.X[par[1::2]], xl, xu, rng, self.crossover_prob,
                                 self.crossover_eta)
            C = np.vstack([c1, c2])
            mutate = rng.random(len(C)) < self.mutation_prob
            C[mutate] = polynomial_mutation(C[mutate], xl, xu, rng, self.mutation_prob_var, self.mutation_eta)
            C = self.repaired(C)
            if self.eliminate_duplicates:
                C = C[fresh_rows(C, np.vstack([a.X, *out]) if out else a.X)]
            out.append(C[: n - have])
            have += len(out[-1])
            if have >= n:
                break
        return np.vstack(out)

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        a = self.arrays
        assert a is not None
        self._survive(Arrays.concat(a, self.evaluate(self.offspring())))
