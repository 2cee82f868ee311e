"""``clm design CONFIG.toml --out DIR``: run a whole design from a configuration file.

Progress goes to stderr (a bar redrawn in place on a terminal, a line per 10 % otherwise),
the summary table to stdout. DIR receives ``result.json`` (configuration, every stage's
population, fronts, shortlist, picks, settings, seeds, timings, versions; lossless floats) and
one CSV per stage (``<k>_<stage>.csv``: every member's parameters, objectives, constraint
values and metrics, with its feasibility, front membership, knee rank and pick). Ctrl-C stops
between generations and still writes the partial result (exit code 130; SIGTERM the same, 143); a
stage that fails writes the stages finished before it, with the error, and exits with code 1.
"""

from __future__ import annotations

import argparse
import csv
import io
import signal
import sys
import threading
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from core.cli import CLIError, path_arg
from core.formats.config import load_config
from core.formats.files import atomic_write, chart_file, check_out_dir, dir_lock, read_design_result, stage_file
from core.formats.typed import MAX_SEED
from core.kinematics.kernel_cache import CompileTimer
from core.kinematics.model import OutputStage
from core.optimize.baselines import DP_METHODS
from core.optimize.design_config import DesignConfig
from core.optimize.multistart import MultiStart, where_name
from core.optimize.problem import Constraint
from core.optimize.result import StageResult, dumps
from core.optimize.run import DesignRun, StageFailed, run_design
from core.optimize.scale import PAPER_STRIDE
from core.optimize.stage import Progress

BAR = 24
COMPILE_NOTE = 0.5  # s of compiling a run's summary and clm compare mention


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "design",
        help="run a hierarchical design (or a baseline) from a TOML configuration",
        description="Run the stages of a design configuration (see docs/optimization.md and assets/configs/), "
        "print a summary table and write result.json and one CSV per stage into --out.",
    )
    p.add_argument("config", type=path_arg, help="configuration file (TOML)")
    p.add_argument("--out", dest="out_text", required=True, metavar="DIR", help="output directory (created if missing)")
    p.add_argument("--seed", type=int, default=None, metavar="N", help="override the configuration's seed")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="processes for a multi-start block's chains (default: the configuration's 'workers', "
                   "else every core); the results do not depend on it")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run a multi-start block's chains on this Dask scheduler (tcp://host:8786) instead of local "
                   "processes; the results are the same")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier run in --out (its result.json, stage CSVs and pareto-*.png charts) once "
                   "this one finishes (one stopped before goes beside it, in OUT-stopped); without it such a folder "
                   "is refused")
    p.set_defaults(func=run)


class ProgressBar:
    """Per-generation progress on a stream: redrawn in place on a terminal, else a line per 10 %."""

    def __init__(self, stream: TextIO, n_stages: int) -> None:
        self.stream, self.n_stages = stream, n_stages
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.line: tuple[int, int | None, float] | None = None  # (stage, chain, fraction) drawn last
        self.deciles: dict[tuple[int, int | None], int] = {}

    def __call__(self, p: Progress) -> None:
        try:
            self._draw(p)
        except OSError:  # BrokenPipeError: the reader went away ('2>&1 | head'): the run goes on, undrawn
            self.stream = io.StringIO()  # (lab rehearsal: it failed the stage and the folder blocked a rerun)

    def _draw(self, p: Progress) -> None:
        frac = min(1.0, p.fraction)
        done = int(round(BAR * frac))
        best = ""
        if p.feasible.any():
            vals = p.F[p.feasible].min(axis=0)
            # Each objective's own best, often of different members: "best h_s=17.12 I=47.66" read as one design's
            # values, whose I was 88 (QA, session 37).
            best = "  " + ", ".join(f"best {o}={v:.4g}" for o, v in zip(p.objectives, vals, strict=True))
        else:
            best = f"  no feasible member (least violation {np.min(p.cv):.3g})" if p.cv.size else ""
        chain = "" if p.chain is None else f" chain {p.chain}"
        line = (f"[{p.index + 1}/{self.n_stages} {p.stage}{chain}] {'#' * done}{'.' * (BAR - done)} "
                f"gen {p.generation}/{p.n_gen}  {p.elapsed:.1f} s{best}")
        key = (p.index, p.chain)
        if self.tty:
            # Chains in worker processes interleave on one line; a finished stage keeps its line.
            if self.line is not None and self.line[:2] != key and self.line[2] >= 1.0:
                self.stream.write("\n")
            self.line = (p.index, p.chain, frac)
            self.stream.write("\r\033[K" + line)
        else:
            decile = int(10 * frac)
            if self.deciles.get(key) != decile:
                self.deciles[key] = decile
                self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty and self.line is not None:
            write_quietly(self.stream, "\n")


