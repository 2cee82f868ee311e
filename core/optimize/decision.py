"""Knee points and candidate ranking on a final population (paper §3.2.4; docs/decision.md).

The paper's first decision step reduces a Pareto set to fewer than ten representative
candidates by knee-point identification; the designer then chooses by hand. This module
does the objective part:

1. keep the feasible members (``cv <= 0``) with finite objectives; drop NaN rows;
2. keep the non-dominated ones (the front) and collapse duplicate objective vectors;
3. normalise by the front's ideal and nadir points;
4. score every front member by its signed distance to the hyperplane through the extreme
   points (the convex knee of Das 1999 and Deb & Gupta 2011; KnEA's knee measure);
5. return the local maxima of that score (no better-ranked point within ``radius``) that
   score above zero, ranked, at most ``n_max``; if none does (a straight or concave front),
   the one member nearest the ideal point; plus the best member per objective.

With no feasible member the shortlist is empty and ``fallback`` names the member of least
violation. Pure numpy; no pymoo.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
METHOD = "hyperplane"

# Scores closer than this are ties (normalised units), broken by distance to the ideal point.
SCORE_TOL = 1e-9
# A normalised span below this (relative) is a degenerate objective: it does not vary on the front.
SPAN_TOL = 1e-12


@dataclass(frozen=True)
class Shortlist:
    """Decision candidates of a population; every index refers to rows of the input F.

    Attributes:
        knees: ranked knee candidates (best first), distinct objective vectors, at most n_max.
        scores: distance of each entry of ``knees`` to the extreme-point hyperplane (normalised units).
        best: per objective, the feasible member with the smallest value (ties: smallest
            other objectives, then lowest index); empty when nothing is feasible.
        front: the feasible non-dominated members (duplicates kept), ascending.
        fallback: least-violation member when nothing is feasible, else None.
        method: the knee measure used (recorded with saved results).
    """

    knees: tuple[int, ...]
    scores: tuple[float, ...]
    best: tuple[int, ...]
    front: tuple[int, ...]
    fallback: int | None
    method: str = METHOD

    @property
    def candidates(self) -> tuple[int, ...]:
        """Knees then best-per-objective members, without repeats (display order)."""
        return tuple(dict.fromkeys(self.knees + self.best))

    @property
    def first(self) -> int | None:
        """The automatic pick: the first knee, else the least-violation fallback."""
        return self.knees[0] if self.knees else self.fallback


def usable(F: F64, cv: F64 | None = None) -> NDArray[np.bool_]:
    """``(pop,)`` True for rows with finite objectives and ``cv <= 0`` (NaN cv is not feasible)."""
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    ok = np.asarray(np.all(np.isfinite(F), axis=1), dtype=bool)
    if cv is not None:
        cv = np.asarray(cv, dtype=np.float64).reshape(-1)
        with np.errstate(invalid="ignore"):
            ok &= cv <= 0.0
    return ok


def dominated(F: F64, block: int = 256) -> NDArray[np.bool_]:
    """``(n,)`` True where some other row Pareto-dominates the row (all <=, one <). Finite F only."""
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    n = F.shape[0]
    out = np.zeros(n, dtype=bool)
    for start in range(0, n, block):  # blocks bound the (block, n, n_obj) temporary
        a = F[start : start + block, None, :]
        le = np.all(F[None, :, :] <= a, axis=-1)
        lt = np.any(F[None, :, :] < a, axis=-1)
        out[start : start + block] = (le & lt).any(axis=1)
    return out


def pareto_front(F: F64, cv: F64 | None = None) -> NDArray[np.intp]:
    """Indices (ascending) of the feasible, finite, non-dominated rows of ``F (pop, n_obj)``."""
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    idx = np.flatnonzero(usable(F, cv))
    if idx.size == 0:
        return idx
    return idx[~dominated(F[idx])]


def best_per_objective(F: F64, cv: F64 | None = None) -> tuple[int, ...]:
    """Per objective m, the usable row minimising f_m; ties by the other objectives in order, then index."""
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    idx = np.flatnonzero(usable(F, cv))
    if idx.size == 0:
        return ()
    sub = F[idx]
    out = []
    for m in range(F.shape[1]):
        keys = [sub[:, k] for k in range(F.shape[1]) if k != m]
        order = np.lexsort([idx] + keys[::-1] + [sub[:, m]])  # last key is primary
        out.append(int(idx[order[0]]))
    return tuple(out)


def normalize(F: F64) -> tuple[F64, F64, F64]:
    """Scale a front to the unit box by its ideal and nadir points.

    Args:
        F: ``(n, n_obj)`` finite objective values of a front.

    Returns:
        ``(Fn, ideal, nadir)``: ``Fn (n, n_obj)`` in [0, 1]; a column that does not vary is 0.
    """
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    ideal, nadir = F.min(axis=0), F.max(axis=0)
    span = nadir - ideal
    live = span > SPAN_TOL * np.maximum(1.0, np.abs(ideal))
    Fn = np.zeros_like(F)
    Fn[:, live] = (F[:, live] - ideal[live]) / span[live]
    return Fn, ideal, nadir


def extreme_hyperplane(Fn: F64) -> F64:
    """Normal ``w`` of the hyperplane ``w . f = 1`` through the extreme points of a normalised front.

    The extreme point of objective m is the front member minimising f_m (ties broken by
    the other objectives). In 2-D after normalisation they are (0, 1) and (1, 0), so the
    plane is f1 + f2 = 1. When the M extreme points do not span a plane with positive
    intercepts (repeated extreme points, or a tilted 3-D front), fall back to the plane
    through the unit points, ``w = (1, ..., 1)``.
    """
    n_obj = Fn.shape[1]
    ext = Fn[list(best_per_objective(Fn))]
    ones = np.ones(n_obj)
    try:
        w = np.asarray(np.linalg.solve(ext, ones), dtype=np.float64)
    except np.linalg.LinAlgError:
        return ones
    if not np.all(np.isfinite(w)) or np.any(w <= 0.0) or np.linalg.cond(ext) > 1e12:
        return ones
    return w


def hyperplane_distance(Fn: F64) -> F64:
    """``(n,)`` signed distance of each normalised point to the extreme-point hyperplane.

    Positive on the ideal side of the plane (a convex bulge); the knee of Das (1999) and
    Deb & Gupta (2011) is the point of largest distance. Extreme points score 0.
    """
    w = extreme_hyperplane(Fn)
    return (1.0 - Fn @ w) / np.linalg.norm(w)


def _least_violation(F: F64, cv: F64 | None) -> int | None:
    if cv is None:
        return None
    cv = np.asarray(cv, dtype=np.float64).reshape(-1)
    if np.isnan(cv).all():
        return None
    key = np.where(np.isnan(cv), np.inf, cv)
    defined = np.isfinite(np.atleast_2d(F)).all(axis=1)
    # Least violation; among equals prefer members with defined objectives, then lower index.
    order = np.lexsort((np.arange(len(cv)), ~defined, key))
    return int(order[0])


def shortlist(
    F: F64,
    cv: F64 | None = None,
    *,
    n_max: int = 10,
    radius: float = 0.1,
) -> Shortlist:
    """Knee candidates and best-per-objective members of a population.

    Args:
        F: ``(pop, n_obj)`` objective values (minimised); NaN/inf rows are ignored.
        cv: ``(pop,)`` total constraint violation (>= 0; 0 is feasible); None: all feasible.
        n_max: at most this many knees.
        radius: neighbourhood radius in normalised objective space; a knee has no
            better-ranked front point closer than this.

    Returns:
        The :class:`Shortlist`; indices refer to rows of F.
    """
    if isinstance(n_max, bool) or not isinstance(n_max, (int, np.integer)) or n_max < 1:
        raise ValueError(f"n_max must be an integer >= 1 (the knee pick needs one), got {n_max!r}")
    if not (np.isfinite(radius) and radius >= 0):
        raise ValueError(f"radius must be a finite number >= 0, got {radius!r}")
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    front = pareto_front(F, cv)
    if front.size == 0:
        return Shortlist((), (), (), (), _least_violation(F, cv))
    best = best_per_objective(F, cv)
    # Collapse duplicate objective vectors to their first member.
    _, first = np.unique(F[front], axis=0, return_index=True)
    uniq = front[np.sort(first)]
    Fn, _, _ = normalize(F[uniq])
    live = Fn.max(axis=0) > 0.0
    Fn = Fn[:, live]
    if uniq.size == 1 or not live.any():
        # One distinct point, or points that differ only by rounding: nothing to trade off.
        return Shortlist((int(uniq[0]),), (0.0,), best, tuple(int(i) for i in front), None)
    score = hyperplane_distance(Fn)
    to_ideal = np.linalg.norm(Fn, axis=1)
    quant = np.round(score / SCORE_TOL)
    order = np.lexsort((uniq, to_ideal, -quant))  # score desc, then nearer the ideal, then index
    rank = np.empty(uniq.size, dtype=np.intp)
    rank[order] = np.arange(uniq.size)
    dist = np.linalg.norm(Fn[:, None, :] - Fn[None, :, :], axis=-1)
    near = dist < radius
    better_near = (near & (rank[None, :] < rank[:, None])).any(axis=1)
    knees = [i for i in order if not better_near[i] and score[i] > SCORE_TOL][:n_max]
    if not knees:  # no convex bulge (a straight or concave front): the compromise nearest the ideal
        knees = [int(np.lexsort((uniq, to_ideal))[0])]
    return Shortlist(
        knees=tuple(int(uniq[i]) for i in knees),
        scores=tuple(float(score[i]) for i in knees),
        best=best,
        front=tuple(int(i) for i in front),
        fallback=None,
    )
