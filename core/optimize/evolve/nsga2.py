"""NSGA-II on arrays: binary tournament on (front, -crowding), SBX + polynomial mutation, exact-duplicate
elimination, and rank-and-crowding survival under constraint domination (Deb et al. 2002).

Options are the names the stage configs use (``core.optimize.algorithms.GA_OPTIONS``), with pymoo's NSGA-II
defaults and operators: bounded SBX (probability 0.9 per pair, η 15), polynomial mutation (probability 0.9 per
member, 1/d per variable, η 20).
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.duplicates import fresh_rows
from core.optimize.evolve.ranges import RANGES
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.sorting import cdp_ranks, crowding
from core.optimize.evolve.variation import polynomial_mutation, sbx_bounded

F64 = np.ndarray
MAX_REFILLS = 100


def rank_and_crowding(a: Arrays, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The n survivors (indices, best first) by front under constraint domination, then crowding; with the
    survivors' fronts and crowding distances (computed in the pool)."""
    rank = cdp_ranks(a.F, a.cv)
    cd = crowding(a.F, rank)
    order = np.lexsort((-cd, rank))[:n]
    return order, rank[order], cd[order]


class NSGA2(ArrayAlgorithm):
    """NSGA-II; the output population is the survivors, best first (front, then crowding)."""

    NAME, MIN_POP, EVEN_POP = "nsga2", 2, False

    def __init__(self, pop_size: int = 100, crossover_prob: float = 0.9, crossover_eta: float = 15.0,
                 mutation_prob: float = 0.9, mutation_prob_var: float | None = None, mutation_eta: float = 20.0,
                 eliminate_duplicates: bool = True, **kwargs: Any) -> None:
        given = {"crossover_prob": crossover_prob, "crossover_eta": crossover_eta, "mutation_prob": mutation_prob,
                 "mutation_prob_var": mutation_prob_var, "mutation_eta": mutation_eta}
        for key, v in given.items():  # built directly, as from a config (crossover_eta=-1 divided by zero)
            lo, hi = RANGES[key]
            if v is not None and (isinstance(v, bool) or not isinstance(v, numbers.Real) or not lo <= v <= hi):
                raise ValueError(f"nsga2 {key} must be a number in [{lo:g}, {hi:g}], got {v!r}")
        super().__init__(pop_size=pop_size, **kwargs)
        self.crossover_prob, self.crossover_eta = float(crossover_prob), float(crossover_eta)
        self.mutation_prob, self.mutation_eta = float(mutation_prob), float(mutation_eta)
        self.mutation_prob_var = None if mutation_prob_var is None else float(mutation_prob_var)
        self.eliminate_duplicates = bool(eliminate_duplicates)
        self.rank = np.zeros(0, dtype=np.int64)
        self.crowd = np.zeros(0)

    def member_values(self) -> dict[str, F64]:
        """Each member's front (0 first) and crowding distance, as pymoo's NSGA-II sets ``rank`` and ``crowding``."""
        return {"rank": self.rank, "crowding": self.crowd}

    def _survive(self, pool: Arrays) -> None:
        order, self.rank, self.crowd = rank_and_crowding(pool, self.pop_size)
        self.arrays = pool.take(order)
        self.log(feasible_ratio=float((self.arrays.cv <= 0.0).mean()))

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        self._survive(self.evaluate(self.initial_X()))

    def offspring(self) -> F64:
        """``(pop_size, d)`` new members: mated, varied, repaired, and (by default) unlike any member so far.

        Duplicates are dropped before the repair too, so the repair (the stage's placement, as costly as an
        evaluation) runs on the pop_size members kept, not on the spares; and again after it, since a repair
        can map two members onto one.
        """
        a, rng, p = self.arrays, self.random_state, self.problem
        assert a is not None
        xl, xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        n = self.pop_size
        out: list[F64] = []
        have = 0
        for _ in range(MAX_REFILLS):
            need = n - have
            k = (need + 1) // 2 + need // 20 + 1  # a few spare pairs: duplicates rarely need a refill
            par = tournament((self.rank, -self.crowd), 2 * k, rng)
            c1, c2 = sbx_bounded(a.X[par[0::2]], a.X[par[1::2]], xl, xu, rng, self.crossover_prob,
                                 self.crossover_eta)
            C = polynomial_mutation(np.vstack([c1, c2]), xl, xu, rng, self.mutation_prob_var, self.mutation_eta,
                                    rows=rng.random(2 * k) < self.mutation_prob)
            if self.eliminate_duplicates:
                seen = np.vstack([a.X, *out]) if out else a.X
                C = C[fresh_rows(C, seen)][:need]
                if self.repair is not None:
                    C = self.repaired(C)
                    C = C[fresh_rows(C, seen)]
            else:
                C = self.repaired(C[:need])
            out.append(C)
            have += len(C)
            if have >= n:
                break
        return np.vstack(out)

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        a = self.arrays
        assert a is not None
        self._survive(Arrays.concat(a, self.evaluate(self.offspring())))
