"""Checks every constrained MOEA's tests share (imported by tests/test_<algorithm>.py)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from pymoo.optimize import minimize

from core.optimize.moea import problem_by_name

F64 = np.ndarray


def replace_ok(g_old: F64, g_new: F64, cv_old: F64, cv_new: float, eps: float, pull: bool) -> np.ndarray:
    """CMOEMT's task-2 rule as the spec states it (the numpy form the compiled placement in
    core/optimize/evolve/moead.py is held to): which neighbours a child may replace, by Tchebycheff alone
    (push) or by the improved epsilon rule (pull)."""
    better = g_old >= g_new
    if not pull:
        return better
    return (better & (((cv_old <= eps) & (cv_new <= eps)) | (cv_old == cv_new))) | (cv_new < cv_old)


def logistic(x: F64, sigma: float) -> F64:
    """MOEA/D-CMT's soft comparison L(x; sigma) = 1 / (1 + e^(-x / sigma)) as the spec states it; 0.5 where
    x == 0, a step where sigma == 0 (spec §7 pitfall 1)."""
    x = np.asarray(x, dtype=np.float64)
    if sigma <= 0:
        return np.where(x > 0, 1.0, np.where(x < 0, 0.0, 0.5))
    with np.errstate(over="ignore", invalid="ignore"):
        return np.where(x == 0, 0.5, 1.0 / (1.0 + np.exp(-x / sigma)))


class Halve:
    """A repair that halves every variable (and counts its calls)."""

    def __init__(self) -> None:
        self.calls = 0

    def _do(self, problem: Any, X: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.clip(X * 0.5, problem.xl, problem.xu)


def check_repair_and_generations(make: Callable[..., Any], problem: str = "mw3", n_gen: int = 5) -> None:
    """The algorithm applies the stage's repair to every member it evaluates and honours an n_gen budget."""
    p = problem_by_name(problem)
    repair = Halve()
    alg = make(repair=repair, seed=2)
    res = minimize(p, alg, ("n_gen", n_gen), seed=2, copy_algorithm=False)
    assert repair.calls >= n_gen and len(alg.trace) == n_gen
    assert np.all(res.pop.get("X") <= 0.5 * p.xu + 1e-12)


def check_seed(run: Callable[..., Any], problem: str, evals: int, seed: int, **options: Any) -> None:
    """Same seed, same final population; the next seed, another. ``run(problem, evals, seed=, **options)``
    returns (pymoo result, algorithm), as each algorithm's test module defines it."""
    a, _ = run(problem, evals, seed=seed, **options)
    b, _ = run(problem, evals, seed=seed, **options)
    c, _ = run(problem, evals, seed=seed + 1, **options)
    X = a.pop.get("X")
    assert np.array_equal(X, b.pop.get("X")) and not np.array_equal(X, c.pop.get("X"))
