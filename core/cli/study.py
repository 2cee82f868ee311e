"""``clm study``: run a study (algorithms x cases x seeds) on Dask, or write its report.

    clm study STUDY.toml --out DIR [--scheduler tcp://host:8786] [--workers N]
    clm study report DIR
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from core.cli import CLIError
from core.formats.files import check_out_dir, dir_lock, new_folders, remove_empty

MAX_WORKERS = 256


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "study",
        usage="clm study STUDY.toml --out DIR [--scheduler ADDRESS | --workers N] [--quiet] [--rerun-changed]\n"
              "                 [--mixed-code]\n"
              "       clm study report DIR",
        help="run a study of algorithms x cases x seeds on Dask, or write its report",
        description="Run every (algorithm, case, seed) cell of a study file as a Dask task (a local cluster with one "
        "worker per core, or --scheduler), keep each finished run in DIR/study.sqlite and DIR/runs/, and write "
        "DIR/report.md and DIR/report.html. Running the same command again resumes: finished cells are skipped "
        "and failed ones run again. 'clm study report DIR' writes the report of what is there.",
    )
    p.add_argument("args", nargs="+", metavar="STUDY.toml | report DIR", help="a study file, or 'report' and a study "
                   "directory")
    p.add_argument("--out", help="study directory (created; resumed if it holds the same study)")
    p.add_argument("--scheduler", help="address of a running Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--workers", type=int, help="worker processes of the local cluster (default: one per core)")
    p.add_argument("--quiet", action="store_true", help="no progress line on stderr")
    p.add_argument("--rerun-changed", action="store_true",
                   help="run again the finished cells whose settings changed since (budget, population, options, "
                   "the case config) or whose code did (a digest of core/); without it such a directory is refused")
    p.add_argument("--mixed-code", action="store_true",
                   help="keep finished cells another version of the code ran; the report counts the runs of each")
    p.set_defaults(func=run)


def _check_out(out: str | None) -> Path:
    if out is None:
        raise CLIError("--out is required: the study directory")
    return check_out_dir(out, ["study.sqlite", "report.md", "report.html"])


def _runs_kept(out: Path, done: bool = False) -> int:
    """How many runs the study folder's database holds (``done``: that finished, not the failed ones, which run again;
    0 if it has none or cannot be read)."""
    import sqlite3

    try:
        db = sqlite3.connect(f"file:{out / 'study.sqlite'}?mode=ro", uri=True)
        try:
            where = " WHERE status = 'done'" if done else ""
            return int(db.execute(f"SELECT count(*) FROM runs{where}").fetchone()[0])
        finally:
            db.close()
    except sqlite3.Error:
        return 0


def _remove_if_unused(out: Path, made: list[Path]) -> None:
    """Remove a study directory this command made, and the folders it made above it (``made``, innermost first),
    when no run finished in it and nothing else was put in it (a refused or failed start). Under the folder's
    lock: another command that took the folder once this one let it go keeps it (review of session 33); the lock
    file goes last, by ``dir_lock`` while still held, so no newer one is removed with it (review of session 35)."""

    ours = {".lock", "study.sqlite", "study.sqlite-journal", "study.sqlite-wal", "study.sqlite-shm"}
    try:
        with dir_lock(out, "clm study", remove=True):
            used = _runs_kept(out) > 0
            if used or any(p.name not in ours for p in out.iterdir()):  # a user's file put there meanwhile too
                return
            for p in out.iterdir():
                if p.name != ".lock":  # the database and its journals; the lock goes last (above)
                    p.unlink(missing_ok=True)
    except (ValueError, OSError):  # held by another command now (its folder), or not ours to remove
        return
    remove_empty(made)  # the folder itself, then a refused --out new/a/b's new/a: unless something came since


def run(args: argparse.Namespace) -> int:
    import sqlite3

    try:
        return _run(args)
    except sqlite3.Error as e:  # a damaged, truncated or read-only study.sqlite
        where = args.args[1] if args.args[0] == "report" and len(args.args) == 2 else args.out
        raise CLIError(f"{Path(str(where)) / 'study.sqlite'}: not a usable study database ({e}); the finished runs' "
                       "results are in runs/ beside it") from None


def _run(args: argparse.Namespace) -> int:
    from core.study.report import write_report

    if args.args[0] == "report":
        if len(args.args) != 2:
            raise CLIError("usage: clm study report DIR")
        md, page = write_report(args.args[1])
        print(f"wrote {md} and {page}")
        return 0
    if len(args.args) != 1:
        raise CLIError("give one study file (or 'report DIR')")
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise CLIError(f"--workers must be between 1 and {MAX_WORKERS}, got {args.workers}")
    if args.scheduler is not None and not args.scheduler.strip():  # Dask said "missing port number in address ''"
        raise CLIError("--scheduler is empty; give a Dask scheduler address such as tcp://127.0.0.1:8786")
    if args.scheduler is not None and args.workers is not None:
        raise CLIError("--workers sets up a local cluster; a --scheduler's cluster has its own workers")
    from core.formats.study import load_study
    from core.study.runner import run_study

    study = load_study(args.args[0])
    if args.scheduler is not None:  # asked before DIR is made: a refusal leaves nothing behind (rehearsal 8)
        from core.optimize.workers import connect

        try:
            connect(args.scheduler).close()
        except ValueError as exc:
            raise CLIError(str(exc)) from None
    made = new_folders(Path(args.out)) if args.out is not None else []
    out = _check_out(args.out)
    try:
        summary = run_study(study, str(out), scheduler=args.scheduler, workers=args.workers,
                            stream=None if args.quiet else sys.stderr, rerun_changed=args.rerun_changed,
                            mixed_code=args.mixed_code)
    except BaseException as exc:
        if made:
            _remove_if_unused(out, made)
        if isinstance(exc, KeyboardInterrupt):  # it ended silently with 130 (QA, session 36)
            kept = _runs_kept(out, done=True) if out.is_dir() else 0
            print(f"clm: stopped; {kept} finished run{'s' * (kept != 1)} kept in {out}: the same command goes on from "
                  "there" if kept else "clm: stopped before any run finished; nothing kept", file=sys.stderr)
        raise
    md, page = write_report(out)
    print(f"{study.name}: {summary.total} cells, {summary.skipped} already done, {summary.ran} run now "
          f"({summary.failed} failed) in {summary.wall_time:.1f} s; report: {md}, {page}")
    return 1 if summary.failed else 0