def write_quietly(stream: TextIO, text: str) -> bool:
    """Write and flush ``text``; False, and nothing raised, if the stream's reader went away (BrokenPipeError:
    ``clm design ... 2>&1 | head``): a message about the run must not stop the run."""
    try:
        stream.write(text)
        stream.flush()
        return True
    except OSError:
        return False


def stage_rows(res: StageResult) -> tuple[list[str], list[list[Any]]]:
    """CSV header and rows of one stage result (one row per member)."""
    names = list(res.mechanism.param_names)
    metrics = [k for k in res.metrics if k not in res.objectives]
    header = (["member", "feasible", "front", "knee_rank", "picked", "cv"] + names + list(res.objectives)
              + [f"constraint[{c}]" for c in res.constraints] + metrics)  # "g[...]" sat beside the parameter g
    knee = {i: r for r, i in enumerate(res.shortlist.knees)}
    front = set(res.front)
    rows = []
    for i in range(res.pop):
        rows.append([i, int(res.feasible[i]), int(i in front), knee.get(i, ""), int(res.picked == i),
                     float(res.cv[i])] + [float(v) for v in res.X[i]] + [float(v) for v in res.F[i]]
                    + [float(v) for v in res.G[i]] + [float(res.metrics[k][i]) for k in metrics])
    return header, rows


def _csv(rows: list[list[Any]]) -> str:
    buf = io.StringIO()
    csv.writer(buf).writerows(rows)
    return buf.getvalue()


def output_names(config: DesignConfig) -> list[str]:
    """The files ``write_outputs`` writes for a configuration."""
    if config.method in DP_METHODS:
        return ["result.json", f"{config.method}.csv"]
    return ["result.json", *(stage_file(k, s.name) for k, s in enumerate(config.stages))]


