"""Variation operators over arrays (PlatEMO's variants, spec §1.5): SBX, polynomial mutation, DE/rand/1.

Every operator clips to the bounds before mutation; mutation keeps members inside the bounds.
"""

from __future__ import annotations

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
    beta = np.where(u <= 0.5, (2.0 * u) ** (1.0 / (eta + 1.0)), (2.0 - 2.0 * u) ** (-1.0 / (eta + 1.0)))
    beta *= np.where(rng.random((k, d)) < 0.5, -1.0, 1.0)
    keep = rng.random((k, d)) >= prob_var
    keep[rng.random(k) >= prob] = True
    mid, half = (P1 + P2) / 2.0, (P1 - P2) / 2.0
    # β = 1 gives the parents back; taken as they are (no rounding through the mean).
    c1 = np.where(keep, P1, mid + beta * half)
    c2 = np.where(keep, P2, mid - beta * half)
    return np.clip(c1, xl, xu), np.clip(c2, xl, xu)


def sbx_bounded(P1: F64, P2: F64, xl: F64, xu: F64, rng: np.random.Generator, prob: float = 0.9,
                eta: float = 15.0, prob_var: float = 0.5, prob_bin: float = 0.5) -> tuple[F64, F64]:
    """Deb's bounded SBX as pymoo's NSGA-II does it (``pymoo.operators.crossover.sbx.cross_sbx``): the spread
    factor accounts for the distance to the bounds, so children near a bound are as likely as elsewhere.

    A pair crosses with probability ``prob``; a variable with ``prob_var``; children swap per variable with
    ``prob_bin``.
    """
    from pymoo.operators.crossover.sbx import cross_sbx

    k = len(P1)
    X = np.stack([P1, P2]).astype(np.float64)
    Q = X.copy()
    do = rng.random(k) < prob
    m = int(do.sum())
    if m:
        Q[:, do] = cross_sbx(X[:, do], np.asarray(xl, dtype=np.float64), np.asarray(xu, dtype=np.float64),
                             np.full((m, 1), eta), np.full((m, 1), prob_var), np.full((m, 1), prob_bin),
                             random_state=rng)
    return Q[0], Q[1]


def polynomial_mutation(X: F64, xl: F64, xu: F64, rng: np.random.Generator, prob_var: float | None = None,
                        eta: float = 20.0) -> F64:
    """Deb's bounded polynomial mutation, each variable with probability ``prob_var`` (default 1/d)."""
    X = np.array(X, dtype=np.float64)
    n, d = X.shape
    if n == 0:
        return X
    pm = 1.0 / d if prob_var is None else prob_var
    mask = rng.random((n, d)) < pm
    u = rng.random((n, d))
    span = np.where(xu > xl, xu - xl, 1.0)
    d1 = (X - xl) / span
    d2 = (xu - X) / span
    p = 1.0 / (eta + 1.0)
    low = u <= 0.5
    with np.errstate(invalid="ignore"):
        dq_lo = (2.0 * u + (1.0 - 2.0 * u) * (1.0 - d1) ** (eta + 1.0)) ** p - 1.0
        dq_hi = 1.0 - (2.0 * (1.0 - u) + 2.0 * (u - 0.5) * (1.0 - d2) ** (eta + 1.0)) ** p
    dq = np.where(low, dq_lo, dq_hi)
    Y = np.where(mask, X + dq * span, X)
    return np.clip(Y, xl, xu)


def ga(P1: F64, P2: F64, xl: F64, xu: F64, rng: np.random.Generator, half: bool = False, prob: float = 1.0,
       eta_c: float = 20.0, prob_var: float | None = None, eta_m: float = 20.0) -> F64:
    """PlatEMO's "GA": SBX then polynomial mutation; both children ``(2k, d)``, or only the first (``half``)."""
    c1, c2 = sbx(P1, P2, xl, xu, rng, prob, eta_c)
    C = c1 if half else np.vstack([c1, c2])
    return polynomial_mutation(C, xl, xu, rng, prob_var, eta_m)


def de_rand_1(X1: F64, X2: F64, X3: F64, xl: F64, xu: F64, rng: np.random.Generator, F: float = 0.5,
              CR: float = 1.0, prob_var: float | None = None, eta_m: float = 20.0) -> F64:
    """DE/rand/1 (PlatEMO's default): ``x1 + F (x2 - x3)`` on every variable with rand < CR (no forced j_rand),
    clipped, then polynomial mutation."""
    trial = X1 + F * (X2 - X3)
    C = np.where(rng.random(X1.shape) < CR, trial, X1)
    return polynomial_mutation(np.clip(C, xl, xu), xl, xu, rng, prob_var, eta_m)


def de_current_to_pbest_1(X: F64, Xpbest: F64, X2: F64, X3: F64, xl: F64, xu: F64, rng: np.random.Generator,
                          F: float = 0.5, CR: float = 0.9) -> F64:
    """DE/current-to-pbest/1/bin: ``x + F (x_pbest - x) + F (x2 - x3)``, binomial crossover with a forced
    variable, clipped (IMTCMO's variant; no mutation)."""
    n, d = X.shape
    trial = X + F * (Xpbest - X) + F * (X2 - X3)
    mask = rng.random((n, d)) < CR
    mask[np.arange(n), rng.integers(0, d, n)] = True
    return np.clip(np.where(mask, trial, X), xl, xu)


def uniform(n: int, xl: F64, xu: F64, rng: np.random.Generator) -> F64:
    """``(n, d)`` members uniform in the bounds."""
    return rng.uniform(xl, xu, size=(n, len(xl)))
