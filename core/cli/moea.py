"""``clm moea``: run a registered algorithm on a pymoo test problem and print IGD, HV and counts."""

from __future__ import annotations

import argparse
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from core.cli import CLIError, jsonable, out_file, path_arg
from core.formats.files import atomic_write
from core.optimize.problem_names import KNOWN


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "moea",
        help="run an algorithm on a test problem (MW, CTP, DAS-CMOP, ZDT, DTLZ, C-DTLZ, DC-DTLZ)",
        description="Run any registered algorithm on a test problem (pymoo's, and PlatEMO's DC-DTLZ) for a budget "
        "of function evaluations and print IGD and HV (PlatEMO's normalisation, on the feasible non-dominated "
        "members), the evaluations spent, the feasible count and the wall time. Reference fronts need no download: "
        "they ship with the package or are computed from the problem's definition.",
    )
    p.add_argument("--problem", required=True, help=f"{KNOWN} (DTLZ families at 3 objectives)")
    p.add_argument("--algorithm", default="nsga2", help="a registered algorithm (default nsga2)")
    p.add_argument("--pop", type=int, default=100, help="population size (default 100)")
    p.add_argument("--evals", type=int, default=20_000, help="function evaluations (default 20000)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="an algorithm option, as in a configuration's [algorithm] options (repeatable), e.g. "
                   "operator=de for cmoes or mccmo, variant=author_repo for cmoemt; see docs/algorithms.md")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--out", metavar="FILE", type=path_arg,
                   help="also write the final population as CSV: x1.., f1.., cv, feasible, front (1 for the members "
                   "IGD and HV measure, each copy of a point: the printed front counts distinct points), so both can "
                   "be checked")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out FILE")
    p.set_defaults(func=run)


def _fmt(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v:.6g}"


def options(algorithm: str, given: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` strings as typed options: VALUE read as a TOML value (true, 15, 0.9), else as a string."""
    from core.formats.config import algorithm_options
    from core.optimize.algorithms import ALGORITHMS

    raw: dict[str, Any] = {}
    for item in given:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--option expects KEY=VALUE, got {item!r}")
        if key.strip() in raw:  # a configuration refuses a repeated key too
            raise ValueError(f"--option {key.strip()} is given twice")
        try:
            raw[key.strip()] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            raw[key.strip()] = value.strip()
    # An unknown algorithm is reported by the run itself (make_algorithm), with or without options.
    return algorithm_options(algorithm, raw, "--option") if algorithm in ALGORITHMS else raw


def write_population(path: Path, p: dict[str, Any]) -> None:
    """The final population as CSV (``--out``): one row per member, full precision (``repr`` of each float)."""
    X, F = np.atleast_2d(p["X"]), np.atleast_2d(p["F"])
    head = [f"x{j + 1}" for j in range(X.shape[1])] + [f"f{j + 1}" for j in range(F.shape[1])]
    lines = [",".join([*head, "cv", "feasible", "front"])]
    for x, f, c, front in zip(X, F, p["cv"], p["front"], strict=True):
        lines.append(",".join([*(repr(float(v)) for v in (*x, *f, c)), str(int(c <= 0)), str(int(front))]))
    atomic_write(path, "\n".join(lines) + "\n")


def run(args: argparse.Namespace) -> int:
    from core.cli.design import COMPILE_NOTE
    from core.kinematics.kernel_cache import CompileTimer
    from core.optimize.algorithms import registered
    from core.optimize.moea import run as run_moea

    # Lab rehearsal: `--algorithm CMOES` was refused with a did-you-mean while `--problem MW3` was taken.
    args.algorithm = registered(args.algorithm)
    if args.overwrite and args.out is None:
        raise CLIError("--overwrite replaces an existing --out FILE; give --out FILE too")
    if args.out is not None and str(args.out) == "-":  # out_file's "-" prints; this CSV is a file (review, session 37)
        raise CLIError("--out takes a file name for the population's CSV; it is not printed")
    out = None if args.out is None else out_file(str(args.out), args.overwrite)
    timer = CompileTimer()
    with timer:
        r = run_moea(args.problem, args.algorithm, args.pop, args.evals, args.seed,
                     options(args.algorithm, args.option), population=out is not None)
    if out is not None:
        write_population(out, r.pop("population"))
    r["compile_time"] = timer.seconds  # lab rehearsal: CMOES's first run read 36.5 s, 0.6 s after
    if args.json:
        print(json.dumps(jsonable(r)))
        return 0
    compiled = (f" ({r['compile_time']:.1f} s of it compiling numba kernels, which later runs of this code load "
                "from its cache)"
                if r["compile_time"] >= COMPILE_NOTE else "")
    # Lab rehearsal: "IGD -" and 3077 evaluations of a 3000 budget were left to guess.
    none = "no feasible member at the end: nothing to measure" if not math.isfinite(r["igd"]) else "lower is better"
    past = (f" (the generation that reached --evals {args.evals} ran to its end)" if r["n_eval"] > args.evals else "")
    print(f"{r['algorithm']} on {r['problem']} (pop {r['pop']}, seed {r['seed']}): IGD {_fmt(r['igd'])} ({none}), "
          f"HV {_fmt(r['hv'])} (higher is better), {r['n_eval']} evaluations{past}, {r['feasible']} of {r['size']} "
          f"feasible, front {r['front_size']}, {r['wall_time']:.2f} s{compiled}")
    return 0
