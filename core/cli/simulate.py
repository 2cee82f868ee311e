"""``clm simulate``: solve one design over a crank revolution and print a summary or JSON."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from core.analysis.evaluate import MIN_SAMPLES
from core.analysis.targets import read_user_file
from core.cli import CLIError, dumps, path_arg
from core.formats.design import check_design, design_from_dict
from core.formats.typed import unique_keys
from core.kinematics import presets
from core.kinematics.checks import MAX_SAMPLES
from core.kinematics.design import Design
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, RTCLM_PRIMARY
from core.kinematics.solver import Solution
from core.optimize.rtclm import is_rtclm

# Guards memory: joints alone take n_samples * n_joints * 32 bytes, and JSON text ~10x that.
MAX_DESIGN_BYTES = 1_000_000


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="solve one design over a crank revolution",
        description="Solve one design (a preset or a design JSON file, see docs/cli.md) over one crank "
        "revolution; print a summary, or with --json the joints and the tracked point in both frames.",
    )
    add_source(p)
    p.add_argument("--samples", type=int, default=360, metavar="N", help="crank samples per revolution (default 360)")
    p.add_argument("--json", action="store_true", help="print the whole solution as JSON")
    p.add_argument(
        "--backend",
        choices=("numpy", "numba", "auto"),
        default="numpy",
        help="solver; numpy (default) needs no compilation, which suits one design",
    )
    add_mode(p)
    p.set_defaults(func=run)


MODES = {"primary": RTCLM_PRIMARY.name, "auxiliary": RTCLM_AUXILIARY.name}


def add_mode(p: argparse.ArgumentParser) -> None:
    """``--mode``: the RTCLM's other mode of the same design vector (a run's pick is in its primary mode)."""
    p.add_argument("--mode", choices=tuple(MODES),
                   help="for an RTCLM design: this mode of the same leg (its 13 parameters lock it either way)")


def add_source(p: argparse.ArgumentParser) -> argparse._MutuallyExclusiveGroup:
    """The design a command reads: ``--preset NAME`` or ``--design FILE`` (one of them, required); the group, for a
    command that takes another source too (``clm evaluate --curve``)."""
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--preset", metavar="NAME", help="a preset name (see 'clm presets')")
    src.add_argument("--design", metavar="FILE", type=path_arg,
                     help="a design JSON file, or a clm design run (its folder or result.json): its final pick")
    return src


def load_design(args: argparse.Namespace) -> tuple[Design, str | None]:
    """The design named by ``--preset`` or read from ``--design``, checked, in ``--mode``; and the preset name."""
    design, preset = _load(args)
    mode = getattr(args, "mode", None)
    if mode is None or design.mechanism.name == MODES[mode]:
        return design, preset
    if not is_rtclm(design.mechanism.name):
        raise CLIError(f"--mode {mode}: {design.mechanism.name} has no modes; only the RTCLM (rtclm_primary, "
                       "rtclm_auxiliary) has")
    from core.kinematics import mechanisms

    return Design(mechanisms.get(MODES[mode]), design.params, design.output), None


def warn_units(design: Design, label: str, sol: Any = None) -> None:
    """``clm: warning:`` on stderr when the design looks written in m or degrees (``core.formats.design.unit_note``);
    ``sol``: the design solved, if the caller has it."""
    from core.formats.design import unit_note

    sol = design.solve(360, derivatives=False) if sol is None else sol
    note = unit_note(design, sol.point[0] if sol.violation[0] == 0.0 else None)  # else: what does not assemble
    if note:
        print(f"clm: warning: {label}: {note}", file=sys.stderr)


def design_label(args: argparse.Namespace, preset: str | None) -> str:
    """What the output calls the design: the preset, or the preset or file in the ``--mode`` it was switched to (a
    switched preset is no preset any more, and was printed as "None")."""
    if preset is not None:
        return preset
    source = args.preset if args.preset is not None else str(args.design)
    source = "<stdin>" if source == "-" else source
    mode = getattr(args, "mode", None)
    return f"{source} ({mode} mode)" if mode is not None else source


def _load(args: argparse.Namespace) -> tuple[Design, str | None]:
    if args.preset is not None:
        return check_design(presets.get(args.preset).design()), args.preset
    path: Path = args.design
    if str(path) == "-":  # piped in (rehearsal 8: jq ... | clm evaluate --design - was refused)
        text = _stdin(MAX_DESIGN_BYTES)
        path = Path("<stdin>")
    elif not path.exists():
        from core.formats.files import backslash_hint

        raise CLIError(f"design file {path} not found{backslash_hint(path)}")
    elif path.is_dir() and not (path / "result.json").is_file():
        raise CLIError(f"{path} is a folder without a result.json: not a 'clm design --out' run; give a design JSON "
                       "or a run's folder")
    elif path.is_dir() or _is_run(path):  # a `clm design` run (its folder or result.json): its final pick
        return run_pick(path / "result.json" if path.is_dir() else path), None
    else:
        text = read_user_file(path, MAX_DESIGN_BYTES, "design file")
    if not text.strip():  # read "Expecting value at line 1 column 1" (lab rehearsal: a '> my.json' that failed)
        raise CLIError(f"{path} is empty: not a design JSON")
    try:
        data = json.loads(text, object_pairs_hook=unique_keys)
    except json.JSONDecodeError as e:
        raise CLIError(f"{path}: not valid JSON: {json_message(e)}") from None
    except RecursionError:
        raise CLIError(f"{path}: not a design: nested too deep") from None
    except ValueError as e:  # unique_keys
        raise CLIError(f"{path}: {e}") from None
    try:
        return design_from_dict(data), None
    except ValueError as e:
        raise CLIError(f"{path}: {e}") from None


def json_message(e: json.JSONDecodeError) -> str:
    """Where and what, in words: "Unterminated string starting at" read "... at at line 17" (lab rehearsal); a
    decimal comma ("r4": 128,33) and a trailing comma ({"r4": 128,}) are said to be one."""
    hint = ""
    if e.doc[:e.pos].rstrip().endswith(",") and e.doc[e.pos:e.pos + 1] in ("}", "]"):
        hint = " (a trailing comma? JSON takes none after the last item)"
    elif e.msg.startswith("Expecting property name") and e.pos > 0 and e.doc[e.pos - 1:e.pos] == "," \
            and e.doc[e.pos:e.pos + 1].isdigit():  # digits on both sides of the comma
        before = e.doc[max(0, e.pos - 12):e.pos - 1].rstrip()
        if before[-1:].isdigit():
            hint = " (a decimal comma? JSON numbers take '.': 128.33)"
    return f"{e.msg.removesuffix(' at')} at line {e.lineno} column {e.colno}{hint}"


def _stdin(max_bytes: int) -> str:
    """A design JSON piped in, at most ``max_bytes`` as a file may have; CLIError otherwise."""
    if sys.stdin is None or sys.stdin.isatty():
        raise CLIError("--design -: nothing is piped in (give a design JSON on standard input, or a file)")
    data = sys.stdin.buffer.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise CLIError(f"--design -: more than the {max_bytes / 2**20:.0f} MB a design file may have")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise CLIError("--design -: not UTF-8 text") from None


def _is_run(path: Path) -> bool:
    """Whether a file begins as a ``clm design`` result.json does (its format first)."""
    from core.optimize.run import RESULT_FORMAT

    if not path.is_file():  # a FIFO would block the open (read_user_file refuses it, below)
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(256)
    except OSError:
        return False
    return f'"{RESULT_FORMAT}"'.encode() in head


def run_pick(path: Path) -> Design:
    """The final pick of a ``clm design`` run (its ``result.json``, or the folder holding it): the design the run
    chose, as ``--design`` takes it (a designer evaluates, simulates and draws it; there was no way to but
    writing its design JSON by hand)."""
    from core.formats.files import read_design_result
    from core.optimize.pipeline import Pipeline

    try:
        data = read_design_result(path)
        pipe = data.get("pipeline")
        if not isinstance(pipe, dict):
            raise ValueError(f"{path}: a baseline run ({data.get('method', '?')}) holds no population to pick from; "
                             "its design is in the run's rows")
        picked = [r for r in Pipeline.from_dict(pipe).lineage if r.picked is not None]
        if not picked:
            raise ValueError(f"{path}: the run picked no design (status {data.get('status', '?')})")
        last = picked[-1]
        if last.status == "cancelled":  # stopped by Ctrl-C: its rule's pick among the population it reached
            print(f"clm: note: {path}: the run was stopped during {last.name} (generation {last.generation}); its "
                  "pick is that stage's rule among the population it reached", file=sys.stderr)
        return check_design(last.pick())
    except (KeyError, TypeError) as e:
        raise CLIError(f"{path}: not a readable 'clm design' result ({type(e).__name__}: {e})") from None
    except ValueError as e:
        raise CLIError(str(e)) from None


def run_h4(path: Path | None) -> float | None:
    """The h4 target (mm) a ``clm design`` run of the RTCLM drove to (its rtclm2 stage's ``h4_target``), or None
    (not a run, not the RTCLM's, unreadable, piped in: the caller then names the cases' targets)."""
    if path is None or str(path) == "-" or not (path.is_dir() or _is_run(path)):  # "-": stdin, not a file named so
        return None
    from core.formats.files import read_design_result

    try:
        stages = read_design_result(path / "result.json" if path.is_dir() else path)["pipeline"]["stages"]
        targets = [s["problem"]["options"].get("h4_target") for s in stages if s["problem"]["name"] == "rtclm2"]
    except (KeyError, TypeError, ValueError, OSError):
        return None
    return float(targets[-1]) if targets and isinstance(targets[-1], (int, float)) else None


def run_target(path: Path | None) -> str | None:
    """The shape target a ``clm design`` run's last stage measured against (its problem's ``target`` option), when
    it is not the default cycloid; None otherwise (not a run, the RTCLM's heights, unreadable)."""
    if path is None or str(path) == "-" or not (path.is_dir() or _is_run(path)):
        return None
    from core.analysis.targets import cycloid_params
    from core.formats.files import read_design_result

    try:
        stages = read_design_result(path / "result.json" if path.is_dir() else path)["pipeline"]["stages"]
        targets = [s["problem"]["options"].get("target") for s in stages]
    except (KeyError, TypeError, ValueError, OSError):
        return None
    target = next((t for t in reversed(targets) if isinstance(t, str)), None)
    if target is None:
        return None
    try:
        if target.split(":", 1)[0] == "cycloid" and cycloid_params(target) == cycloid_params("cycloid"):
            return None
    except ValueError:
        return None
    return target


def extent(points: np.ndarray) -> dict[str, float | None]:
    """Bounding box of a ``(n_samples, 2)`` path over its finite samples (mm); None if there are none."""
    ok = np.isfinite(points).all(axis=-1)
    if not ok.any():
        return {"width": None, "height": None, "x_min": None, "x_max": None, "y_min": None, "y_max": None}
    lo, hi = points[ok].min(axis=0), points[ok].max(axis=0)
    return {
        "width": float(hi[0] - lo[0]),
        "height": float(hi[1] - lo[1]),
        "x_min": float(lo[0]),
        "x_max": float(hi[0]),
        "y_min": float(lo[1]),
        "y_max": float(hi[1]),
    }


def solution_dict(design: Design, sol: Solution, preset: str | None) -> dict[str, Any]:
    """Member 0 of a solution as a JSON-ready dict; summary keys first, then the per-sample arrays."""
    assert sol.joints is not None and sol.dpoint is not None and sol.dleg is not None
    return {
        "mechanism": design.mechanism.name,
        "preset": preset,
        "params": design.named(0),
        "units": {p.name: p.unit for p in design.mechanism.params},
        "output": design.output.to_dict(),
        "n_samples": int(sol.theta.shape[0]),
        "feasible": bool(sol.feasible[0]),
        "violation": float(sol.violation[0]),
        "crank_margin": float(sol.crank_margin[0]),
        "dyad_names": list(sol.dyad_names),
        "dyad_margin": sol.dyad_margin[0],
        "mu_min": sol.mu_min[0],
        "mu_max": sol.mu_max[0],
        "extent_design": extent(sol.point[0]),
        "extent_leg": extent(sol.leg[0]),
        "joint_names": list(sol.joint_names),
        "theta": sol.theta,
        "valid": sol.valid[0],
        "point_design": sol.point[0],
        "point_leg": sol.leg[0],
        "dpoint_design": sol.dpoint[0],
        "dpoint_leg": sol.dleg[0],
        "joints": sol.joints[0],
    }


def why_not(sol: Solution, design: Design | None = None) -> list[str]:
    """Plain reasons why member 0 does not assemble over the whole revolution (with its ``design``, also a coupling
    that has no solution: RTCLM's switching state)."""
    reasons = []
    if design is not None and design.mechanism.derive is not None:
        _, short = design.mechanism.internal(design.params[:1])
        if np.isfinite(short[0]) and short[0] > 0:
            reasons.append(f"{design.mechanism.derive_failure} (short by {short[0]:.3g} mm)")
    if np.isfinite(sol.crank_margin[0]) and sol.crank_margin[0] < 0:
        reasons.append(f"the crank cannot turn fully (short by {-sol.crank_margin[0]:.3g} mm)")
    for name, m in zip(sol.dyad_names, sol.dyad_margin[0], strict=True):
        if np.isfinite(m) and m < 0:
            reasons.append(f"dyad {name} cannot close (short by {-m:.3g} mm)")
    n_bad = int((~sol.valid[0]).sum())
    if n_bad:
        reasons.append(f"{n_bad} of {sol.valid.shape[1]} samples unplaced")
    return reasons or ["degenerate geometry"]


def summary(design: Design, sol: Solution, label: str) -> str:
    m = design.mechanism
    o = design.output
    out = "identity output" if o.is_identity else f"output {o.describe()}"
    lines = [f"{label}: {m.title} ({m.name}, {m.n_params} parameters), {out}"]
    n = sol.theta.shape[0]
    if sol.feasible[0]:
        lines.append(f"assembles over the whole revolution ({n} sample{'s' if n != 1 else ''}), violation 0")
    else:
        lines.append(f"does not assemble: {'; '.join(why_not(sol, design))}; violation {sol.violation[0]:.4g}")
    for frame, pts in (("design", sol.point[0]), ("leg", sol.leg[0])):
        e = extent(pts)
        if e["width"] is None:
            lines.append(f"path ({frame} frame): no placed samples")
        else:
            lines.append(
                f"path ({frame} frame): width {e['width']:.2f} mm, height {e['height']:.2f} mm, "
                f"x {e['x_min']:.2f}..{e['x_max']:.2f}, y {e['y_min']:.2f}..{e['y_max']:.2f} mm"
            )
    if np.isfinite(sol.crank_margin[0]):
        lines.append(f"crank rotation margin {sol.crank_margin[0]:.2f} mm")
    for name, margin, lo, hi in zip(sol.dyad_names, sol.dyad_margin[0], sol.mu_min[0], sol.mu_max[0], strict=True):
        if np.isfinite(margin) and np.isfinite(lo) and np.isfinite(hi):
            mu = f"{np.degrees(lo):.1f}..{np.degrees(hi):.1f} deg"
            lines.append(f"dyad {name}: margin {margin:.2f} mm, transmission angle {mu}")
        elif np.isfinite(margin):
            lines.append(f"dyad {name}: margin {margin:.2f} mm, never closes (no transmission angle)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if not MIN_SAMPLES <= args.samples <= MAX_SAMPLES:  # one or two samples are no "whole revolution"
        raise CLIError(f"--samples must be between {MIN_SAMPLES} and {MAX_SAMPLES}, got {args.samples}")
    design, preset = load_design(args)
    sol = design.solve(args.samples, backend=args.backend)
    warn_units(design, design_label(args, preset), sol)
    print(dumps(solution_dict(design, sol, preset)) if args.json else summary(design, sol, design_label(args, preset)))
    return 0