def write_outputs(out: Path, run_: DesignRun) -> list[Path]:
    """result.json and the per-stage CSVs, each written atomically; returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "result.json"]
    for res in run_.results:
        path = out / stage_file(res.index, res.name)
        header, rows = stage_rows(res)
        atomic_write(path, _csv([header, *[[_cell(v) for v in r] for r in rows]]))
        written.append(path)
    if run_.baseline is not None:
        b = run_.baseline.to_dict()
        path = out / f"{run_.baseline.method}.csv"
        keys = list(b["params"]) + list(b["metrics"]) + ["dp", "time"]
        atomic_write(path, _csv([keys, [_cell(v) for v in [*b["params"].values(), *b["metrics"].values(), b["dp"],
                                                               b["time"]]]]))
        written.append(path)
    atomic_write(out / "result.json", dumps(run_.to_dict()))  # last: it names the CSVs' run
    return written


def earlier_outputs(result: Path) -> tuple[list[str], bool]:
    """The files an earlier ``clm design`` run in the same folder wrote, read from its ``result.json``: its stage
    CSVs (or baseline CSV) and the ``pareto-<k>_<stage>.png`` charts clm-charts draws from it; and whether it
    completed. CLIError when the file is not such a result (it is not ours to replace)."""
    try:
        data = read_design_result(result)
    except ValueError:
        raise CLIError(f"{result} is not a 'clm design' result; not replacing it (choose another --out)") from None
    names: list[str] = []
    if data.get("method") in DP_METHODS:
        names.append(f"{data['method']}.csv")
    pipeline = data.get("pipeline")
    stages = pipeline.get("stages") if isinstance(pipeline, dict) else None
    for k, stage in enumerate(stages if isinstance(stages, list) else []):
        name = stage.get("name") if isinstance(stage, dict) else None
        if isinstance(name, str) and name:
            names += [stage_file(k, name), chart_file(k, name)]
    return names, data.get("status") == "complete"


def _cell(v: Any) -> Any:
    if isinstance(v, float):
        return repr(v) if np.isfinite(v) else ("nan" if np.isnan(v) else ("inf" if v > 0 else "-inf"))
    return v


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}" if np.isfinite(v) else "-"
    return str(v)


def table(header: list[str], rows: list[list[Any]]) -> str:
    """A plain text table with right-aligned columns (the first left-aligned)."""
    cells = [header] + [[_fmt(v) for v in r] for r in rows]
    widths = [max(len(r[j]) for r in cells) for j in range(len(header))]
    lines = []
    for r in cells:
        parts = [r[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(r[1:], widths[1:], strict=True)]
        lines.append("  ".join(parts).rstrip())
    return "\n".join(lines)


# The summary's metric columns with their units (rehearsal 3 read bare "f2 f3" and asked what and in what).
SHOWN = {"mse": "MSE (mm)", "S": "S (%)", "I": "I (mm/s)", "h_s": "h_s (mm)", "f2": "f2 width (mm^2)",
         "f3": "f3 low point (mm^2)", "h6": "h6 (mm)", "h4": "h4 (mm)"}


def summary(run_: DesignRun) -> str:
    """The end-of-run table: one line per stage (or the baseline) with its pick's metrics."""
    c = run_.config
    workers = f", {run_.workers} worker process{'es' if run_.workers != 1 else ''}" if run_.multistart else ""
    compiled = (f" ({run_.compile_time:.1f} s of it compiling numba kernels, which later runs of this code load from "
                "its cache; the stage times below include it)" if run_.compile_time >= COMPILE_NOTE else "")
    lines = [f"{c.name}: {c.method}, {c.mechanism.name}, seed {c.seed}, {run_.status}, wall {run_.wall_time:.1f} s"
             + compiled + workers]
    if run_.baseline is not None:
        b = run_.baseline
        m = b.metrics
        lines.append(table(["method", "time (s)", "MSE (mm)", "S (%)", "I (mm/s)", "h_s (mm)", "violation"],
                           [[b.to_dict()["title"], b.time, m["mse"], m["S"], m["I"], m["h_s"], m["violation"]]]))
        return "\n".join(lines)
    show = [k for k in SHOWN if any(k in r.metrics for r in run_.results)]
    header = ["stage", "status", "gen", "time (s)", "evals", "feasible", "front", "pick", *(SHOWN[k] for k in show)]
    rows = []
    for r in run_.results:
        i = r.picked
        vals = [float(r.metrics[k][i]) if (i is not None and k in r.metrics) else float("nan") for k in show]
        rows.append([r.name, r.status, r.generation, float(r.timings["total"]), r.n_evals,
                     f"{int(r.feasible.sum())}/{r.pop}", len(r.front), "-" if i is None else i, *vals])
    lines.append(table(header, rows))
    for block in run_.multistart:
        lines.append(chains_table(block, show))
    lines += notes(run_)
    return "\n".join(lines)


def notes(run_: DesignRun) -> list[str]:
    """A line for each stage that ran out of generations short of its early stop, or picked an infeasible member:
    an impossible target (an RTCLM h4 of 5000 mm) ended "complete" with nothing to say so; and one for a leg sized
    other than the paper's."""
    out = []
    k = max((s.problem_spec().scale for s in run_.config.stages), key=lambda v: abs(v - 1.0), default=1.0)
    if k != 1.0:
        out.append(f"note: the target is {PAPER_STRIDE * k:.4g} mm wide: the built-in bounds, box steps and limits "
                   f"were the paper's x {k:.3g} (typed ones as typed; docs/optimization.md, \"Legs of other sizes\")")
    stops = {s.name: s.stop_below for s in run_.config.stages}
    for r in run_.results:
        i, stop = r.picked, stops.get(r.name)
        if r.status == "complete" and stop is not None and i is not None:
            got = ", ".join(f"{k} {float(r.F[i, j]):.4g}" for j, k in enumerate(r.objectives))
            limits = ", ".join(f"{v:g}" for v in stop)
            # Its budget: the generations, or max_evals (a study cell's), whichever ended it.
            out.append(f"note: {r.name} spent its budget ({r.generation} generations, {r.n_evals} evaluations) "
                       f"without reaching its stop_below [{limits}] (its pick: {got}): the target may be out of reach")
        if i is not None and not r.feasible[i]:
            out.append(f"note: {r.name}'s pick #{i} misses the stage's constraints ({int(r.feasible.sum())} of "
                       f"{r.pop} members meet them)")
    return out


