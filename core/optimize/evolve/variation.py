"""Variation operators over arrays (PlatEMO's variants, spec §1.5): SBX, polynomial mutation, DE/rand/1,
DE/current-to-pbest/1.

Every operator clips to the bounds before mutation; mutation keeps members inside the bounds.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def sbx(P1: F64, P2: F64, xl: F64, xu: F64, rng: np.random.Generator, prob: float = 1.0, eta: float = 20.0,
        prob_var: float = 0.5) -> tuple[F64, F64]:
    """Simulated binary crossover of parent pairs ``(k, d)``; the two children of each pair, clipped.

    Per variable: β from u (``(2u)^(1/(η+1))`` or ``(2-2u)^(-1/(η+1))``), a random sign, β = 1 with
    probability 1 - prob_var (variable not recombined) and for every variable of a pair that fails ``prob``.
    """
    k, d = P1.shape
    u = rng.random((k, d))
    sign, var, pair = rng.random((k, d)), rng.random((k, d)), rng.random(k)
    e = 1.0 / (eta + 1.0)
    # The powers in numpy (its SIMD power may differ from a compiled one in the last bit), the rest compiled.
    below, above = (2.0 * u) ** e, (2.0 - 2.0 * u) ** (-1.0 / (eta + 1.0))
    lo, hi = _bounds(xl, xu, d)
    return _sbx(np.ascontiguousarray(P1, dtype=np.float64), np.ascontiguousarray(P2, dtype=np.float64), u, below,
                above, sign, var, pair, lo, hi, float(prob), float(prob_var))


@numba.njit(cache=True)
def _clip(c: float, lo: float, hi: float) -> float:  # pragma: no cover - compiled
    # np.clip: NaN passes through
    return c if np.isnan(c) else min(max(c, lo), hi)


@numba.njit(cache=True)
def _sbx_pair(p1: float, p2: float, u: float, below: float, above: float, sign: float,
              keep: bool) -> tuple[float, float]:  # pragma: no cover - compiled
    # one variable's two children, unclipped (the parents when `keep`)
    if keep:
        return p1, p2
    beta = below if u <= 0.5 else above
    beta *= -1.0 if sign < 0.5 else 1.0
    mid, half = (p1 + p2) / 2.0, (p1 - p2) / 2.0
    return mid + beta * half, mid - beta * half


@numba.njit(cache=True)
def _sbx(P1: F64, P2: F64, u: F64, below: F64, above: F64, sign: F64, var: F64, pair: F64, lo: F64, hi: F64,
         prob: float, prob_var: float) -> tuple[F64, F64]:  # pragma: no cover - compiled
    k, d = P1.shape
    C1, C2 = np.empty((k, d)), np.empty((k, d))
    for i in range(k):
        for j in range(d):
            c1, c2 = _sbx_pair(P1[i, j], P2[i, j], u[i, j], below[i, j], above[i, j], sign[i, j],
                               var[i, j] >= prob_var or pair[i] >= prob)
            C1[i, j] = _clip(c1, lo[j], hi[j])
            C2[i, j] = _clip(c2, lo[j], hi[j])
    return C1, C2


@numba.njit(cache=True)
def ga_half_row(p1: F64, p2: F64, u: F64, below: F64, above: F64, sign: F64, var: F64, pair: float, site: F64,
                um: F64, lo: F64, hi: F64, out: F64, prob: float = 1.0, prob_var: float = 0.5,
                eta_m: float = 20.0) -> None:  # pragma: no cover - compiled
    """One "GAhalf" child into ``out`` ``(d,)``: :func:`sbx`'s first child of ``p1``, ``p2`` from its numbers
    (``below``, ``above``: the powers of ``u`` as :func:`sbx` takes them), clipped, then :func:`polynomial_mutation`
    (``site``, ``um``; 1/d per variable): :func:`ga` with ``half`` on one pair, the same numbers."""
    d = len(p1)
    for j in range(d):
        c1, _ = _sbx_pair(p1[j], p2[j], u[j], below[j], above[j], sign[j], var[j] >= prob_var or pair >= prob)
        out[j] = _clip(c1, lo[j], hi[j])
    _pm_row(out, lo, hi, site, um, 1.0 / d, eta_m)


@numba.njit(cache=True)
def _pow(x: float, y: float) -> float:  # pragma: no cover - compiled
    """x ** y, by repeated multiplication when y is a small whole number (the usual η + 1): ~5x faster."""
    if y == np.floor(y) and abs(y) <= 64.0:
        k = int(abs(y))
        r, b = 1.0, x
        while k:
            if k & 1:
                r *= b
            b *= b
            k >>= 1
        return r if y >= 0 else 1.0 / r
    return x**y


@numba.njit(cache=True)
def _sbx_bounded(P1: F64, P2: F64, lo: F64, hi: F64, pair: F64, var: F64, u: F64, swap: F64, prob: float,
                 eta: float, prob_var: float, prob_bin: float) -> tuple[F64, F64]:  # pragma: no cover - compiled
    k, d = P1.shape
    C1, C2 = P1.copy(), P2.copy()
    e = 1.0 / (eta + 1.0)
    for i in range(k):
        if pair[i] >= prob:
            continue
        for j in range(d):
            p1, p2 = P1[i, j], P2[i, j]
            if var[i, j] >= prob_var or abs(p1 - p2) <= 1e-14 or lo[j] == hi[j]:
                continue
            y1, y2 = min(p1, p2), max(p1, p2)
            delta = y2 - y1
            r = u[i, j]
            alpha = 2.0 - _pow(1.0 + 2.0 * (y1 - lo[j]) / delta, -(eta + 1.0))
            bq = (r * alpha) ** e if r <= 1.0 / alpha else (1.0 / (2.0 - r * alpha)) ** e
            c1 = 0.5 * ((y1 + y2) - bq * delta)
            alpha = 2.0 - _pow(1.0 + 2.0 * (hi[j] - y2) / delta, -(eta + 1.0))
            bq = (r * alpha) ** e if r <= 1.0 / alpha else (1.0 / (2.0 - r * alpha)) ** e
            c2 = 0.5 * ((y1 + y2) + bq * delta)
            # pymoo orders the children like their parents, then exchanges them when (rand < prob_bin) XOR
            # (p1 > p2): the net effect is that the first child is the upper one with probability prob_bin.
            if swap[i, j] < prob_bin:
                c1, c2 = c2, c1
            C1[i, j] = min(max(c1, lo[j]), hi[j])
            C2[i, j] = min(max(c2, lo[j]), hi[j])
    return C1, C2


def sbx_bounded(P1: F64, P2: F64, xl: F64, xu: F64, rng: np.random.Generator, prob: float = 0.9,
                eta: float = 15.0, prob_var: float = 0.5, prob_bin: float = 0.5) -> tuple[F64, F64]:
    """Deb's bounded SBX as pymoo's NSGA-II does it (``pymoo.operators.crossover.sbx.cross_sbx``, the same
    distribution): the spread factor accounts for the distance to the bounds, so children near a bound are as
    likely as elsewhere.

    A pair crosses with probability ``prob``; a variable with ``prob_var`` (not where the parents are within
    1e-14 or the bounds are equal); children swap per variable with ``prob_bin``. Children are clipped.
    """
    P1, P2 = np.ascontiguousarray(P1, dtype=np.float64), np.ascontiguousarray(P2, dtype=np.float64)
    k, d = P1.shape
    lo, hi = _bounds(xl, xu, d)
    pair, var, u, swap = rng.random(k), rng.random((k, d)), rng.random((k, d)), rng.random((k, d))
    return _sbx_bounded(P1, P2, lo, hi, pair, var, u, swap, float(prob), float(eta), float(prob_var),
                        float(prob_bin))


def _bounds(xl: F64, xu: F64, d: int) -> tuple[F64, F64]:
    # contiguous (d,) float64 bounds as they are (the algorithms keep them so): no copy, no broadcast view
    if (type(xl) is np.ndarray and type(xu) is np.ndarray and xl.dtype == xu.dtype == np.float64
            and xl.shape == xu.shape == (d,) and xl.flags.c_contiguous and xu.flags.c_contiguous):
        return xl, xu
    return (np.ascontiguousarray(np.broadcast_to(np.asarray(xl, dtype=np.float64), (d,))),
            np.ascontiguousarray(np.broadcast_to(np.asarray(xu, dtype=np.float64), (d,))))


@numba.njit(cache=True)
def _pm_row(x: F64, lo: F64, hi: F64, site: F64, u: F64, pm: float, eta: float) -> None:  # pragma: no cover
    # one row in place
    p = 1.0 / (eta + 1.0)
    for j in range(len(x)):
        if site[j] >= pm:
            continue
        span = hi[j] - lo[j] if hi[j] > lo[j] else 1.0
        v, r = x[j], u[j]
        if r <= 0.5:
            dq = (2.0 * r + (1.0 - 2.0 * r) * _pow(1.0 - (v - lo[j]) / span, eta + 1.0)) ** p - 1.0
        else:
            dq = 1.0 - (2.0 * (1.0 - r) + 2.0 * (r - 0.5) * _pow(1.0 - (hi[j] - v) / span, eta + 1.0)) ** p
        x[j] = min(max(v + dq * span, lo[j]), hi[j])


@numba.njit(cache=True)
def _pm(X: F64, lo: F64, hi: F64, site: F64, u: F64, rows: NDArray[np.bool_], pm: float,
        eta: float) -> None:  # pragma: no cover - compiled
    for i in range(X.shape[0]):
        if rows[i]:
            _pm_row(X[i], lo, hi, site[i], u[i], pm, eta)


def polynomial_mutation(X: F64, xl: F64, xu: F64, rng: np.random.Generator, prob_var: float | None = None,
                        eta: float = 20.0, rows: NDArray[np.bool_] | None = None) -> F64:
    """Deb's bounded polynomial mutation, each variable with probability ``prob_var`` (default 1/d); only the
    ``rows`` given (a ``(n,)`` mask; default all). The result stays inside the bounds (a new array)."""
    X = np.array(X, dtype=np.float64, order="C")
    n, d = X.shape
    if n == 0:
        return X
    pm = 1.0 / d if prob_var is None else float(prob_var)
    lo, hi = _bounds(xl, xu, d)
    site, u = rng.random((n, d)), rng.random((n, d))
    sel = np.ones(n, dtype=np.bool_) if rows is None else np.asarray(rows, dtype=np.bool_)
    _pm(X, lo, hi, site, u, sel, pm, float(eta))
    return X


def ga(P1: F64, P2: F64, xl: F64, xu: F64, rng: np.random.Generator, half: bool = False, prob: float = 1.0,
       eta_c: float = 20.0, prob_var: float | None = None, eta_m: float = 20.0) -> F64:
    """PlatEMO's "GA": SBX then polynomial mutation; both children ``(2k, d)``, or only the first (``half``)."""
    c1, c2 = sbx(P1, P2, xl, xu, rng, prob, eta_c)
    C = c1 if half else np.vstack([c1, c2])
    return polynomial_mutation(C, xl, xu, rng, prob_var, eta_m)


