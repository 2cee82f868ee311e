"""Algorithms on constrained test problems (pymoo's, and PlatEMO's DC-DTLZ from :mod:`core.optimize.dcdtlz`):
problems by name, reference fronts shipped with the package or computed, and IGD and HV measured as PlatEMO
measures them (spec §1.7). Used by ``clm moea`` and ``benchmarks/algorithms.py``.

Both indicators use the feasible non-dominated members of the final population only; IGD is NaN when
there is none. HV normalises by ``(F - fmin) / ((fmax - fmin) * 1.1)`` with ``fmin = min(min F, 0)`` and
``fmax`` the reference front's maximum, drops points with a coordinate > 1, reference point (1, ..., 1).

Some problems compute NaN objectives outside their defined region (MW11's square root of a negative, CTP3's
0 / 0); the algorithms read NaN as +inf (never better than anything), so numpy's warnings about them are not
printed during a run.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import moocore
import numpy as np
from numpy.typing import NDArray
from pymoo.core.problem import Problem
from pymoo.indicators.igd import IGD
from pymoo.optimize import minimize

from core.optimize.algorithms import AlgorithmSpec, make_algorithm
from core.optimize.dcdtlz import DCDTLZ
from core.optimize.decision import pareto_front
from core.optimize.problem_names import DC_DTLZ, DTLZ, KNOWN, PROBLEMS

F64 = NDArray[np.float64]
FRONTS = Path(__file__).resolve().parent / "evolve" / "fronts"
DASCMOP_DIFFICULTY = 8  # (0.5, 0.5, 0.5): PlatEMO's for DAS-CMOP3-9; its DAS-CMOP1-2 use (0, 0.5, 0.5) (spec §8.1)
LATTICE = 5050  # reference points of a 3-objective DTLZ front (Das-Dennis, H = 99), before C2-DTLZ2's cut
MAX_EVALS = 10**8


def problem_by_name(name: str) -> Problem:
    """A pymoo test problem by name (``mw1``…``mw14``, ``ctp1``…``ctp8``, ``dascmop1``…``dascmop9`` at
    difficulty 8, ``zdt1``…``zdt3``, the DTLZ and constrained DTLZ problems of :data:`DTLZ` and PlatEMO's DC-DTLZ
    at 3 objectives); ValueError naming the known ones otherwise."""
    from pymoo.problems import get_problem

    key = name.lower()
    if key not in PROBLEMS:
        raise ValueError(f"unknown problem {name!r}; known: {KNOWN}")
    if key in DTLZ:
        return get_problem(key, n_var=DTLZ[key], n_obj=3)
    if key in DC_DTLZ:
        return DCDTLZ(int(key[2]), int(key[-1]), 3)
    return get_problem(key, DASCMOP_DIFFICULTY) if key.startswith("dascmop") else get_problem(key)


def reference_front(name: str) -> F64 | None:
    """The problem's true Pareto front: a shipped file (MW, CTP, DAS-CMOP), pymoo's analytic one (ZDT; DTLZ and
    constrained DTLZ on a Das-Dennis lattice of 5050 directions, C2-DTLZ2's and DC-DTLZ's cut to their feasible
    parts), else None."""
    key = name.lower()
    for f in (FRONTS / f"{key.upper()}.pf", FRONTS / f"{key}.pf"):
        if f.is_file():
            return np.loadtxt(f, ndmin=2)
    if key.startswith("zdt"):
        return np.asarray(problem_by_name(key).pareto_front(), dtype=np.float64)
    if key in DTLZ or key in DC_DTLZ:
        from core.optimize.evolve.weights import simplex_lattice

        directions = simplex_lattice(LATTICE, 3)
        return np.asarray(problem_by_name(key).pareto_front(ref_dirs=directions), dtype=np.float64)
    return None


def feasible_front_mask(F: F64, cv: F64 | None = None) -> NDArray[np.bool_]:
    """``(n,)`` True for the members IGD and HV measure: feasible, finite, non-dominated (copies of a point each)."""
    F = np.asarray(F, dtype=np.float64).reshape(len(F), -1) if len(F) else np.zeros((0, 1))
    ok = np.isfinite(F).all(axis=1) if cv is None else (np.asarray(cv) <= 0) & np.isfinite(F).all(axis=1)
    idx = np.flatnonzero(ok)
    mask = np.zeros(len(F), dtype=bool)
    if len(idx):
        mask[idx[pareto_front(F[idx])]] = True
    return mask


def feasible_front(F: F64, cv: F64 | None = None) -> F64:
    F = np.asarray(F, dtype=np.float64).reshape(len(F), -1) if len(F) else np.zeros((0, 1))
    return F[feasible_front_mask(F, cv)]


def igd(F: F64, pf: F64 | None) -> float:
    """Mean distance from each reference point to its nearest member of F (NaN without members or front)."""
    if pf is None or len(F) == 0:
        return float("nan")
    return float(IGD(pf)(np.asarray(F, dtype=np.float64)))


def hv_platemo(F: F64, pf: F64 | None) -> float:
    """PlatEMO's normalised hypervolume (module doc); 0 without members, NaN without a front."""
    if pf is None:
        return float("nan")
    F = np.asarray(F, dtype=np.float64)
    if len(F) == 0:
        return 0.0
    fmin = np.minimum(F.min(axis=0), 0.0)
    fmax = pf.max(axis=0)
    Fn = (F - fmin) / ((fmax - fmin) * 1.1)
    Fn = Fn[(Fn <= 1.0).all(axis=1)]
    if len(Fn) == 0:
        return 0.0
    return float(moocore.hypervolume(Fn, ref=np.ones(F.shape[1])))


