"""``clm evaluate``: every performance metric of one design or curve (paper §2, spec §3-5)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from core import CODE_DIGEST
from core.analysis.clearance import ground_clearance, rigid
from core.analysis.evaluate import (
    CONSTRAINT_NAMES,
    CONSTRAINT_TEXT,
    CONSTRAINT_UNITS,
    DEFAULT_OBSTACLE,
    MIN_SAMPLES,
    RECORD_UNITS,
    Evaluation,
    evaluate,
    evaluate_paths,
    gait_verdict,
    why_infeasible,
)
from core.analysis.features import DEFAULT_PERIOD, FEATURE_NAMES
from core.analysis.gait import DEFAULT_TRUNK
from core.analysis.targets import cycloid_params, load_curve, parse_target, path_note, scale_note
from core.cli import CLIError, dumps, path_arg
from core.kinematics.checks import MAX_SAMPLES
from core.kinematics.presets import PAPER_PANTOGRAPH
from core.kinematics.solver import MU_DEAD, MU_USUAL


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="every performance metric of a design or a curve",
        description="Feature points, body fluctuation, impact, obstacle crossing and shape error of one "
        "design (a preset or a design JSON file) or of a closed curve from a CSV file (see docs/metrics.md).",
    )
    from core.cli.simulate import add_source

    src = add_source(p)
    src.add_argument("--curve", metavar="FILE", type=path_arg, help="a CSV curve: x,y or x,y,t per line (design frame)")
    p.add_argument(
        "--leg-frame",
        action="store_true",
        help="the --curve, and a --target CSV, are foot paths in the leg frame, as the bench view draws them (stance "
        "at the bottom): mapped to the design frame by the design's output stage (a --curve: by the paper's "
        "pantograph); default: both in the design frame",
    )
    p.add_argument("--target", metavar="SPEC", help="cycloid[:L=300,H=100,T=2] (default) or a CSV curve")
    p.add_argument("--obstacle", nargs=2, type=float, metavar=("A", "B"), default=list(DEFAULT_OBSTACLE),
                   help="obstacle length and height for psi (mm, default 25 25)")
    p.add_argument("--trunk", type=float, default=DEFAULT_TRUNK,
                   help=f"quadruped hip distance (mm, default {DEFAULT_TRUNK:g})")
    p.add_argument("--period", type=float, default=None,
                   help=f"crank period T (s); default the time law's: a --curve's own times, else the target's T "
                   f"(cycloid T, a CSV target's times), as the optimizer takes it; else {DEFAULT_PERIOD:g}")
    p.add_argument("--samples", type=int, default=360, metavar="N", help="samples per revolution, even (default 360)")
    p.add_argument("--phase-optimal", action="store_true",
                   help="also report the shape error at the best cyclic shift (always for a target without times)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--backend", choices=("numpy", "numba", "auto"), default="numpy",
                   help="solver; numpy (default) needs no compilation, which suits one design")
    from core.cli.simulate import add_mode

    add_mode(p)
    p.set_defaults(func=run)


def _check(args: argparse.Namespace) -> None:
    if not MIN_SAMPLES <= args.samples <= MAX_SAMPLES or args.samples % 2:
        raise CLIError(f"--samples must be an even number between {MIN_SAMPLES} and {MAX_SAMPLES} (take-off is "
                       f"landing + T/2, which must fall on a sample), got {args.samples}")
    if args.period is not None and not (math.isfinite(args.period) and args.period > 0):
        raise CLIError(f"--period must be a positive number of seconds, got {args.period}")
    a, b = args.obstacle
    if not (math.isfinite(a) and math.isfinite(b) and a >= 0 and b >= 0):
        raise CLIError(f"--obstacle needs two non-negative sizes in mm, got {a} {b}")
    if not (math.isfinite(args.trunk) and args.trunk > 0):
        raise CLIError(f"--trunk must be a positive length in mm (the quadruped's hip distance), got {args.trunk}")
    if 0.0 < max(a, b) < 1.0:  # lab rehearsal: --obstacle 0.025 0.025 (m) read psi2 99.98 % without a word
        print(f"clm: warning: --obstacle {a:g} {b:g}: an obstacle under 1 mm; its sizes are read in mm (values in m "
              "need scaling)", file=sys.stderr)


def _evaluate(args: argparse.Namespace) -> tuple[Evaluation, str, dict[str, Any]]:
    target = parse_target(args.target)
    csv_target = args.target is not None and args.target.split(":", 1)[0] != "cycloid"
    if args.curve is not None and getattr(args, "mode", None) is not None:  # ignored without a word (rehearsal 8)
        raise CLIError(f"--mode {args.mode} applies to an RTCLM design (--preset or --design); a --curve has no mode")
    if args.leg_frame and args.curve is None and not csv_target:
        raise CLIError("--leg-frame applies to a --curve or a --target CSV; the cycloid is a design-frame target")
    # A CSV in m or um, or times in ms, is read as mm and s; so is a cycloid given in them (lab rehearsal:
    # cycloid:L=0.3,H=0.1 and T=2000 passed without a word) and a --curve (review of session 31).
    note = "" if target is None or args.target is None \
        else scale_note(target.points, target.period if target.has_time else None)
    if note:
        name = args.target if not csv_target else Path(args.target).name
        print(f"clm: warning: target {name}: {note}", file=sys.stderr)
    curve = load_curve(args.curve) if args.curve is not None else None
    note = "" if curve is None else scale_note(curve.points, curve.period if curve.has_time else None)
    if note:
        print(f"clm: warning: curve {Path(args.curve).name}: {note}", file=sys.stderr)
    period = args.period
    if period is None:  # the time law's period: T = 4 in the target is the crank period the optimizer used
        own = curve if curve is not None and curve.has_time else target
        period = own.period if own.has_time else DEFAULT_PERIOD
    # A target without times is compared at the best cyclic shift, as the optimizer's f1 compares it: without that
    # row a run's pick read MSE 10.21 here against the run's 8.29.
    untimed = target is not None and not target.has_time
    kw: dict[str, Any] = dict(target=target, period=period, obstacle=tuple(args.obstacle), trunk=args.trunk,
                              phase_optimal=args.phase_optimal or untimed)
    if curve is not None:
        if args.leg_frame and csv_target:  # the file as the bench view draws it, by the same map as the curve
            target = dataclasses.replace(target, points=PAPER_PANTOGRAPH.invert(target.points))
            kw["target"] = target
        pts = curve.sample(args.samples)
        leg = pts if args.leg_frame else PAPER_PANTOGRAPH.apply(pts)
        point = PAPER_PANTOGRAPH.apply(pts) if args.leg_frame else pts
        ev = evaluate_paths(point, leg, None, None, **kw)
        info: dict[str, Any] = {"source": str(args.curve), "frame": "leg" if args.leg_frame else "design",
                "time_law": curve.has_time}
        return ev, str(args.curve), info
    from core.cli.simulate import design_label, load_design, run_target, warn_units

    design, preset = load_design(args)
    ran = run_target(getattr(args, "design", None)) if args.target is None else None
    if ran is not None:  # measured against the default cycloid without a word (rehearsal 8)
        print(f"clm: note: {args.design} was made against target {ran}; these numbers are against the default "
              f"cycloid (give --target {ran} to measure against the run's)", file=sys.stderr)
    if args.leg_frame and csv_target:  # a foot path drawn in the leg frame: back through the design's own map
        target = dataclasses.replace(target, points=design.output.invert(target.points))
        kw["target"] = target
    if target is not None and csv_target and design.mechanism.derive is None:  # the RTCLM's: heights, no curve
        note = path_note(design.output.apply(target.sample(args.samples)))
        if note:  # a curve drawn clockwise or stance up: the design may match it, and walk wrongly
            print(f"clm: warning: target {Path(args.target).name} in the design's leg frame: {note}", file=sys.stderr)
    ev = evaluate(design, args.samples, backend=args.backend, **kw)
    sol = design.solve(args.samples, derivatives=False, backend=args.backend)  # joints: the words below
    warn_units(design, design_label(args, preset), sol)
    upside_down(sol, design, design_label(args, preset))
    info = {"mechanism": design.mechanism.name, "preset": preset, "params": design.named(0),
            "output": design.output.to_dict(), "clearance_note": None}  # a key of every design's record
    if rigid(design.output):  # which joint is lowest, in words (a pantograph's bars are not modelled)
        from core.optimize.rtclm import mode_clearance

        c = mode_clearance(ground_clearance(sol, design.mechanism, design.output), design.mechanism, design.params)
        ev = dataclasses.replace(ev, clearance=c.value)  # the RTCLM's auxiliary mode: both legs' locked points
        info["clearance_note"] = c.text()
    return ev, design_label(args, preset), info


def upside_down(sol: Any, design: Any, label: str) -> None:
    """A warning on stderr when the design's own foot path stands on its swing in the leg frame (its flat part at
    the top): the paper's X3 in a design file without "output" is read with the identity and printed h_s 101 mm,
    S 35 % and "feasible" with no word (rehearsal 8). A path that only runs clockwise is not flagged: several of
    the paper's RTCLM rows walk toward -x. ``sol``: the design solved."""
    if sol.violation[0] != 0.0:
        return
    note = path_note(sol.leg[0], remedy=False)
    if "flat part is at the top" not in note:
        return
    hint = ""
    if design.mechanism.derive is None and design.output.k == 1.0:  # not the RTCLM, whose legs take no pantograph
        hint = ("; check its output stage (a design file without \"output\" is read with the identity, k = 1; the "
                "paper's legs map the foot by k = -1)")
    print(f"clm: warning: {label}: its foot path: {note}{hint}", file=sys.stderr)


