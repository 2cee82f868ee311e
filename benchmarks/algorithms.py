"""Algorithms: bookkeeping time per generation, and IGD/HV on constrained test problems.

    python benchmarks/algorithms.py            # bookkeeping at pop 200; IGD/HV over 10 seeds, 50 000 evaluations
    python benchmarks/algorithms.py --quick    # fewer generations and seeds, 5 000 evaluations (CI)

Bookkeeping is everything a generation costs but evaluation (mating, variation, duplicate elimination,
survival, pymoo objects), measured on DTLZ2 with 16 variables and 3 objectives at pop 200, whose evaluation
is a few microseconds. Target (issue 11): <= 1 ms per generation for NSGA-II. The quality table gives the
median IGD and HV (PlatEMO's normalisation, spec §1.7) per algorithm and problem, with the Wilcoxon rank-sum
verdict against pymoo's NSGA-II (+ better, - worse, ≈ no significant difference at 5 %).
Not a test: wall-clock numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from pymoo.core.problem import Problem  # noqa: E402
from pymoo.optimize import minimize  # noqa: E402
from pymoo.problems import get_problem  # noqa: E402
from scipy.stats import ranksums  # noqa: E402

from core.optimize.algorithms import AlgorithmSpec, make_algorithm  # noqa: E402
from core.optimize.moea import hv_platemo, igd, reference_front  # noqa: E402

REFERENCE = "nsga2_pymoo"


class Timed(Problem):
    """A problem that adds up the time spent in its own evaluation."""

    def __init__(self, inner: Problem) -> None:
        super().__init__(n_var=inner.n_var, n_obj=inner.n_obj, n_ieq_constr=inner.n_ieq_constr, xl=inner.xl,
                         xu=inner.xu)
        self.inner, self.spent = inner, 0.0

    def _evaluate(self, X, out, *args, **kwargs):
        t = time.perf_counter()
        res = self.inner.evaluate(X, return_as_dictionary=True)
        out["F"] = res["F"]
        if "G" in res:
            out["G"] = res["G"]
        self.spent += time.perf_counter() - t


def bookkeeping(name: str, n_gen: int) -> float:
    """Seconds per generation spent outside evaluation (median of 3 runs)."""
    times = []
    for seed in (1, 2, 3):
        p = Timed(get_problem("dtlz2", n_var=16, n_obj=3))
        alg = make_algorithm(AlgorithmSpec(name, 200), 3, seed)
        t = time.perf_counter()
        minimize(p, alg, ("n_gen", n_gen), seed=seed)
        times.append((time.perf_counter() - t - p.spent) / n_gen)
    return float(np.median(times))


def quality(names: list[str], problems: list[str], seeds: range, evals: int) -> None:
    print(f"\nmedian IGD / HV over {len(seeds)} seeds, pop 100, {evals} evaluations "
          f"(verdicts against {REFERENCE}; '-' IGD: no feasible member)")
    print(f"{'problem':<8}" + "".join(f"{n:>26}" for n in names))
    for prob in problems:
        pf = reference_front(prob)
        vals: dict[str, tuple[list[float], list[float]]] = {}
        for n in names:
            igds, hvs = [], []
            for s in seeds:
                p = get_problem(prob)
                r = minimize(p, make_algorithm(AlgorithmSpec(n, 100), p.n_obj, s), ("n_eval", evals), seed=s)
                F = r.F if r.F is not None else np.zeros((0, p.n_obj))
                igds.append(igd(F, pf))
                hvs.append(hv_platemo(F, pf))
            vals[n] = (igds, hvs)
        cells = []
        for n in names:
            igds, hvs = vals[n]
            mark = ""
            if n != REFERENCE:
                ref = vals[REFERENCE][0]
                a, b = np.nan_to_num(igds, nan=np.inf), np.nan_to_num(ref, nan=np.inf)
                p = ranksums(a, b).pvalue if not np.array_equal(a, b) else 1.0
                mark = "≈" if not p < 0.05 else ("+" if np.median(a) < np.median(b) else "-")
            med = np.nanmedian(igds) if np.isfinite(igds).any() else np.nan
            cells.append(f"{med:10.4g} / {np.median(hvs):6.4f} {mark:<2}".rjust(26))
        print(f"{prob:<8}" + "".join(cells))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer generations, seeds and evaluations (CI)")
    ap.add_argument("--algorithms", default="nsga2", help="comma-separated algorithms besides nsga2_pymoo")
    args = ap.parse_args(argv)
    names = [REFERENCE] + [n for n in args.algorithms.split(",") if n and n != REFERENCE]
    n_gen = 20 if args.quick else 100
    print(f"bookkeeping per generation (pop 200, 16 variables, 3 objectives, DTLZ2, {n_gen} generations)")
    print(f"{'algorithm':<14} {'ms/generation':>14}")
    for n in names:
        print(f"{n:<14} {1000 * bookkeeping(n, n_gen):14.3f}")
    if args.quick:
        quality(names, ["mw1", "mw3", "ctp2"], range(1, 4), 5000)
    else:
        quality(names, [f"mw{i}" for i in range(1, 15)] + [f"ctp{i}" for i in range(1, 9)], range(1, 11), 50_000)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
