"""``clm compare DIR...``: the Appendix B-5-style table (method, time, MSE, S, I) of saved runs.

Each argument is a ``clm design`` output directory (or its ``result.json``). A hierarchical run
gives one row (its final pick), a single-level run three (smallest MSE, h_s and I, like the
paper's Appendix B-4), a DP baseline one. ``--paper`` appends the paper's own printed
Appendix B-5 values for reference (its times are MATLAB minutes on one core, converted to s), and
a column h_s/300: the paper's S, which the column S (ours, h_s / l_s) is not.
RTCLM runs add the columns h6 and h4.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from core.cli import CLIError, path_arg
from core.cli.design import COMPILE_NOTE, table
from core.formats.files import read_design_result
from core.optimize.result import decode_float

# Appendix B-5 as printed: method, time (min), MSE (mm), S (%), I (mm/s).
PAPER_B5 = (
    ("paper: DP+SQP (printed)", 1.6e-4, 19.80, 14.78, 33.52),
    ("paper: DP+GA (printed)", 0.32, 19.63, 17.04, 53.56),
    ("paper: DP+GA+SQP (printed)", 0.34, 14.36, 5.94, 116.20),
    ("paper: FS and DP-based [9] (printed)", 2.18, 9.91, 4.17, 49.8),
    ("paper: hierarchical, ours (printed)", 7.69, 3.97, 0.95, 0.90),
)

# Appendix C-1: the RTCLM cases (time in MATLAB minutes on one core, h6, h4 in mm), printed.
PAPER_C1 = (
    ("paper: RTCLM case 1 (printed)", 13.3, 50.1, 220.1),
    ("paper: RTCLM case 2 (printed)", 19.2, 50.2, 239.6),
    ("paper: RTCLM case 3 (printed)", 34.3, 50.0, 260.1),
    ("paper: RTCLM case 4 (printed)", 38.2, 49.9, 280.1),
    ("paper: RTCLM case 5 (printed)", 31.9, 49.9, 300.5),
)

PAPER_NOTES = (
    "The paper's S is h_s / 300 mm (its column h_s/300 here); ours is h_s / l_s, which reads ~3 % higher.",
    "The hierarchical row's printed S = 0.95 contradicts the paper's B-1 (X3: 1.93): a copy error of the",
    "Stephenson-III row (docs/paper-reproduction.md). The paper's times are MATLAB minutes on one core, here in s.",
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare",
        help="compare saved design runs (method, time, MSE, S, I)",
        description="Print one table of the runs saved by 'clm design --out DIR': method, time and the "
        "chosen designs' MSE, S and I (Appendix B-5 style). The time is compute time, every chain of a multi-start "
        "counted, as the paper's one-core times are; the run's wall time is result.json's wall_time.",
    )
    p.add_argument("runs", nargs="+", type=path_arg, metavar="DIR", help="output directories (or result.json files)")
    p.add_argument("--paper", action="store_true", help="append the paper's printed rows: Appendix B-5's, or for "
                   "RTCLM runs (rows with h6 and h4) Appendix C-1's five cases")
    p.set_defaults(func=run)




def load_rows(path: Path) -> list[dict[str, Any]]:
    """The summary rows of one saved run (see ``DesignRun.rows``)."""
    f = path / "result.json" if path.is_dir() else path
    if path.is_dir() and (path / "study.sqlite").is_file():  # rehearsal 6 gave the study directory itself
        raise CLIError(f"{path} is a study directory: compare its runs' files ({path}/runs/<case>/<algorithm>/"
                       f"<seed>.json), or see its report (clm study report {path})")
    if not f.exists():
        raise CLIError(f"{str(f)!r} not found (expected a 'clm design --out' directory)")
    data = read_design_result(f)  # its ValueError is one clm: error line
    if not isinstance(data.get("status"), str) or "rows" not in data:  # every run writes both, a cancelled one too
        raise CLIError(f"{f}: an incomplete 'clm design' result (no status or rows)")
    rows = data.get("rows") or []
    if not isinstance(rows, list) or not all(isinstance(r, dict) and isinstance(r.get("label"), str) for r in rows):
        raise CLIError(f"{f}: 'rows' must be a list of objects with a label")
    if not rows:
        return [{"label": f"{data.get('name', f.parent.name)}: no result ({data.get('status')})", "time": float("nan")}]
    compiled = data.get("compile_time")
    if isinstance(compiled, int | float) and compiled >= COMPILE_NOTE:  # a first run: its time is mostly compiling
        rows = [{**r, "compiled": float(compiled)} for r in rows]
    numeric = {"time", "evals", "mse", "S", "I", "h_s", "f2", "f3", "h6", "h4", "dh6", "dh4", "violation", "dp"}
    config: dict[str, Any] = data["config"] if isinstance(data.get("config"), dict) else {}
    try:
        return [{**{k: (decode_float(v) if k in numeric else v) for k, v in r.items()}, "run": _run_name(config, r)}
                for r in rows]
    except (ValueError, TypeError) as e:
        raise CLIError(f"{f}: a row holds a value that is not a number ({e})") from None


def _run_name(config: dict[str, Any], row: dict[str, Any]) -> str:
    """``nsga2, seed 3``: the row's stage's algorithm (the config's, nsga2 by default) and the run seed."""
    def name(alg: Any) -> str | None:
        return alg.get("name") if isinstance(alg, dict) else None

    stages = [s for s in config.get("stages") or () if isinstance(s, dict) and s.get("name") == row.get("stage")]
    alg = (name(stages[0].get("algorithm")) if stages else None) or name(config.get("algorithm"))
    if alg is None and row.get("method", "hierarchical") in ("hierarchical", "single_level"):
        alg = "nsga2"
    seed = config.get("seed")
    return ", ".join(x for x in (alg, None if seed is None else f"seed {seed}") if x)


def infeasible(row: dict[str, Any]) -> bool:
    """A pick that misses its stage's constraints, or a baseline whose path is no valid walking path."""
    return row.get("feasible") is False or row.get("violation", 0.0) > 0.0


def run(args: argparse.Namespace) -> int:
    rows: list[dict[str, Any]] = []
    seen: set[Path] = set()
    for p in args.runs:
        f = (p / "result.json" if p.is_dir() else p).resolve()
        if f in seen:  # lab rehearsal: 'clm compare runs/a runs/a' listed the run twice without a word
            print(f"clm: note: {p} is given more than once; listed once", file=sys.stderr)
            continue
        seen.add(f)
        rows += [{**r, "source": str(p)} for r in load_rows(p)]
    extra = [k for k in ("h6", "h4") if any(k in r for r in rows)]
    # Evaluations beside the time (lab rehearsal: at the same population and generations CMOES spent 2-3x NSGA-II's,
    # and a comparison read as like for like); a result written before they were kept reads "-".
    header = ["method", "time (s)", "evaluations", "MSE (mm)", "S (%)", "I (mm/s)"] + [f"{k} (mm)" for k in extra]
    out = []
    labels = [r["label"] for r in rows]
    named = [f"{r['label']} ({r['run']})" if labels.count(r["label"]) > 1 and r.get("run") else r["label"]
             for r in rows]  # runs of one config (a study's cells): which is which
    for r, label in zip(rows, named, strict=True):
        if named.count(label) > 1:  # still alike (copies of one config with other targets): the run's folder
            label += f" in {r['source']}"
        label += "" if r.get("status", "complete") == "complete" else f" [{r['status']}]"
        label += " *" if infeasible(r) else ""
        evals = r.get("evals")
        out.append([label, r.get("time", float("nan")), "-" if evals is None or evals != evals else int(evals)]
                   + [r.get(k, float("nan")) for k in ("mse", "S", "I", *extra)])
    rtclm = bool(rows) and all("h4" in r for r in rows)
    if args.paper and rtclm:  # the RTCLM's own table, not the Stephenson-I baselines of B-5
        nan = float("nan")
        out += [[name, 60.0 * t, "-", nan, nan, nan, h6, h4] for name, t, h6, h4 in PAPER_C1]
    elif args.paper:
        # The paper's S is h_s / 300 mm (spec §4), ours h_s / l_s: side by side only in a column of their own.
        header.insert(5, "h_s/300 (%)")
        for row, r in zip(out, rows, strict=True):
            row.insert(5, 100.0 * r.get("h_s", float("nan")) / 300.0)
        out += [[name, 60.0 * t, "-", mse, float("nan"), s, i] + [float("nan")] * len(extra)
                for name, t, mse, s, i in PAPER_B5]
    print(table(header, out))
    if any(infeasible(r) for r in rows):
        print("* infeasible: the pick misses its stage's constraints, or the baseline's path is no valid walking path "
              "(its violation > 0)")
    first = sorted({(r["source"], r["compiled"]) for r in rows if r.get("compiled")})
    if first:
        print("The time includes compiling numba kernels (a first run of this code, in this checkout; later runs load "
              "them from the cache) in "
              + ", ".join(f"{src} ({t:.1f} s of it)" for src, t in first) + ".")
    if args.paper and rtclm:
        print("The paper's times are MATLAB minutes on one core (Appendix C-1), here in s.")
    elif args.paper:
        print("\n".join(PAPER_NOTES))
    return 0
