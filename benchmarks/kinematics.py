"""Throughput of the batch dyad solver: numpy reference vs numba kernel (serial and parallel).

    python benchmarks/kinematics.py            # pop 200 and 10 000, N 360, best of 7
    python benchmarks/kinematics.py --quick    # pop 200 and 1 000, best of 3 (CI, a few seconds)

Prints trajectories (designs x one crank revolution of N samples) per second for the four-bar,
Stephenson-I and Jansen mechanisms, each population a preset jittered by 3 % (seeded). A
mechanism not yet in the registry is skipped with a note. Times are the best of k repeats after
a warm-up call (k at least enough for ~1 s of calls: fast cases get more tries against the
noise of a shared machine), through ``solver_numba.run`` and ``solver_numpy.reduce`` (the same
outputs, allocation included: new arrays every call, as a caller gets them; ``solver_numba``
hands out the previous call's block of paths again once nothing refers to it, as in this loop
and in an optimizer that drops each generation's paths, and a block of fresh pages would cost
~0.6 us per design of first-touch faults at pop 10 000 on this VM). "reused out": the serial
kernel alone, writing into outputs allocated once (the compute). "solve()": the public
``kinematics.solve(joints=False)``, which also maps the tracked point to the leg frame and
derives the violation and transmission angles. Compile (or cache load) time is reported apart.
Targets (issue 3): Stephenson-I numba serial joints=False >= 500 k/s on one core, numpy
reference >= 50 k/s. Single-thread columns (``SINGLE_THREAD``) time the calling thread's CPU
time (``time.thread_time``, page faults included): on a shared machine a call of ~20 ms is
almost never left alone for its wall-clock duration; the others (parallel, solve()) take
wall-clock time (``--wall``: wall-clock time everywhere). Not a test: the numbers depend on the machine and its
load (the other processes on its 2 cores share its caches and memory bandwidth).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from _timing import best_of

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from core.kinematics import kernel as solver_numba  # noqa: E402
from core.kinematics import reference as solver_numpy  # noqa: E402
from core.kinematics.mechanisms import MECHANISMS  # noqa: E402
from core.kinematics.model import Mechanism  # noqa: E402
from core.kinematics.presets import PRESETS, Preset  # noqa: E402
from core.kinematics.solver import sample_angles, solve  # noqa: E402

MECHANISM_NAMES = ("fourbar", "stephenson1", "jansen")
TITLES = {"fourbar": "four-bar", "stephenson1": "Stephenson-I", "jansen": "Jansen"}
TARGET_NUMBA = 500_000.0
TARGET_NUMPY = 50_000.0
JITTER = 0.03
# Columns timed by thread CPU time (unless --wall); solve() goes parallel from PARALLEL_MIN_POP on.
SINGLE_THREAD = ("numpy", "numba serial", "reused out", "serial+joints")
MIN_SECONDS = 1.0  # of timed calls per case, at least (--quick: a tenth)


def preset_for(name: str) -> Preset | None:
    """The preset a mechanism is benchmarked around: ``name``, X3 for Stephenson-I, else its first."""
    for key in (name, f"{name}/X3"):
        if key in PRESETS and PRESETS[key].mechanism.name == name:
            return PRESETS[key]
    return next((p for p in PRESETS.values() if p.mechanism.name == name), None)


def jittered(preset: Preset, pop: int, seed: int = 0) -> np.ndarray:
    """``(pop, n_params)`` the preset's parameters, every one jittered by 3 %."""
    rng = np.random.default_rng(seed)
    return np.asarray(preset.values) * (1.0 + JITTER * rng.standard_normal((pop, preset.mechanism.n_params)))


def operands(preset: Preset, pop: int, seed: int = 0) -> np.ndarray:
    """``(pop, n_steps, 3)`` kernel operands of the preset with every parameter jittered by 3 %."""
    m = preset.mechanism
    internal, _ = m.internal(jittered(preset, pop, seed))
    return np.ascontiguousarray(m.compile().operands(internal))


def compile_report(ops: np.ndarray, vals: np.ndarray, theta: np.ndarray, tracked: int) -> str:
    """Time of the first call of each kernel entry (a compile, or a load from numba's disk cache)."""
    parts = []
    for parallel, kernel in ((False, solver_numba._run_serial), (True, solver_numba._run_parallel)):
        t = time.perf_counter()
        solver_numba.run(ops, vals[:2], theta, tracked, False, parallel)
        dt = time.perf_counter() - t
        misses = sum(kernel.stats.cache_misses.values())
        how = "compiled" if misses else "loaded from cache"
        parts.append(f"{'parallel' if parallel else 'serial'} {dt:.2f} s ({how})")
    return "first call: " + ", ".join(parts)


def kernel_only(
    ops: np.ndarray, vals: np.ndarray, theta: np.ndarray, tracked: int, derivatives: bool
) -> Callable[[], object]:
    """The serial kernel writing into outputs allocated once: compute without allocation and
    first-touch page faults (which cost ~1 us per design at pop 10 000 on this VM)."""
    pop, n_steps = vals.shape[:2]
    n = theta.shape[0]
    none = np.empty((0, 0, 0, 2))
    point = np.empty((pop, n, 2))
    dpoint = np.empty((pop, n, 2)) if derivatives else point[:0]
    out: tuple[np.ndarray, ...] = (none, none, point, dpoint, point[:0], point[:0])
    out += (np.empty((pop, n), dtype=bool),) + tuple(np.empty((pop, n_steps)) for _ in range(3)) + (np.empty(pop),)
    prog = solver_numba.prepare(ops, tracked)
    ct, st = solver_numba.angles(theta)
    program = (prog.ops, vals, ct, st, prog.tracked, prog.sinks, prog.links, False, False, (1.0, 1.0, 0.0, 0.0),
               derivatives)
    return lambda: solver_numba._run_serial(*program, *out)


