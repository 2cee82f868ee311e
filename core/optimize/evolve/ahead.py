"""A one-at-a-time MOEA/D loop with its children evaluated ahead in batches, and the same results.

CMOEMT's task 2 and MOEA/D-CMT make a child, evaluate it and let it replace neighbours before the next child is
made from the populations as they now are. Evaluating one child per call costs ~0.1-0.3 ms against ~8 us a member
in a batch. No random number those loops draw depends on what the populations hold, so the algorithm draws every
child's numbers first, in the loop's order, and :class:`Ahead` makes all children from the generation's starting
populations and evaluates them in one call. The loop then runs as published, compiled (the algorithm's ``place``):
a child none of whose parents has been replaced since it was made is the child the loop makes, so its evaluation
is used. At the first other child ``place`` stops; that child is made again from its numbers and the populations
as they now are, together with the next few children that are out of date too, and those are evaluated in one
call; then ``place`` goes on.

Replacements stamp the members they replace with the placing child's tick (its index + 1): a child made when
``t`` children had been placed is out of date once a parent's stamp exceeds ``t``. Parents are given as
(population, member) pairs, population -1 for none.

The evaluator counts the loop's evaluations (one per child), as the published algorithm spends them; evaluations
made ahead and not used are extra calls of the problem, reported in the trace. With ``enabled`` False each child
is made at its turn and evaluated alone: the published loop, call for call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba.np.random.random_methods import random_interval
from numpy.typing import NDArray

from core.optimize.evolve.base import Arrays
from core.optimize.evolve.variation import de_row, ga_half_row

if TYPE_CHECKING:
    from core.optimize.evolve.base import ArrayAlgorithm

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Make = Callable[[I64], F64]
"""Makes children ``ks`` ``(len(ks), d)`` from their numbers and the populations as they are now."""
Place = Callable[[int, int, Arrays, I64], int]
"""Places children ``j0 .. j1 - 1`` (evaluated: rows of the Arrays) in order, with ticks ``j + 1``; returns the
first out-of-date child (by the ``at`` array: children placed when each was made), or ``j1``."""
WINDOW = 8  # children made again and evaluated together when one is out of date


@numba.njit(cache=True)
def stale(c: int, t: int, pp: I64, pi: I64, stamps: I64) -> bool:  # pragma: no cover - compiled
    """Has a parent of child ``c`` (rows of ``pp``, ``pi``: population, member) been replaced by a child placed
    after the first ``t`` (``stamps`` ``(populations, n)``)?"""
    for q in range(pp.shape[1]):
        if pp[c, q] >= 0 and stamps[pp[c, q], pi[c, q]] > t:
            return True
    return False


@numba.njit(cache=True)
def _out_of_date(j: int, at: I64, pp: I64, pi: I64, stamps: I64, window: int) -> I64:  # pragma: no cover
    # child j and the next children out of date now, at most `window` in all
    redo = np.empty(window, dtype=np.int64)
    redo[0], m = j, 1
    for k in range(j + 1, len(at)):
        if m >= window:
            break
        if stale(k, at[k], pp, pi, stamps):
            redo[m] = k
            m += 1
    return redo[:m]


DE, GA_HALF = 0, 1


@numba.njit(cache=True)
def _parent(XA: F64, XB: F64, pp: I64, pi: I64, c: int, q: int) -> F64:  # pragma: no cover - compiled
    return XA[pi[c, q]] if pp[c, q] == 0 else XB[pi[c, q]]


@numba.njit(cache=True)
def make_children(op: int, ks: I64, pp: I64, pi: I64, XA: F64, XB: F64, nums: F64, below: F64, above: F64,
                  lo: F64, hi: F64) -> F64:  # pragma: no cover - compiled
    """Children ``ks`` ``(len(ks), d)`` from their parents (``pp`` population 0 is ``XA``, 1 ``XB``; ``pi`` the
    member) and their numbers, drawn as the operator draws them: ``DE`` (DE/rand/1 from parents 0, 1, 2, then
    polynomial mutation: ``nums`` rows ``r, site, u``, d each) or ``GA_HALF`` (SBX's first child of parents 0, 1,
    then mutation: ``u, sign, var`` (d each), ``pair``, ``site, u``; ``below``, ``above`` the powers of ``u``)."""
    d = XA.shape[1]
    C = np.empty((len(ks), d))
    for r in range(len(ks)):
        c = ks[r]
        x0, x1 = _parent(XA, XB, pp, pi, c, 0), _parent(XA, XB, pp, pi, c, 1)
        v = nums[c]
        if op == DE:
            de_row(x0, x1, _parent(XA, XB, pp, pi, c, 2), v[:d], v[d:2 * d], v[2 * d:3 * d], lo, hi, C[r], 0.5, 1.0,
                   1.0 / d, 20.0)
        else:
            ga_half_row(x0, x1, v[:d], below[c], above[c], v[d:2 * d], v[2 * d:3 * d], v[3 * d],
                        v[3 * d + 1:4 * d + 1], v[4 * d + 1:5 * d + 1], lo, hi, C[r])
    return C


def draw_pools(rng: np.random.Generator, B: I64, members: I64, n: int, delta: float,
               nums: F64) -> tuple[I64, I64]:
    """The published loop's draws for one child of each subproblem in ``members``, in turn: a number choosing
    its pool (below ``delta``: the subproblem's neighbourhood ``B[i]``, else the whole population of n), the
    pool permuted, then the child's row of ``nums`` (filled in place). Returns the pools as one array and offsets:
    child t's pool is ``flat[offs[t]:offs[t + 1]]``.
    Compiled: numba's generator draws numpy's numbers in numpy's way, without a Python call per draw."""
    return _draw_pools(rng, np.ascontiguousarray(B, dtype=np.int64), np.asarray(members, dtype=np.int64), int(n),
                       float(delta), nums)


@numba.njit(cache=True)
def _draw_pools(rng: np.random.Generator, B: I64, members: I64, n: int, delta: float,
                nums: F64) -> tuple[I64, I64]:  # pragma: no cover - compiled
    m = len(members)
    offs = np.zeros(m + 1, dtype=np.int64)
    flat = np.empty(m * max(n, B.shape[1]), dtype=np.int64)
    everyone = np.arange(n)
    for t in range(m):
        pool = permuted(rng, B[members[t]]) if rng.random() < delta else permuted(rng, everyone)
        offs[t + 1] = offs[t] + len(pool)
        flat[offs[t] : offs[t + 1]] = pool
        for j in range(nums.shape[1]):
            nums[t, j] = rng.random()
    return flat[: offs[m]].copy(), offs


@numba.njit(cache=True)
def permuted(rng: np.random.Generator, values: I64) -> I64:  # pragma: no cover - compiled
    """``rng.permutation(values)``: the same numbers drawn the same way (numpy's Fisher-Yates with
    ``random_interval``), 3.5x faster than numba's, whose swaps go through 0-d array views (~36 ns a member: most of
    CMOEMT's and MOEA/D-CMT's drawing time)."""
    out = values.copy()
    bits = rng.bit_generator
    for i in range(len(out) - 1, 0, -1):
        j = numba.types.intp(random_interval(bits, i))
        if i != j:
            out[i], out[j] = out[j], out[i]
    return out


def numbers(op: int, d: int) -> int:
    """How many uniform numbers the operator draws for one child (see :func:`make_children`)."""
    return 3 * d if op == DE else 5 * d + 1


def powers(nums: F64, d: int, eta: float = 20.0) -> tuple[F64, F64]:
    """SBX's two powers of each child's ``u`` (the first d numbers), in numpy as :func:`variation.sbx` takes them."""
    u = np.ascontiguousarray(nums[:, :d])
    return (2.0 * u) ** (1.0 / (eta + 1.0)), (2.0 - 2.0 * u) ** (-1.0 / (eta + 1.0))


class Ahead:
    """One generation's children: ``run`` makes, evaluates and places them; the parents ``pp``, ``pi`` ``(n, q)``
    and the populations' ``stamps`` ``(populations, n_members)`` (zeros; ``place`` writes them) tell which are
    out of date."""

    def __init__(self, alg: ArrayAlgorithm, enabled: bool = True, window: int | None = None) -> None:
        self.alg, self.enabled = alg, enabled
        self.window = WINDOW if window is None else window

    def run(self, n: int, pp: I64, pi: I64, stamps: I64, make: Make, place: Place) -> tuple[Arrays, int]:
        """The ``n`` children as placed (evaluated) and how many evaluations were made and not used."""
        alg = self.alg
        d = int(alg.problem.n_var)
        at = np.zeros(n, dtype=np.int64)
        if n == 0 or not self.enabled:
            Y = alg.evaluate(np.zeros((0, d)))
            for j in range(n):
                at[j] = j
                y = alg.evaluate(alg.repaired(make(np.array([j]))))
                if j == 0:
                    Y = Arrays(*(np.zeros((n, *v.shape[1:])) for v in (y.X, y.F, y.G, y.cv)))
                Y.X[j], Y.F[j], Y.G[j], Y.cv[j] = y.X[0], y.F[0], y.G[0], y.cv[0]
                place(j, j + 1, Y, at)
            return Y, 0
        Y = alg.evaluate(alg.repaired(make(np.arange(n))))
        Y = Arrays(*(np.array(v) for v in (Y.X, Y.F, Y.G, Y.cv)))  # rows are written when made again
        evaluated, j = n, 0
        while True:
            j = place(j, n, Y, at)
            if j >= n:
                break
            redo = _out_of_date(j, at, pp, pi, stamps, self.window)
            at[redo] = j
            y = alg.evaluate(alg.repaired(make(redo)))
            evaluated += len(redo)
            Y.X[redo], Y.F[redo], Y.G[redo], Y.cv[redo] = y.X, y.F, y.G, y.cv
        alg.evaluator.n_eval -= evaluated - n  # the loop's evaluations only
        return Y, evaluated - n