def rtclm_height(mechanism: str, preset: str | None, run_h4: float | None = None) -> tuple[str, str] | None:
    """An RTCLM mode's name for h_m and its target in words (``("h6", "50 mm")``), or None for another mechanism;
    h4's target is the run's (``run_h4``: a ``clm design`` run's pick drove to it) or the case's when ``preset`` was
    made for one (``Preset.case``: ``rtclm/case3``), else the five cases'. (A regex over the label took a case from
    any path: runs/showcase2/leg.json read case 2's.)"""
    from core.kinematics import presets
    from core.optimize.rtclm import H4_CASES, H6_TARGET, MODE_HEIGHT, case_h4

    name = MODE_HEIGHT.get(mechanism)
    if name is None:
        return None
    if name == "h6":
        return name, f"{H6_TARGET:g} mm"
    if run_h4 is not None:
        return name, f"{run_h4:g} mm (the run's)"
    h4 = case_h4(preset)
    if h4 is not None:
        return name, f"{h4:g} mm (case {presets.PRESETS[str(preset)].case})"
    return name, " / ".join(f"{v:g}" for v in H4_CASES.values()) + " mm (cases 1-5)"


def papers_stride(spec: str | None) -> bool:
    """Whether a ``--target`` value is the paper's 300 mm stride, the only one whose S the paper printed as
    h_s / 300 mm: a cycloid with L = 300, read from its parameters (a CSV file is never, whatever its name)."""
    if spec is not None and spec.split(":", 1)[0] != "cycloid":
        return False
    return cycloid_params(spec or "cycloid")["L"] == 300.0