def de_rand_1(X1: F64, X2: F64, X3: F64, xl: F64, xu: F64, rng: np.random.Generator, F: float | F64 = 0.5,
              CR: float | F64 = 1.0, prob_var: float | None = None, eta_m: float = 20.0) -> F64:
    """DE/rand/1 (PlatEMO's default): ``x1 + F (x2 - x3)`` on every variable with rand < CR (no forced j_rand),
    clipped, then polynomial mutation. ``F`` and ``CR`` are scalars or ``(k, 1)`` per-child values."""
    if isinstance(F, float) and isinstance(CR, float) and X1.shape == X2.shape == X3.shape and X1.ndim == 2:
        # scalar F and CR (the usual case): one compiled pass, the same numbers and random draws as below
        n, d = X1.shape
        lo, hi = _bounds(xl, xu, d)
        r = rng.random((n, d))
        if n == 0:
            return np.array(X1, dtype=np.float64, order="C")
        site, u = rng.random((n, d)), rng.random((n, d))
        return _de_pm(np.ascontiguousarray(X1, dtype=np.float64), np.ascontiguousarray(X2, dtype=np.float64),
                      np.ascontiguousarray(X3, dtype=np.float64), r, site, u, lo, hi, F, CR,
                      1.0 / d if prob_var is None else float(prob_var), float(eta_m))
    trial = X1 + F * (X2 - X3)
    C = np.where(rng.random(X1.shape) < CR, trial, X1)
    return polynomial_mutation(np.clip(C, xl, xu), xl, xu, rng, prob_var, eta_m)


