"""Large float64 work blocks kept between calls, handed out again once nothing refers to them.

A fresh large array's pages are faulted in (and zeroed by the kernel) when first written: at
population 10 000 and 360 samples that cost ~0.6 us per design, a third of a kinematic solve.
A :class:`Pool` keeps the last few blocks it handed out and gives one back out when no array (no
view: every view refers to its block) uses it any more, so its pages are mapped already. Used by
the numba kernel (its paths) and the numpy reference (its slab); plain numpy, no numba.
"""

from __future__ import annotations

import sys
import threading

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def _refs(blocks: list[F64], k: int) -> int:
    return sys.getrefcount(blocks[k])


# The reference count of a block nothing but the pool's list refers to (the interpreter's own counting).
_UNUSED = _refs([np.empty(0)], 0)


class Pool:
    """Keeps up to ``keep`` blocks of ``lo`` .. ``hi`` bytes (newest first); thread-safe.

    Blocks stay allocated after their arrays are gone: at most ``keep * hi`` bytes per pool.
    """

    def __init__(self, keep: int = 2, lo: int = 1 << 20, hi: int = 1 << 28) -> None:
        self.keep, self.lo, self.hi = keep, lo, hi
        self.blocks: list[F64] = []
        self.lock = threading.Lock()

    def take(self, size: int) -> F64:
        """An uninitialized float64 array of ``size`` elements (a view of a kept block if one is free)."""
        if not self.lo <= size * 8 <= self.hi:
            return np.empty(size)
        with self.lock:
            kept = self.blocks
            for k in range(len(kept)):
                if size <= kept[k].size <= 2 * size and _refs(kept, k) == _UNUSED:
                    block = kept.pop(k)
                    break
            else:
                block = np.empty(size)
            kept.insert(0, block)
            del kept[self.keep :]
        return block[:size]