def _fmt(v: float, digits: int = 3) -> str:
    if not np.isfinite(v):
        return "n/a"
    return f"{v:.{digits}f}" if abs(v) < 1e9 else f"{v:.4g}"  # a 1e300 mm target printed 300 digits


def table(ev: Evaluation, label: str, papers: bool = False, height: tuple[str, str] | None = None,
          untimed: bool = False, clearance: str | None = None, design: bool = True) -> str:
    """A readable summary of member 0; ``papers``: also the paper's S (h_s / 300 mm), for its stride; ``height``:
    an RTCLM mode's name for h_m and its target (:func:`rtclm_height`), whose cases drive heights, not a shape;
    ``untimed``: the target has no times, so its shape error is the best phase's (the optimizer's f1), and the
    one with its first point as t = 0 comes second (it read 76.7 mm for a right target above 24 mm for the same
    target upside down); ``clearance``: the ground clearance in words (``Clearance.text``), for a design whose leg
    frame is rigid; ``design``: a design's (a curve has no transmission angle)."""
    r = ev.record(0)
    deg = math.degrees
    status = "feasible" if r["feasible"] else f"INFEASIBLE (violation {r['violation']:.4g}: {why_infeasible(ev)})"
    a, b = ev.obstacle
    rows = [
        ("stance length l_s", _fmt(r["l_s"]), "mm"),
        ("body fluctuation h_s", _fmt(r["h_s"]), "mm"),
        ("straightness S = h_s/l_s", _fmt(r["S"]), "%"),
        *([("  (h_s / 300 mm, the paper's S)", _fmt(100 * r["h_s"] / 300.0), "%")] if papers else []),
        ("impact I", _fmt(r["I"]), "mm/s"),
        ("landing angle theta1", _fmt(deg(r["theta1"]) if np.isfinite(r["theta1"]) else np.nan, 2), "deg"),
        ("take-off angle theta2", _fmt(deg(r["theta2"]) if np.isfinite(r["theta2"]) else np.nan, 2), "deg"),
        ("width (design frame)", _fmt(r["width"]), "mm"),
        ("y_min (design frame)", _fmt(r["y_min"]), "mm"),
        ("step length 2 l_s", _fmt(r["step_length"]), "mm"),
        (f"max crossing height h_m = {height[0]}" if height else "max crossing height h_m", _fmt(r["h_m"]),
         f"mm (the RTCLM's {height[0]}, target {height[1]})" if height else "mm"),
        ("mean crossing height h_bar", _fmt(r["h_bar"]), "mm"),
        (f"psi2({a:g}, {b:g})", _fmt(100 * r["psi2"], 2), "%"),
        (f"psi4({a:g}, {b:g}), trunk {ev.trunk:g} mm", _fmt(100 * r["psi4"], 2), "%"),
        ("shape error MSE", _fmt(r["mse"]), "mm" if height is None else
         "mm (against the target below; the RTCLM cases drive h6 and h4, not a shape)"),
    ]
    if untimed and height is None and np.isfinite(r["mse_phase"]):
        at_zero = rows.pop()
        rows.append(("shape error MSE, best phase", _fmt(r["mse_phase"]),
                     "mm (the target has no times: it is taken at constant speed along its length, so this includes "
                     "timing; f1 is this)"))  # a leg's own path read 21 mm against itself (lab rehearsal)
        rows.append(("shape error, its first point at t = 0", at_zero[1], "mm (no meaning without times)"))
    elif np.isfinite(r["mse_phase"]):
        rows.append(("shape error, best phase", _fmt(r["mse_phase"]), "mm"))
    if design and r["kinematic_violation"] > 0:  # a dyad cannot close: no angle
        rows.append(("worst transmission angle", "n/a", "deg (it does not assemble over the whole cycle)"))
    elif np.isfinite(r["transmission"]):  # a design's (a curve has none)
        rows.append(("worst transmission angle", _fmt(r["transmission"], 1),
                     f"deg (90 ideal, {MU_USUAL:g} the usual minimum"
                     + (f"; under {MU_DEAD:g}: close to a dead point)" if r["transmission"] < MU_DEAD else ")")))
    if clearance is not None:
        value = r["clearance"]
        rows.append(("ground clearance", _fmt(value, 1), "mm" if not np.isfinite(value) else
                     "mm (" + (clearance.partition("(")[2] or clearance + ")") if value >= 0 else
                     f"mm: {clearance}"))
    w = max(len(n) for n, _, _ in rows)
    lines = [f"{label}: {status}; T = {ev.period:g} s, {ev.n_samples} samples, target {ev.target}"]
    lines += [f"  {n:<{w}}  {v:>10}  {u}" for n, v, u in rows]
    lines.append("  feature points (leg frame):")
    for n in FEATURE_NAMES:
        fp = r["feature_points"][n]
        lines.append(f"    {n}: t = {_fmt(fp['t'], 4)} s, ({_fmt(fp['x'], 2)}, {_fmt(fp['y'], 2)}) mm")
    lines.append("  constraints (<= 0 satisfied): " + ", ".join(
        f"{n} {_fmt(v, 4)}" + ("" if u == "1" else f" {u}")  # psi2's is a fraction: no unit
        for (n, v), u in zip(r["constraints"].items(), CONSTRAINT_UNITS, strict=True)))
    unmet, undefined = gait_verdict(ev.constraints[0])
    held = "the RTCLM stages hold Eq. 30, and Eq. 31 in the auxiliary mode; the paper's §3 subtasks neither"
    said = [f"{len(unmet)} unmet: " + "; ".join(CONSTRAINT_TEXT[n] for n in unmet)] if unmet else []
    if undefined:  # no bench trajectory to measure them on (it does not assemble): not measured, so not "unmet"
        said.append(f"{len(undefined)} not defined ({', '.join(undefined)}: no well-defined bench trajectory)")
    lines.append(f"  gait constraints Eq. 30-31 ({held}): " + ("; ".join(said) if said else "all met"))
    return "\n".join(lines)


NO_TIMES = ("  the curve has no times: the foot is taken to move at constant speed along it over T, so what depends on "
            "time\n  (I, theta1, theta2, the feature points, the stance, MSE) is not a mechanism's: give x,y,t rows "
            "for those")


def run(args: argparse.Namespace) -> int:
    _check(args)
    ev, label, info = _evaluate(args)
    if args.json:
        rec = ev.record(0)
        rec["constraint_names"] = list(CONSTRAINT_NAMES)
        units = {k: v for k, v in RECORD_UNITS.items() if k in rec}
        print(dumps({**rec, **info, "units": units, "code": CODE_DIGEST}))
    else:
        from core.cli.simulate import run_h4

        height = rtclm_height(str(info.get("mechanism", "")), args.preset,
                              run_h4(getattr(args, "design", None)))
        target = parse_target(args.target) if args.target is not None else None
        text = table(ev, label, papers_stride(args.target) and height is None, height,
                     untimed=target is not None and not target.has_time, clearance=info.get("clearance_note"),
                     design="mechanism" in info)
        if info.get("time_law") is False:
            head, _, rest = text.partition("\n")
            text = f"{head}\n{NO_TIMES}\n{rest}"
        print(text)
    return 0
