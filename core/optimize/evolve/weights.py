"""Weight vectors and scalarisations for decomposition (CMOEMT, MOEA/D-CMT; spec §1.6)."""

from __future__ import annotations

from itertools import combinations
from math import comb

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def das_dennis(n: int, m: int) -> F64:
    """The simplex lattice with the largest H such that C(H + m - 1, m - 1) <= n, components clipped to >= 1e-6.

    The effective population size is the number of vectors (91 for m = 3, n = 100; 190 for m = 3, n = 200).
    """
    return np.maximum(simplex_lattice(n, m), 1e-6)


class OnePerWeight:
    """An algorithm whose output keeps one member per Das-Dennis weight (CMOEMT, MOEA/D-CMT): ``kept_size``
    tells a config which member indices will exist before the stage runs."""

    pop_size: int

    def weights(self, n_obj: int, name: str) -> F64:
        """One weight per member: the Das-Dennis lattice, or N equal ones for one objective. A population smaller
        than the objectives is refused: the lattice has a vector per objective at least, so the algorithm ran with
        more members than asked (EMO rehearsal, session 33)."""
        if n_obj == 1:
            return np.ones((self.pop_size, 1))
        if self.pop_size < n_obj:
            raise ValueError(f"{name} needs a population of at least one member per objective ({n_obj}), got "
                             f"{self.pop_size}")
        return das_dennis(self.pop_size, n_obj)

    def kept_size(self, n_obj: int) -> int:
        """Members the output keeps: one per weight (91 for 100 at three objectives), all for one objective."""
        return len(das_dennis(self.pop_size, n_obj)) if n_obj > 1 else self.pop_size


def simplex_lattice(n: int, m: int) -> F64:
    """:func:`das_dennis`'s lattice as it is, zeros included (reference fronts on it: the points of the
    boundary)."""
    if m == 1:
        return np.ones((1, 1))
    H = 1
    while comb(H + 1 + m - 1, m - 1) <= n:
        H += 1
    rows = []
    for bars in combinations(range(H + m - 1), m - 1):
        cuts = (-1, *bars, H + m - 1)
        rows.append([cuts[i + 1] - cuts[i] - 1 for i in range(m)])
    return np.asarray(rows, dtype=np.float64) / H


def neighbours(W: F64, T: int) -> NDArray[np.int64]:
    """``(n, T)`` indices of the T nearest weight vectors of each (Euclidean), itself first."""
    d = np.sqrt(((W[:, None, :] - W[None, :, :]) ** 2).sum(axis=2))
    return np.argsort(d, axis=1, kind="stable")[:, :T]


def tchebycheff(F: F64, W: F64, z: F64) -> F64:
    """``max_k w_k |f_k - z_k|`` for rows of F against rows of W (broadcast); CMOEMT's form."""
    return (W * np.abs(F - z)).max(axis=-1)


def tchebycheff_div(F: F64, W: F64, z: F64) -> F64:
    """``max_k |f_k - z_k| / w_k`` (broadcast); MOEA/D-CMT's form (W >= 1e-6 from ``das_dennis``)."""
    return (np.abs(F - z) / W).max(axis=-1)


def pbi(F: F64, W: F64, z: F64, theta: float = 5.0) -> F64:
    """Penalty-based boundary intersection: ``d1 + θ d2`` along each weight direction."""
    w = W / np.linalg.norm(W, axis=-1, keepdims=True)
    diff = F - z
    d1 = (diff * w).sum(axis=-1)
    d2 = np.linalg.norm(diff - d1[..., None] * w, axis=-1)
    return d1 + theta * d2
