"""Algorithms: bookkeeping time per generation, where a Stephenson-I stage spends its time, and IGD/HV on
constrained test problems.

    python benchmarks/algorithms.py            # IGD/HV over 10 seeds, pop 100, 50 000 evaluations
    python benchmarks/algorithms.py --quick    # fewer generations, seeds and evaluations (CI)
    python benchmarks/algorithms.py --algorithms nsga2,imtcmo --problems mw1,mw3

Bookkeeping is everything a generation costs but evaluation (mating, variation, duplicate elimination,
survival, pymoo's loop), per steady-state generation (the first one and the setup excluded), on DTLZ2 with 16
variables and 3 objectives at pop 200, whose evaluation takes ~0.2 ms. Target (issue 11): <= 1 ms per
generation for NSGA-II, <= 3 ms for the CMOEAs. The stage table splits the predesign and subtask-1 stages of
``assets/configs/stephenson1_cycloid.toml`` (pop 200) into evaluation (the objectives), repair (the analytic
placement every new member gets before evaluation) and the rest. The quality table gives the median IGD and
HV (PlatEMO's normalisation, spec §1.7) per algorithm and problem, with the Wilcoxon rank-sum verdict against
pymoo's NSGA-II (+ better, - worse, ≈ no significant difference at 5 %).
Not a test: wall-clock numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from pymoo.core.problem import Problem  # noqa: E402
from pymoo.problems import get_problem  # noqa: E402
from scipy.stats import ranksums  # noqa: E402

from core.kinematics.memory import keep_freed_memory  # noqa: E402
from core.optimize.algorithms import AlgorithmSpec, make_algorithm  # noqa: E402
from core.optimize.moea import KNOWN, PROBLEMS  # noqa: E402
from core.optimize.moea import run as run_moea  # noqa: E402

REFERENCE = "nsga2_pymoo"
FAST_PHASE_MS = 5.0  # pymoo's NSGA-II bookkeeping in the VM's fast phase (sessions 16-20: 4.85-5.5 ms)


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
    """Seconds per steady-state generation spent outside evaluation (median over 3 seeds)."""
    times = []
    for seed in (1, 2, 3):
        p = Timed(get_problem("dtlz2", n_var=16, n_obj=3))
        alg = make_algorithm(AlgorithmSpec(name, 200), 3, seed)
        alg.setup(p, termination=("n_gen", n_gen + 2), seed=seed)
        alg.next()  # the initial population
        spent = p.spent
        t = time.perf_counter()
        for _ in range(n_gen):
            alg.next()
        times.append((time.perf_counter() - t - (p.spent - spent)) / n_gen)
    return float(np.median(times))


def qnet_line() -> str:
    """DRLOS-EMCMO's Q-network training, which the table's first 100 generations never reach: its first
    training (generation EXPLORE_GENS + 1) and each update, per generation between updates."""
    from core.optimize.evolve.drlos_emcmo import EXPLORE_GENS, FIRST_STEPS, PERIOD, UPDATE_STEPS
    from core.optimize.evolve.qnet import QNet

    rng = np.random.default_rng(1)
    X, Y = rng.random((200, 4)), rng.random((200, 4))
    net = QNet(rng)
    net.fit(X, Y, 10)  # the compiled kernels loaded
    t = time.perf_counter()
    net.fit(X, Y, FIRST_STEPS)
    first = time.perf_counter() - t
    t = time.perf_counter()
    net.fit(X, Y, UPDATE_STEPS)
    update = time.perf_counter() - t
    return (f"drlos_emcmo's Q-network: first training at generation {EXPLORE_GENS + 1} {first:.2f} s, then "
            f"{1000 * update:.0f} ms every {PERIOD + 1} generations = {1000 * update / (PERIOD + 1):.2f} ms per "
            "generation on top of the table's")


def stage_split(name: str, n_gen: int | None, seed: int = 1) -> list[tuple[str, int, float, float, float]]:
    """Predesign then subtask 1 of the Stephenson-I config with algorithm ``name``: per stage (name,
    generations, total s, evaluation s, repair s)."""
    from core.formats.config import load_config
    from core.optimize.pipeline import Pipeline

    cfg = load_config(ROOT / "assets" / "configs" / "stephenson1_cycloid.toml")
    specs = [replace(c.spec(seed + k), algorithm=AlgorithmSpec(name, c.algorithm.pop_size),
                     n_gen=c.n_gen if n_gen is None else n_gen) for k, c in enumerate(cfg.stages[:2])]
    pipe = Pipeline(specs, cfg.start)
    rows = []
    for k, spec in enumerate(specs):
        stage = pipe.stage(k)
        stage.setup()
        used = {"eval": 0.0, "repair": 0.0}
        wrap(stage.problem, "_evaluate", used, "eval")
        repair = getattr(stage.algorithm, "repair", None)
        if repair is not None:
            wrap(repair, "_do", used, "repair")
        t = time.perf_counter()
        res = stage.run()
        total = time.perf_counter() - t
        pipe.record(k, res.with_pick(spec.pick))
        rows.append((spec.name, spec.n_gen, total, used["eval"], used["repair"]))
    return rows


def wrap(obj: object, method: str, used: dict[str, float], key: str) -> None:
    """Make ``obj.method`` add its run time to ``used[key]``."""
    inner = getattr(obj, method)

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            used[key] += time.perf_counter() - t

    setattr(obj, method, timed)


def stage_table(names: list[str], n_gen: int | None) -> None:
    print("\nStephenson-I stages (pop 200, seed 1): where the time goes")
    print(f"{'algorithm':<14} {'stage':<10} {'gens':>5} {'total (s)':>10} {'evaluation':>11} {'repair':>8} "
          f"{'eval+repair':>12} {'rest ms/gen':>12}")
    for n in names:
        stage_split(n, 2)  # compiles what the numba cache lacks, which the first run would count as bookkeeping
        for stage, gens, total, ev, rep in stage_split(n, n_gen):
            print(f"{n:<14} {stage:<10} {gens:>5} {total:10.2f} {ev / total:10.0%} {rep / total:8.0%} "
                  f"{(ev + rep) / total:12.0%} {1000 * (total - ev - rep) / gens:12.2f}")


def _one(job: tuple[str, str, int, int]) -> tuple[str, str, int, float, float]:
    prob, name, evals, seed = job
    r = run_moea(prob, name, 100, evals, seed)  # as clm moea measures them
    return prob, name, seed, r["igd"], r["hv"]


def quality(names: list[str], problems: list[str], seeds: range, evals: int, jobs: int = 1,
            cache: Path | None = None) -> tuple[list[list[str]], set[str]]:
    """Median IGD / HV per problem and algorithm with the rank-sum verdict on IGD against the reference;
    printed, and returned as rows of cells (problem first) with the codes (:func:`code_version`) the runs were
    made with. With ``cache`` (a JSON-lines file), each finished run is appended to it as it ends, with its code,
    and runs found in it are not run again: a long table survives an interruption and can be grown problem by
    problem. A cached run keeps the code it was made with, so a table from runs of older code says so."""
    import json

    work = [(p, n, evals, s) for p in problems for n in names for s in seeds]
    code = code_version()
    known: dict[tuple[str, str, int, int], tuple[float, float]] = {}
    made: dict[tuple[str, str, int, int], str] = {}  # the code each run was made with
    if cache is not None and cache.exists():
        for line in cache.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                key = (r["problem"], r["algorithm"], r["evals"], r["seed"])
                known[key] = (float(r["igd"]), float(r["hv"]))
                made[key] = str(r.get("code", "unknown"))
    todo = [w for w in work if (w[0], w[1], w[2], w[3]) not in known]
    print(f"{len(work) - len(todo)} of {len(work)} runs found in the cache, {len(todo)} to run", flush=True)

    def keep(r: tuple[str, str, int, float, float]) -> None:
        prob, name, seed, ig, hv = r
        known[(prob, name, evals, seed)] = (ig, hv)
        made[(prob, name, evals, seed)] = code
        if cache is not None:
            with cache.open("a") as fh:
                fh.write(json.dumps({"problem": prob, "algorithm": name, "evals": evals, "seed": seed,
                                     "igd": ig, "hv": hv, "code": code}) + "\n")

    if jobs > 1 and todo:
        import multiprocessing as mp

        with mp.get_context("fork").Pool(jobs) as pool:
            for r in pool.imap_unordered(_one, todo, chunksize=1):
                keep(r)
    else:
        for w in todo:
            keep(_one(w))
    done = [(p, n, s, *known[(p, n, e, s)]) for p, n, e, s in work]
    got: dict[tuple[str, str], tuple[list[float], list[float]]] = {}
    for prob, name, _, ig, hv in done:
        got.setdefault((prob, name), ([], []))
        got[(prob, name)][0].append(ig)
        got[(prob, name)][1].append(hv)
    print(f"\nmedian IGD / HV over {len(seeds)} seeds, pop 100, {evals} evaluations "
          f"(verdicts against {REFERENCE}; IGD over the runs with a feasible member, (k/n) when not all)")
    print(f"{'problem':<10}" + "".join(f"{n:>26}" for n in names))
    rows = []
    for prob in problems:
        cells = []
        for n in names:
            igds, hvs = got[(prob, n)]
            mark = ""
            if n != REFERENCE:
                ref = got[(prob, REFERENCE)][0]
                a, b = np.nan_to_num(igds, nan=np.inf), np.nan_to_num(ref, nan=np.inf)
                pv = ranksums(a, b).pvalue if not np.array_equal(a, b) else 1.0
                mark = "≈" if not pv < 0.05 else ("+" if np.median(a) < np.median(b) else "-")
            feasible = int(np.isfinite(igds).sum())
            med = np.nanmedian(igds) if feasible else np.nan
            some = f" ({feasible}/{len(igds)})" if feasible < len(igds) else ""
            cells.append(f"{med:.3g}{some} / {np.median(hvs):.3f} {mark}".strip())
        rows.append([prob, *cells])
        print(f"{prob:<10}" + "".join(c.rjust(26) for c in cells))
    if len(problems) > 1:
        ranks = mean_ranks([[got[(prob, n)][0] for n in names] for prob in problems])
        cells = [f"{r:.2f}" for r in ranks]
        rows.append(["mean rank", *cells])
        print(f"{'mean rank':<10}" + "".join(c.rjust(26) for c in cells))
    return rows, {made[w] for w in work}


def mean_ranks(igds: list[list[list[float]]]) -> NDArray[np.float64]:
    """``(n_algorithms,)`` the Friedman-style mean rank over problems (1 = best): on each problem the algorithms
    are ranked by median IGD, a run without a feasible member counting as the worst (+inf), ties sharing the
    average rank. ``igds[problem][algorithm]``: the runs' IGDs, NaN for a run without a feasible member."""
    from scipy.stats import rankdata

    med = np.array([[np.median(np.nan_to_num(np.asarray(r, dtype=float), nan=np.inf)) for r in row] for row in igds])
    return rankdata(med, axis=1).mean(axis=0)