@numba.njit(cache=True)
def de_row(x1: F64, x2: F64, x3: F64, r: F64, site: F64, u: F64, lo: F64, hi: F64, out: F64, F: float, CR: float,
           pm: float, eta_m: float) -> None:  # pragma: no cover - compiled
    """One DE/rand/1 child into ``out`` ``(d,)`` from its numbers: ``x1 + F (x2 - x3)`` where ``r < CR``, clipped (NaN
    passes through, as in np.clip), then polynomial mutation (``site`` against ``pm``, ``u``): :func:`de_rand_1`
    with scalar ``F`` and ``CR`` on one row, the same numbers."""
    for j in range(len(x1)):
        c = x1[j] + F * (x2[j] - x3[j]) if r[j] < CR else x1[j]
        out[j] = _clip(c, lo[j], hi[j])
    _pm_row(out, lo, hi, site, u, pm, eta_m)


@numba.njit(cache=True)
def _de_pm(X1: F64, X2: F64, X3: F64, r: F64, site: F64, u: F64, lo: F64, hi: F64, F: float, CR: float, pm: float,
           eta: float) -> F64:  # pragma: no cover - compiled
    C = np.empty(X1.shape)
    for i in range(X1.shape[0]):
        de_row(X1[i], X2[i], X3[i], r[i], site[i], u[i], lo, hi, C[i], F, CR, pm, eta)
    return C


def de_current_to_pbest_1(X: F64, Xpbest: F64, X2: F64, X3: F64, xl: F64, xu: F64, rng: np.random.Generator,
                          F: float | F64 = 0.5, CR: float | F64 = 1.0, prob_var: float | None = None,
                          eta_m: float = 20.0) -> F64:
    """DE/current-to-pbest/1 as IMTCMO's (spec §5): ``x + F (x_pbest - x + x2 - x3)`` on every variable with
    rand < CR (no forced j_rand), clipped, then polynomial mutation. ``F``, ``CR``: scalars or ``(k, 1)``."""
    trial = X + F * (Xpbest - X + X2 - X3)
    C = np.where(rng.random(X.shape) < CR, trial, X)
    return polynomial_mutation(np.clip(C, xl, xu), xl, xu, rng, prob_var, eta_m)


def uniform(n: int, xl: F64, xu: F64, rng: np.random.Generator) -> F64:
    """``(n, d)`` members uniform in the bounds."""
    return rng.uniform(xl, xu, size=(n, len(xl)))
