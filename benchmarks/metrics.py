"""Throughput of the whole analysis stack (kinematics + feature points + metrics + shape error).

    python benchmarks/metrics.py            # pop 200 x N 360, Stephenson-I around X3
    python benchmarks/metrics.py --quick    # a short run for CI

Prints designs per second for the numpy reference and for the numba path (solver kernel plus
metrics kernel), with the time split between kinematics and analysis. Target (issue 3): whole
stack >= 50 k designs/s at pop 200 x N 360. Not a test: wall-clock numbers depend on the machine.
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

from core.design import Design  # noqa: E402
from core.evaluate import evaluate, evaluate_paths  # noqa: E402
from core.presets import get  # noqa: E402

TARGET = 50_000.0


def population(pop: int, seed: int = 0) -> Design:
    """X3 with every parameter perturbed by 3 % (about 60 % of them assemble)."""
    base = get("stephenson1/X3").design()
    rng = np.random.default_rng(seed)
    p = base.params * (1.0 + 0.03 * rng.standard_normal((pop, base.params.shape[1])))
    return Design(base.mechanism, p, base.output)


def best_of(fn, repeats: int) -> float:
    """Best wall time of repeats calls (s): the least disturbed by other processes."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return float(best)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="few repeats (CI)")
    ap.add_argument("--pop", type=int, default=200)
    ap.add_argument("--samples", type=int, default=360)
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 20
    design = population(args.pop)
    n = args.samples

    try:
        import core.solver_numba  # noqa: F401

        backends = ["numpy", "numba"]
    except ImportError:
        backends = ["numpy"]
        print("core.solver_numba missing: numpy backend only")

    rows = []
    for backend in backends:
        kernel = backend == "numba"
        t0 = time.perf_counter()
        sol = design.solve(n, joints=False, backend=backend)
        evaluate_paths(sol.point, sol.leg, sol.dleg, sol.violation, kernel=kernel)
        warm = time.perf_counter() - t0
        reps = max(1, repeats // 5) if backend == "numpy" else repeats
        t_kin = best_of(lambda b=backend: design.solve(n, joints=False, backend=b), reps)
        t_ana = best_of(lambda k=kernel, s=sol: evaluate_paths(s.point, s.leg, s.dleg, s.violation, kernel=k), reps)
        t_all = best_of(lambda b=backend: evaluate(design, n, backend=b), reps)
        rows.append((backend, warm, t_kin, t_ana, t_all))

    feas = int(evaluate(design, n, backend=backends[-1]).feasible.sum())
    print(f"Stephenson-I, pop {args.pop} x N {n} ({feas} feasible), best of {repeats} (numpy: {max(1, repeats // 5)})")
    head = ("backend", "first call s", "kinematics ms", "analysis ms", "whole ms", "designs/s")
    print(f"{head[0]:<8} {head[1]:>12} {head[2]:>14} {head[3]:>12} {head[4]:>9} {head[5]:>10}")
    for backend, warm, t_kin, t_ana, t_all in rows:
        rate = args.pop / t_all
        print(f"{backend:<8} {warm:>12.2f} {1e3 * t_kin:>14.2f} {1e3 * t_ana:>12.2f} {1e3 * t_all:>9.2f} {rate:>10.0f}")
    best = args.pop / min(r[4] for r in rows)
    verdict = "meets" if best >= TARGET else "below"
    print(f"target {TARGET:.0f} designs/s: {verdict} ({best:.0f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
