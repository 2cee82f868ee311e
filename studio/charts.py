"""Pareto charts as PNG files, drawn on the server (plotly + kaleido, with Debian's chromium).

    clm-charts RUN_DIR            # pareto-<k>_<stage>.png next to the CSVs of a `clm design --out RUN_DIR`
    python -m studio.charts RUN_DIR

``core`` never imports plotly, so ``clm design`` writes the data (result.json, CSVs) and this command, on the
studio's side, draws it; the studio's Files panel serves the same PNG of the stage in view.
"""

from __future__ import annotations

import argparse
import html
import logging
import math
import os
import sys
import threading
import warnings
from collections.abc import Mapping
from pathlib import Path

import plotly.graph_objects as go

from core.analysis.targets import cycloid_params
from core.formats.files import atomic_write, chart_file, read_design_result
from core.optimize.pipeline import Pipeline
from core.optimize.result import StageResult
from core.optimize.rtclm import is_rtclm
from studio.figures import flat_axes, make_pareto_figure, same_for_all, with_title_wrapped
from studio.study import status_text

WIDTH, HEIGHT = 1000, 800
TITLE_CHARS = 140  # a title line the PNG shows whole (13 px type: ~6 px a character; 170 ran past 1000 px)


# kaleido's browser, kept running between PNGs when asked (the studio): each PNG started its own chromium, 3.6 s
# for a small chart and 7-8 s for the studio's on this machine, against 0.26 s once one is running.
_KALEIDO_LOCK = threading.Lock()
_kaleido_kept = False


def _not_ignored(record: logging.LogRecord) -> bool:
    return "Ignoring" not in str(record.msg)


def _quiet_channel() -> None:
    """kaleido's browser channel logs a traceback for a message it then ignores ("JSONError decoding message.
    Ignoring"), which read as a crash on clm-charts' stderr (QA, session 36): that record is filtered out; its real
    failures raise in :func:`png`. The module is imported first: a logger asked for by name before it made its own
    is a plain one, whose missing ``debug2`` stopped the channel's reader and hung every PNG."""
    try:
        import choreographer.channels.pipe as pipe
    except ImportError:
        return
    logger = getattr(pipe, "_logger", None)
    if isinstance(logger, logging.Logger) and _not_ignored not in logger.filters:
        logger.addFilter(_not_ignored)


def png(fig: go.Figure, width: int = WIDTH, height: int = HEIGHT, keep: bool = False) -> bytes:
    """The figure as PNG bytes; ValueError naming what is missing when kaleido or its browser cannot run.
    ``keep``: start kaleido's browser once and draw this and later PNGs in it (``stop_png_browser`` ends it)."""
    global _kaleido_kept
    _quiet_channel()
    with _KALEIDO_LOCK:  # one drawing at a time: the kept browser is one
        if keep and not _kaleido_kept:
            try:
                import kaleido  # type: ignore[import-untyped]

                kaleido.start_sync_server(silence_warnings=True)
                _kaleido_kept = True
            except Exception:  # noqa: BLE001 - then each PNG starts its own browser, as without keep
                pass
        try:
            with warnings.catch_warnings():  # plotly's "kopts argument is ignored if using a server"
                warnings.simplefilter("ignore", UserWarning)
                return fig.to_image(format="png", width=width, height=height, scale=1)
        except Exception as exc:  # noqa: BLE001 - kaleido raises assorted errors when no browser can start
            if _kaleido_kept:  # a kept browser that died: the next PNG starts afresh
                _stop_kaleido()
            raise ValueError(f"cannot draw PNG charts here ({type(exc).__name__}: {exc}); they need the kaleido "
                             "package and a chromium browser (apt-get install chromium)") from None


def _stop_kaleido() -> None:
    global _kaleido_kept
    try:
        import kaleido

        kaleido.stop_sync_server(silence_warnings=True)
    except Exception:  # noqa: BLE001 - already gone
        pass
    _kaleido_kept = False


def stop_png_browser() -> None:
    """End the browser ``png(keep=True)`` keeps (a no-op if none runs)."""
    with _KALEIDO_LOCK:
        if _kaleido_kept:
            _stop_kaleido()


def chart_title(r: StageResult, state: str, target: str = "") -> str:
    """A Pareto chart's title, readable on its own: mechanism, stage, ``state``, feasible count, front size and
    the target (``target_text``)."""
    # The RTCLM's stages measure both modes: its mechanism's title ("RTCLM, primary mode (...)") read wrong over
    # rtclm2, the auxiliary-mode stage.
    mech = "RTCLM" if is_rtclm(r.mechanism.name) else r.mechanism.title
    return (f"{mech} · {r.name} · {state} · {int(r.feasible.sum())} feasible of {r.pop} · "
            f"front {len(set(r.front))}" + (f" · target {target}" if target else ""))