def run(problem: str, algorithm: str, pop: int, evals: int, seed: int, options: dict[str, Any] | None = None,
        population: bool = False) -> dict[str, Any]:
    """Run an algorithm on a test problem for ``evals`` function evaluations; IGD, HV, evaluations, the final
    population's size (``size``: the Das-Dennis N of the decomposition-based ones, e.g. 91 for ``pop`` 100) and
    feasible count, and wall time. ``population``: also the final population under ``"population"``: ``X`` (n, d),
    ``F`` (n, m), ``cv`` (n,) and ``front`` (n,) True for the members IGD and HV measure (feasible, finite,
    non-dominated), so a reader can check both indicators."""
    if not 4 <= pop <= 100_000:
        raise ValueError(f"--pop must be between 4 and 100000, got {pop}")
    if not 1 <= evals <= MAX_EVALS:
        raise ValueError(f"--evals must be between 1 and {MAX_EVALS}, got {evals}")
    if not 0 <= seed <= 2**32 - 1:
        raise ValueError(f"--seed must be between 0 and {2**32 - 1}, got {seed}")
    p = problem_by_name(problem)
    alg = make_algorithm(AlgorithmSpec(algorithm, pop, options or {}), p.n_obj, seed)
    t = time.perf_counter()
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # see the module's docstring
        res = minimize(p, alg, ("n_eval", evals), seed=seed)
    wall = time.perf_counter() - t
    pop_ = res.pop
    F = np.asarray(pop_.get("F"), dtype=np.float64)
    cv = np.asarray(pop_.get("CV"), dtype=np.float64).reshape(-1)
    on_front = feasible_front_mask(F, cv)
    front = F[on_front]
    pf = reference_front(problem)
    out = {"problem": problem.lower(), "algorithm": algorithm, "pop": pop, "seed": seed,
           "igd": igd(front, pf), "hv": hv_platemo(front, pf), "n_eval": int(res.algorithm.evaluator.n_eval),
           "feasible": int((cv <= 0).sum()), "size": int(len(cv)),
           "front_size": int(len(np.unique(front, axis=0))) if len(front) else 0, "wall_time": wall,
           "reference_points": 0 if pf is None else int(len(pf))}
    if population:
        out["population"] = {"X": np.asarray(pop_.get("X"), dtype=np.float64), "F": F, "cv": cv, "front": on_front}
    return out
