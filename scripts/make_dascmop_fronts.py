"""Write the reference Pareto fronts of DAS-CMOP1-9 at difficulty 8 (eta = zeta = gamma = 0.5) to
core/optimize/evolve/fronts/dascmop{1..9}.pf. Run: python scripts/make_dascmop_fronts.py (deterministic).

How they are derived, from pymoo's own code (pymoo/problems/multi/dascmop.py):
- Every objective is s(x) + g, where x = x1 (DAS-CMOP1-6) or (x1, x2) (DAS-CMOP7-9) and g >= 0 is the
  distance function of the other variables, which can take any value in [0, 7] (at least) whatever x is.
- The constraints are: a diversity constraint on x alone; d <= g <= e (d = 0.5, e = d - ln 0.5); and
  "stay outside" ellipses (1-6) or spheres (7-9) in objective space.
- For a fixed x, a larger g is dominated by a smaller one, so only the smallest feasible g*(x) counts.
  Along F = s(x) + t, g = t every constraint column is a quadratic in t (constant for the diversity
  one), so g*(x) is a root of one of them: the smallest root at which all of pymoo's constraints hold.
- The front is the non-dominated set of s(x) + g*(x) over a fine grid of x (the grid has the ends of the
  diversity intervals as nodes), thinned by farthest-point sampling that starts from each objective's
  minimum and maximum.
At this difficulty the spheres of 7-9 never reach the region g >= d, so those fronts lie at g = d; in 2/5
and 3/6 the ellipse centred at (1, 0.5) lifts parts of the front to g of up to 0.533.
"""

from __future__ import annotations

from pathlib import Path

import moocore
import numpy as np
from pymoo.problems import get_problem

OUT = Path(__file__).resolve().parents[1] / "core" / "optimize" / "evolve" / "fronts"
DIFFICULTY = 8
TOL = 1e-12  # a constraint value this small counts as met (points on a constraint's boundary)
GRID = {2: 40001, 3: 601}  # nodes per position variable: steps of 1/40000 and 1/600 hit every k/40
SIZE = {2: 1000, 3: 2000}  # points written per front
CHUNK = 100_000


def shape(k: int, problem, P: np.ndarray) -> np.ndarray:
    """pymoo's F at positions P with the distance variables at g's minimiser, i.e. s(x) (g = 0)."""
    n_pos, n_dist = P.shape[1], problem.n_var - P.shape[1]
    if k <= 3:  # g1: x_j = sin(pi x1 / 2)
        D = np.repeat(np.sin(0.5 * np.pi * P[:, :1]), n_dist, axis=1)
    elif k <= 8:  # g2: x_j = 0.5
        D = np.full((len(P), n_dist), 0.5)
    else:  # g3: x_j = cos(pi j (x1 + x2) / (4 n)), j = 3..n
        j = np.arange(n_pos, problem.n_var) + 1
        D = np.cos(0.25 * j / problem.n_var * np.pi * (P[:, 0:1] + P[:, 1:2]))
    F = problem.evaluate(np.hstack([P, D]), return_as_dictionary=True)["F"]
    return np.asarray(F, dtype=np.float64)


def constraints(problem, P: np.ndarray, S: np.ndarray, t: np.ndarray) -> np.ndarray:
    """pymoo's G (feasible: <= 0) at positions P, objectives S + t and distance value g = t."""
    t = t.reshape(-1, 1)
    F = S + t
    return np.asarray(problem.constraints(P, *np.split(F, F.shape[1], axis=1), t), dtype=np.float64)


def smallest_feasible_g(problem, P: np.ndarray, S: np.ndarray) -> np.ndarray:
    """g*(x) per row (inf where no g is feasible)."""
    n = len(P)
    G0, G1, Gm = (constraints(problem, P, S, np.full(n, v)) for v in (0.0, 1.0, -1.0))
    a, b, c = (G1 + Gm) / 2 - G0, (G1 - Gm) / 2, G0
    check = constraints(problem, P, S, np.full(n, 0.5))
    assert np.abs(a / 4 + b / 2 + c - check).max() < 1e-9, "a constraint is not quadratic in g"
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(b * b - 4 * a * c)
        roots = np.concatenate([(-b - root) / (2 * a), (-b + root) / (2 * a)], axis=1)
    roots[~np.isfinite(roots)] = np.inf
    roots.sort(axis=1)
    best = np.full(n, np.inf)
    for col in roots.T:  # ascending per row: the first feasible root is the smallest
        todo = np.flatnonzero(np.isinf(best) & np.isfinite(col))
        if todo.size == 0:
            continue
        ok = constraints(problem, P[todo], S[todo], col[todo]).max(axis=1) <= TOL
        best[todo[ok]] = col[todo[ok]]
    return best


def thin(F: np.ndarray, size: int) -> np.ndarray:
    """``size`` rows of F by farthest-point sampling, seeded by each objective's minimum and maximum."""
    if len(F) <= size:
        return F
    chosen = sorted({int(i) for m in range(F.shape[1]) for i in (F[:, m].argmin(), F[:, m].argmax())})
    dist = np.min([((F - F[i]) ** 2).sum(axis=1) for i in chosen], axis=0)  # squared, to the chosen set
    while len(chosen) < size:
        i = int(dist.argmax())
        chosen.append(i)
        dist = np.minimum(dist, ((F - F[i]) ** 2).sum(axis=1))
    return F[chosen]


def front(k: int) -> np.ndarray:
    problem = get_problem(f"dascmop{k}", DIFFICULTY)
    axis = np.linspace(0.0, 1.0, GRID[problem.n_obj])
    P_all = np.stack(np.meshgrid(*[axis] * (problem.n_obj - 1), indexing="ij"), axis=-1)
    P_all = P_all.reshape(-1, problem.n_obj - 1)
    parts = []
    for start in range(0, len(P_all), CHUNK):
        P = P_all[start : start + CHUNK]
        S = shape(k, problem, P)
        g = smallest_feasible_g(problem, P, S)
        F = S[np.isfinite(g)] + g[np.isfinite(g), None]
        parts.append(F[moocore.is_nondominated(F)])
    F = np.concatenate(parts)
    F = thin(F[moocore.is_nondominated(F)], SIZE[problem.n_obj])
    return F[np.lexsort(F.T[::-1])]


def main() -> None:
    for k in range(1, 10):
        F = front(k)
        path = OUT / f"dascmop{k}.pf"
        np.savetxt(path, F, fmt="%.12g")
        print(f"{path.name}: {len(F)} points, {path.stat().st_size} bytes")


if __name__ == "__main__":
    main()