def _limits(where: Sequence[Constraint]) -> str:
    return "".join(f", {where_name(c)} {c.upper if c.upper is not None else c.lower:g}" for c in where)


def chains_table(block: MultiStart, show: list[str]) -> str:
    """One line per chain of a multi-start block: its status, time and its last pick (at the block's last stage,
    or where a screen dropped it or a cancel stopped it)."""
    names = block.stages
    head = (f"multi-start {names[0]}..{names[-1]}: {len(block.chains)} chains, select {block.starts.select}"
            + _limits(block.starts.where))
    if (sc := block.starts.screen) is not None:
        head += f"; after {sc.after} the {sc.keep} best by {sc.by}{_limits(sc.where)} went on"
    rows = []
    for c in block.chains:
        last = c.last_pick()
        at, m = (names[last[0]], last[1]) if last is not None else ("-", {})
        feasible = ("yes" if c.feasible else "no") if c.status == "complete" else "-"
        rows.append([("* " if c.index == block.chosen else "  ") + str(c.index), c.status, c.time, at, feasible,
                     *[float(m.get(k, float("nan"))) for k in show]])
    return head + "\n" + table(["chain", "status", "time (s)", "pick at", "feasible",
                                 *(SHOWN.get(k, k) for k in show)], rows)


def run(args: argparse.Namespace) -> int:
    args.out = Path(args.out_text)
    config = load_config(args.config)
    if args.seed is not None:
        if not 0 <= args.seed <= MAX_SEED:
            raise CLIError(f"--seed must be between 0 and {MAX_SEED}, got {args.seed}")
        config = replace(config, seed=args.seed)
    if args.workers is not None:
        if args.workers < 1:
            raise CLIError(f"--workers must be >= 1, got {args.workers}")
        config = replace(config, workers=args.workers)
    if args.scheduler is not None:
        if not args.scheduler.strip():
            raise CLIError("--scheduler is empty; give a Dask scheduler address such as tcp://127.0.0.1:8786")
        config = replace(config, scheduler=args.scheduler)
        if not any(st.starts for st in config.stages):  # not contacted at all: say so rather than seem to use it
            print(f"clm: note: --scheduler is not used: {args.config} has no multi-start block "
                  "(only a block's chains run on Dask)", file=sys.stderr)
        else:  # asked now, as clm study does: exit 2 and nothing written, not a failed run in --out (rehearsal 8)
            from core.optimize.workers import connect

            try:
                connect(args.scheduler).close()
            except ValueError as exc:
                raise CLIError(str(exc)) from None
    if config.start.mechanism.derive is None:  # the RTCLM's targets are heights, not a curve
        _warn_target(config.baseline.target, config.start.output)
    check_out_dir(args.out_text, output_names(config))
    # Held from the check for an earlier run to the last file written (lab rehearsal: a second clm design started
    # into the same folder 0.3 s later passed the check, and its files silently replaced the first run's).
    with dir_lock(args.out, "clm design", remove=True):
        return _run_into(args, config)


