"""Throughput of the whole analysis stack (kinematics + feature points + metrics + shape error).

    python benchmarks/metrics.py                  # pop 200 x N 360, Stephenson-I around X3
    python benchmarks/metrics.py --pop 200 10000  # several population sizes
    python benchmarks/metrics.py --quick          # a short run for CI

What the optimizer pays is ``core.analysis.evaluate.evaluate(design)`` once per generation, on a new
population each time: the "evaluate()" columns time exactly that, as a plain loop over
``--loops`` populations (different seeds, fresh arrays, nothing reused between calls), mean and
best. The parts are timed apart (best of ``--repeats`` on one population): "solve" is
``Design.solve(joints=False)``, "analysis" is ``evaluate_paths`` on its result. With numba,
``evaluate`` does not go through them: it solves and analyses each design in one fused kernel
pass (``metrics_numba.run_designs``), so it costs less than their sum. Target (issue 3): whole
stack >= 50 k designs/s at pop 200 x N 360. Not a test: wall-clock numbers depend on the machine
and its load (the numpy reference is skipped above pop 1000 unless ``--numpy-large``).
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np
from _timing import best_of

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from core.analysis.evaluate import evaluate, evaluate_paths  # noqa: E402
from core.kinematics.design import Design  # noqa: E402
from core.kinematics.presets import get  # noqa: E402

TARGET = 50_000.0


def population(pop: int, seed: int = 0) -> Design:
    """X3 with every parameter perturbed by 3 % (about 70 % of them assemble)."""
    base = get("stephenson1/X3").design()
    rng = np.random.default_rng(seed)
    p = base.params * (1.0 + 0.03 * rng.standard_normal((pop, base.params.shape[1])))
    return Design(base.mechanism, p, base.output)


def loop_times(designs: list[Design], n: int, backend: str) -> np.ndarray:
    """Wall time (s) of ``evaluate`` on each population in turn, as an optimizer calls it."""
    out = []
    for d in designs:
        t = time.perf_counter()
        evaluate(d, n, backend=backend)  # type: ignore[arg-type]
        out.append(time.perf_counter() - t)
    return np.asarray(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="few repeats (CI)")
    ap.add_argument("--pop", type=int, nargs="+", default=[200])
    ap.add_argument("--samples", type=int, default=360)
    ap.add_argument("--repeats", type=int, default=None, help="best-of repeats of the parts (default 20, quick 3)")
    ap.add_argument("--loops", type=int, default=None, help="populations in the evaluate() loop (default 40, quick 5)")
    ap.add_argument("--numpy-large", action="store_true", help="also run the numpy reference above pop 1000")
    args = ap.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 20)
    loops = args.loops or (5 if args.quick else 40)
    n = args.samples

    try:
        import core.kinematics.kernel  # noqa: F401

        backends = ["numpy", "numba"]
    except ImportError:
        backends = ["numpy"]
        print("core.kinematics.kernel missing: numpy backend only")

    head = ("pop", "backend", "first call s", "solve ms", "analysis ms", "evaluate() ms mean", "best", "designs/s")
    rows = []
    for pop in args.pop:
        design = population(pop)
        for backend in backends:
            if backend == "numpy" and pop > 1000 and not args.numpy_large:
                continue
            kernel = backend == "numba"
            # Fewer numpy runs and loops, and fewer of both for big populations.
            scale = (5 if backend == "numpy" else 1) * max(1, pop // 2000)
            reps, n_loops = max(1, repeats // scale), max(2, loops // scale)
            t0 = time.perf_counter()
            evaluate(design, n, backend=backend)  # type: ignore[arg-type]
            warm = time.perf_counter() - t0
            sol = design.solve(n, joints=False, backend=backend)
            t_kin = best_of(partial(design.solve, n, joints=False, backend=backend), reps)
            t_ana = best_of(partial(evaluate_paths, sol.point, sol.leg, sol.dleg, sol.violation, kernel=kernel), reps)
            times = loop_times([population(pop, seed) for seed in range(1, n_loops + 1)], n, backend)
            feas = int(evaluate(design, n, backend=backend).feasible.sum())  # type: ignore[arg-type]
            rows.append((pop, backend, warm, t_kin, t_ana, float(times.mean()), float(times.min()), feas, n_loops))

    print(f"Stephenson-I around X3 (3 % jitter), N {n}; parts best of {repeats} (numpy: fewer); "
          f"evaluate() over {loops} fresh populations (numpy, large pops: fewer)")
    widths = (6, -8, 12, 9, 12, 19, 8, 10)
    print(" ".join(f"{h:<{-w}}" if w < 0 else f"{h:>{w}}" for h, w in zip(head, widths, strict=True)))
    for pop, backend, warm, t_kin, t_ana, mean, best, feas, _ in rows:
        print(f"{pop:>6} {backend:<8} {warm:>12.2f} {1e3 * t_kin:>9.2f} {1e3 * t_ana:>12.2f} {1e3 * mean:>19.2f} "
              f"{1e3 * best:>8.2f} {pop / mean:>10.0f}   ({feas} feasible)")
    at200 = [r for r in rows if r[0] == 200]
    if at200:
        rate = max(200 / r[5] for r in at200)
        verdict = "meets" if rate >= TARGET else "below"
        print(f"target {TARGET:.0f} designs/s at pop 200 (evaluate() mean): {verdict} ({rate:.0f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