def result_figure(r: StageResult, labels: dict[str, str] | None = None, target: str = "") -> go.Figure:
    """A stage result's chart, titled with its mechanism, stage, status and target (readable on its own). Three
    objectives of which one is the same for every member are drawn projected onto two, as the studio opens them
    (subtask 1's f2 = f3 = 0 drew one clipped diamond in an empty 3-D box), and the title says which are flat."""
    title = chart_title(r, status_text(r), target)
    axes = flat_axes(r.F, r.objectives)
    if axes is not None and (flat := same_for_all(r.F, r.objectives)):
        title += f" · {flat}"
    return make_pareto_figure(r.F, r.cv, objectives=r.objectives, labels=labels or {}, front=r.front,
                              knees=r.shortlist.knees, best=r.shortlist.best, passed=r.picked, title=title, axes=axes)


def target_text(settings: object, curve_names: Mapping[str, str] | None = None) -> str:
    """The target a stage was run against, from its settings (``cycloid L=300 mm, H=100 mm, T=2 s``, ``curve leg.csv``),
    else "". A curve file is named by ``curve_names`` (``{target option: name}``, an upload's name) or its file name,
    never by its path: the studio keeps curves in the server's cache folder, whose path has no place on a chart."""
    problem = settings.get("problem") if isinstance(settings, dict) else None
    options = problem.get("options") if isinstance(problem, dict) else None
    target = options.get("target") if isinstance(options, dict) else None
    if isinstance(options, dict) and all(_number(options.get(k)) for k in ("h6_target", "h4_target")):
        return f"h6={options['h6_target']:g} mm, h4={options['h4_target']:g} mm"  # an RTCLM stage's heights
    if not isinstance(target, str) or not target or len(target) >= 200:
        return ""
    if curve_names and target in curve_names:
        text = curve_names[target]
    elif target.split(":", 1)[0] == "cycloid":  # as core.analysis.targets.parse_target reads it
        text = cycloid_text(target)
    else:
        text = f"curve {Path(target).name}"
    return html.escape(text, quote=False)  # a chart's title is HTML to plotly: an upload named "<b>" is text


def _number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def cycloid_text(target: str) -> str:
    """``cycloid:L=300.0,H=100.0,T=2.0`` as a title says it: ``cycloid L=300 mm, H=100 mm, T=2 s`` (the option's
    own text, "L=300.0 H=100.0 T=2.0", gave no units); a malformed one as it is."""
    try:
        p = cycloid_params(target)
    except ValueError:
        return target.replace(":", " ").replace(",", " ")
    return f"cycloid L={p['L']:g} mm, H={p['H']:g} mm, T={p['T']:g} s"


def run_charts(run_dir: Path) -> list[Path]:
    """Write ``pareto-<k>_<stage>.png`` for every stage with a result in ``run_dir/result.json``."""
    data = read_design_result(run_dir / "result.json")
    if not isinstance(data.get("pipeline"), dict):
        raise ValueError(f"{run_dir / 'result.json'} has no pipeline (a baseline run has no Pareto front)")
    pipe = Pipeline.from_dict(data["pipeline"])
    written = []
    for k, (spec, r) in enumerate(zip(pipe.stages, pipe.results, strict=True)):
        if r is None or r.pop == 0:
            continue
        # A long title (an RTCLM stage's unmet constraints) ran past the PNG's edge: broken into lines.
        fig = with_title_wrapped(result_figure(r, dict(spec.problem.labels), target_text(r.settings)), TITLE_CHARS)
        path = run_dir / chart_file(k, r.name)
        atomic_write(path, png(fig))
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="clm-charts", description="Draw the Pareto chart of every stage of a "
                                 "`clm design --out DIR` run as DIR/pareto-<k>_<stage>.png.")
    ap.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    args = ap.parse_args(argv)
    try:
        written = run_charts(args.run_dir)
    except ValueError as exc:
        print(f"clm-charts: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # "[Errno 13] Permission denied: 'run/pareto-0_predesign.png'" read as Python's (QA)
        where = f": {exc.filename}" if exc.filename else ""
        print(f"clm-charts: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    try:
        for path in written:
            print(f"wrote {path}", flush=True)
    except BrokenPipeError:  # the reader (head) went away: quietly, as clm (the charts are written)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