def _run_into(args: argparse.Namespace, config: DesignConfig) -> int:
    previous: list[str] = []
    finished = False  # the earlier run in --out completed: only a completed run replaces it
    if (args.out / "result.json").exists():
        if not args.overwrite:
            raise CLIError(f"--out {args.out_text!r} holds an earlier run (result.json); choose another folder or "
                           "pass --overwrite to replace it")
        previous, finished = earlier_outputs(args.out / "result.json")
    n = max(1, len(config.stages))
    bar = None if args.quiet else ProgressBar(sys.stderr, n)
    cancel = threading.Event()
    old: dict[int, Any] = {}
    terminated = False

    def say(text: str) -> None:
        # A closed pipe (`clm design ... | head`) must not turn a graceful stop into a failed stage (review of
        # session 32: the handler's print raised BrokenPipeError inside the running stage).
        write_quietly(sys.stderr, text + "\n")

    def on_sigint(signum: int, frame: Any) -> None:
        # First Ctrl-C: stop between generations and keep the partial result; a second one aborts.
        if cancel.is_set():
            raise KeyboardInterrupt
        cancel.set()
        say("\nclm: stopping after this generation (Ctrl-C again to abort)")

    def on_sigterm(signum: int, frame: Any) -> None:
        # kill, timeout, a batch scheduler's end of job: the same graceful stop (a generation takes well under
        # the seconds they wait before SIGKILL), exit code 143.
        nonlocal terminated
        terminated = True
        if not cancel.is_set():
            cancel.set()
            say("\nclm: terminated; stopping after this generation")

    if threading.current_thread() is threading.main_thread():
        old = {signal.SIGINT: signal.signal(signal.SIGINT, on_sigint),
               signal.SIGTERM: signal.signal(signal.SIGTERM, on_sigterm)}
    failure: StageFailed | None = None
    timer = CompileTimer()
    try:
        with timer:
            result = run_design(config, bar, cancel)
    except StageFailed as e:  # keep the stages that finished before it
        result, failure = e.run, e
    finally:
        for signum, handler in old.items():
            signal.signal(signum, handler)
        if bar is not None:
            bar.close()
    result.compile_time = timer.seconds
    code = 1 if failure is not None else 0 if result.status == "complete" else 143 if terminated else 130
    dest, stale = args.out, []
    if finished and code:
        # Ctrl-C, a kill or a failing stage under --overwrite replaced a finished run with a partial one (QA, session
        # 36): the earlier run stays, and this one goes beside it.
        note = (f"the earlier run in {args.out} is kept as it was: a run that did not finish does not replace it "
                "under --overwrite")
        try:
            dest = _beside(args.out)
            write_outputs(dest, result)
        except OSError as exc:  # a parent folder the user cannot write to (review of session 36)
            print(f"clm: {note}; this one could not be written beside it ({exc.strerror or exc}: "
                  f"{exc.filename or args.out.parent})", file=sys.stderr)
            if failure is not None:
                print(f"clm: error: {failure}", file=sys.stderr)
            return code
        print(f"clm: {note}; this one is in {dest}", file=sys.stderr)
    else:
        kept = {p.name for p in write_outputs(args.out, result)}
        # Plain names in --out only: a result.json is a file anyone could have edited ("0_../x.csv").
        stale = [args.out / n for n in previous if n not in kept and Path(n).name == n and (args.out / n).is_file()]
        for path in stale:
            path.unlink(missing_ok=True)
    print(summary(result))
    if stale:
        print(f"removed {len(stale)} file(s) of the earlier run: {', '.join(p.name for p in stale)}")
    print(f"wrote {dest / 'result.json'}")
    if failure is not None:
        done = len(result.results)
        print(f"clm: error: {failure}; the {done} stage(s) finished before it are in {dest / 'result.json'} "
              "(its 'error' holds the traceback)", file=sys.stderr)
    return code


def _beside(out: Path) -> Path:
    """A new folder next to ``out`` for a run that must not replace it: ``<out>-stopped``, or ``-stopped-2``, ...
    (made here, so no other command writes into it)."""
    out = out.resolve()  # '--out .' named nothing to put the suffix on: './-stopped', inside the earlier run
    for k in range(1, 1000):
        p = out.parent / (f"{out.name}-stopped" + (f"-{k}" if k > 1 else ""))
        try:
            p.mkdir()
            return p
        except FileExistsError:
            continue
    raise CLIError(f"no free folder next to {out} for the stopped run")


def _warn_target(target: str, output: OutputStage) -> None:
    """A word on stderr when the config's target curve is far from a leg's size (a CSV in m or um is read as mm: the
    run went on to a confident nonsense, where the studio warned about the same file), or would make the leg walk
    wrongly once the output stage maps it to the leg frame (drawn clockwise, or stance up)."""
    from core.analysis.targets import path_note, scale_note
    from core.optimize.objectives import load_target

    cycloid = target.split(":", 1)[0] == "cycloid"
    curve = load_target(target)  # read once: a CSV was read for each note
    note = scale_note(curve.points, curve.period if curve.has_time else None)  # a cycloid's T = 2000 (ms) too
    if note:
        print(f"clm: warning: target {target if cycloid else Path(target).name}: {note}", file=sys.stderr)
    note = path_note(output.apply(curve.sample(360)), remedy=not cycloid)
    if note:
        fix = ". Check the config's output stage (the paper's legs map the cycloid by k = -1 about (L/2, 0))" \
            if cycloid else ""
        print(f"clm: warning: target {target if cycloid else Path(target).name} with output "
              f"{output.describe()}: {note}{fix}", file=sys.stderr)