def best_cpu_of(fn: Callable[[], object], repeats: int) -> float:
    """Least CPU time of the calling thread over repeats calls (s)."""
    return best_of(fn, repeats, time.thread_time)


def rates(
    ops: np.ndarray, vals: np.ndarray, theta: np.ndarray, tracked: int, repeats: int,
    solve_args: tuple[Mechanism, np.ndarray] | None = None, min_seconds: float = MIN_SECONDS, wall: bool = False,
) -> dict[str, float]:
    """Trajectories per second of each backend and mode on one population: keys ``(mode, column)``
    with mode "paths" (positions only) or "d/dtheta" (with exact derivatives)."""
    pop = vals.shape[0]
    cases: dict[tuple[str, str], Callable[[], object]] = {}
    for mode, d in (("paths", False), ("d/dtheta", True)):
        cases[mode, "numpy"] = partial(solver_numpy.reduce, ops, vals, theta, tracked, False, d)
        cases[mode, "numba serial"] = partial(solver_numba.run, ops, vals, theta, tracked, False, False, d)
        cases[mode, "reused out"] = kernel_only(ops, vals, theta, tracked, d)
        cases[mode, "parallel"] = partial(solver_numba.run, ops, vals, theta, tracked, False, True, d)
        if d:
            cases[mode, "serial+joints"] = partial(solver_numba.run, ops, vals, theta, tracked, True, False, d)
            cases[mode, "parallel+joints"] = partial(solver_numba.run, ops, vals, theta, tracked, True, True, d)
        if solve_args is not None:
            mechanism, params = solve_args
            cases[mode, "solve()"] = partial(solve, mechanism, params, theta.shape[0], joints=False, derivatives=d,
                                             backend="numba")
    out = {}
    for key, fn in cases.items():
        t = time.perf_counter()
        fn()  # warm-up: caches, first-touch page faults
        t = time.perf_counter() - t
        k = max(1, repeats // 3) if key[1] == "numpy" else repeats
        timer = best_cpu_of if key[1] in SINGLE_THREAD and not wall else best_of
        out[key] = pop / timer(fn, max(k, min(200, math.ceil(min_seconds / max(t, 1e-6)))))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small populations, few repeats (CI)")
    ap.add_argument("--samples", type=int, default=360)
    ap.add_argument("--wall", action="store_true", help="wall-clock time for every column (else CPU time of "
                    "the calling thread for the single-thread ones)")
    args = ap.parse_args(argv)
    pops = (200, 1000) if args.quick else (200, 10_000)
    repeats = 3 if args.quick else 7
    n = args.samples
    theta = sample_angles(n)

    rows: list[tuple[str, int, dict[str, float]]] = []
    compiled = False
    for name in MECHANISM_NAMES:
        preset = preset_for(name) if name in MECHANISMS else None
        if preset is None:
            print(f"skipping {name}: {'no preset' if name in MECHANISMS else 'not in MECHANISMS'} yet")
            continue
        prog = preset.mechanism.compile()
        for pop in pops:
            vals = operands(preset, pop)
            if not compiled:
                print(compile_report(prog.ops, vals, theta, prog.tracked))
                compiled = True
            solve_args = (preset.mechanism, jittered(preset, pop))
            rows.append((name, pop, rates(prog.ops, vals, theta, prog.tracked, repeats, solve_args,
                                          MIN_SECONDS / 10 if args.quick else MIN_SECONDS, args.wall)))

    clock = "wall-clock time" if args.wall else "thread CPU time (parallel, solve(): wall-clock)"
    print(f"trajectories/s (N = {n}), best of >= {repeats} (numpy: {max(1, repeats // 3)}), {clock}; "
          "joints=False unless noted")
    for mode, title in (("paths", "paths only (derivatives=False)"), ("d/dtheta", "paths and exact d/dtheta")):
        columns = [c for m, c in rows[0][2] if m == mode] if rows else []
        print(f"-- {title}")
        print(f"{'mechanism':<14}{'pop':>7}" + "".join(f"{c:>16}" for c in columns))
        for name, pop, by_case in rows:
            print(f"{TITLES[name]:<14}{pop:>7}" + "".join(f"{_rate(by_case[mode, c]):>16}" for c in columns))
    for pop, r in ((pop, r) for name, pop, r in rows if name == "stephenson1"):
        for mode in ("paths", "d/dtheta"):
            serial, reused, ref = r[mode, "numba serial"], r[mode, "reused out"], r[mode, "numpy"]
            print(
                f"targets, Stephenson-I {mode} at pop {pop}: numba serial {_rate(serial)}, reused out {_rate(reused)} "
                f"({'meets' if min(serial, reused) >= TARGET_NUMBA else 'below'} {_rate(TARGET_NUMBA)}), "
                f"numpy {_rate(ref)} ({'meets' if ref >= TARGET_NUMPY else 'below'} {_rate(TARGET_NUMPY)})"
            )
    return 0


def _rate(r: float) -> str:
    return f"{r / 1e6:.2f} M" if r >= 1e6 else f"{r / 1e3:.1f} k"


if __name__ == "__main__":
    raise SystemExit(main())
