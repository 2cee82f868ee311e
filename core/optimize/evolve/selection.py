"""Mating selection: binary tournaments on lexicographic keys."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

I64 = NDArray[np.int64]


def tournament(keys: tuple[NDArray[np.float64] | I64, ...], n: int, rng: np.random.Generator) -> I64:
    """``(n,)`` winners of n binary tournaments: two candidates drawn uniformly with replacement, the lower
    key wins (keys compared lexicographically, first key first), ties go to the first drawn (spec §1.5).

    Args:
        keys: one ``(pop,)`` array per key, most significant first (negate a key where larger is better).
        n: number of winners.
        rng: the random generator.
    """
    pop = len(keys[0])
    a = rng.integers(0, pop, n)
    b = rng.integers(0, pop, n)
    b_wins = np.zeros(n, dtype=bool)
    decided = np.zeros(n, dtype=bool)
    for k in keys:
        ka, kb = np.asarray(k)[a], np.asarray(k)[b]
        b_wins |= ~decided & (kb < ka)
        decided |= ka != kb
    return np.where(b_wins, b, a)