def code_version() -> str:
    """The algorithms' code a run is made with: the last commit that changed core/ (``e4a941b``), with ``+dirty``
    when core/ has uncommitted changes, or ``unknown`` outside git."""
    import subprocess

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()

    try:
        head = git("log", "-1", "--format=%h", "--", "core")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", "core")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return (head or "unknown") + ("+dirty" if dirty else "")


def made_with(codes: set[str]) -> str:
    """The table's note on the code its runs were made with (cached runs keep the code they were made with)."""
    listed = ", ".join(sorted(codes))
    return f"; its runs were made with core/ as of commit{'s' if len(codes) > 1 else ''} {listed}"


def write_markdown(path: Path, names: list[str], rows: list[list[str]], seeds: int, evals: int,
                   marker: str = "quality-table", problems: str | None = None, codes: set[str] | None = None) -> None:
    """Put the table between ``<!-- {marker} -->`` and ``<!-- /{marker} -->`` in ``path``."""
    algorithms = ",".join(n for n in names if n != REFERENCE)
    command = (f"python benchmarks/algorithms.py --no-timing --algorithms {algorithms}"
               + (f" --problems {problems}" if problems else "")
               + f" --seeds {seeds} --evals {evals} --jobs 2 --markdown {path}"
               + (f" --marker {marker}" if marker != "quality-table" else ""))
    head = (f"Median IGD / HV (PlatEMO's normalisation) over {seeds} seeds, population 100, {evals} evaluations. "
            "IGD: the median over the runs that end with a feasible member, with (k/n) when only k of the n do "
            "(nan: none does); HV: the median over all runs, 0 for a run without one. "
            f"+ / - / ≈: IGD significantly better / worse / no different than {REFERENCE} (Wilcoxon rank-sum, 5 %; "
            f"a run without a feasible member counts as the worst). Mean rank: each algorithm's rank by median IGD "
            "on each problem (1 best, a run without a feasible member as the worst, ties shared), averaged over the "
            f"problems. Generated by `{command}`{made_with(codes or {code_version()})}.\n\n")
    table = "| problem | " + " | ".join(names) + " |\n|---|" + "---|" * len(names) + "\n"
    table += "".join("| " + " | ".join(r) + " |\n" for r in rows)
    text = path.read_text()
    a, b = f"<!-- {marker} -->", f"<!-- /{marker} -->"
    if a not in text or b not in text:
        raise SystemExit(f"{path} has no {a} ... {b} markers")
    i, j = text.index(a) + len(a), text.index(b)
    path.write_text(text[:i] + "\n" + head + table + text[j:])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer generations, seeds and evaluations (CI)")
    ap.add_argument("--algorithms", default="nsga2", help="comma-separated algorithms besides nsga2_pymoo")
    ap.add_argument("--problems", default=None, help=f"comma-separated problems for the quality table, of {KNOWN} "
                    "(default: MW1-14, CTP1-8, DAS-CMOP1-9)")
    ap.add_argument("--no-quality", action="store_true", help="timings only")
    ap.add_argument("--no-timing", action="store_true", help="the quality table only")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per cell (default 10; 3 with --quick)")
    ap.add_argument("--evals", type=int, default=None, help="evaluations per run (default 50 000; 5 000 --quick)")
    ap.add_argument("--jobs", type=int, default=1, help="runs in parallel processes")
    ap.add_argument("--markdown", type=Path, default=None, help="write the table into this file's markers")
    ap.add_argument("--marker", default="quality-table",
                    help="the markers in --markdown's file the table goes between (<!-- NAME --> <!-- /NAME -->)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="JSON-lines file of finished runs: appended as runs end, found runs are not run again")
    args = ap.parse_args(argv)
    keep_freed_memory()  # as clm does (core.kinematics.memory): SPEA2's (n, n) matrices reuse their pages
    names = [REFERENCE] + [n for n in args.algorithms.split(",") if n and n != REFERENCE]
    n_gen = 20 if args.quick else 100
    if not args.no_timing:
        print(f"bookkeeping per steady-state generation (pop 200, 16 variables, 3 objectives, DTLZ2, {n_gen} "
              "generations, median of 3 seeds)")
        # The VM's speed drifts up to 3x between sessions (pymoo's NSGA-II 4.9-17 ms): the last column scales each
        # figure by pymoo's in the same run to its fast phase, so runs of different days compare.
        ms = {n: 1000 * bookkeeping(n, n_gen) for n in names}
        print(f"{'algorithm':<14} {'ms/generation':>14} {f'at {REFERENCE} {FAST_PHASE_MS:g} ms':>22}")
        for n in names:
            print(f"{n:<14} {ms[n]:14.3f} {ms[n] * FAST_PHASE_MS / ms[REFERENCE]:22.3f}")
        if "drlos_emcmo" in names:
            print(qnet_line())
        stage_table(names, 10 if args.quick else None)
    if args.no_quality:
        return 0
    if args.problems:
        problems = [p.lower() for p in args.problems.split(",") if p]
        unknown = [p for p in problems if p not in PROBLEMS]
        if unknown:  # before any run, not as a worker's traceback after the others
            ap.error(f"unknown problem {unknown[0]!r}; known: {KNOWN}")
    elif args.quick:
        problems = ["mw1", "mw3", "ctp2"]
    else:
        problems = [p for p in PROBLEMS if p.startswith(("mw", "ctp", "dascmop"))]  # the table
    seeds = args.seeds or (3 if args.quick else 10)
    evals = args.evals or (5000 if args.quick else 50_000)
    rows, codes = quality(names, problems, range(1, seeds + 1), evals, args.jobs, args.cache)
    if args.markdown is not None:
        write_markdown(args.markdown, names, rows, seeds, evals, args.marker, args.problems, codes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
