"""Rows of the Metrics panel and the bench-trajectory annotations, as plain data.

The paper's metrics come from ``core.analysis.evaluate`` (feature points, h_s, S, I, theta1, theta2, l_s,
h_m, h_bar, psi2, psi4, shape error, feasibility); the kinematic facts (crank and assembly
margins, transmission angle) from the solver's :class:`core.kinematics.solver.Solution`. A
:class:`Row` is one line of the table with a stable key; tests and later layers address rows
by key.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from core.analysis.clearance import Clearance
from core.analysis.evaluate import (
    CONSTRAINT_TEXT,
    DEFAULT_OBSTACLE,
    Evaluation,
    evaluate_paths,
    gait_verdict,
    why_infeasible,
)
from core.analysis.features import FEATURE_NAMES
from core.analysis.gait import DEFAULT_TRUNK
from core.analysis.targets import Target
from core.kinematics.solver import DEAD_POINT_RISK, MU_DEAD, MU_USUAL, Solution, worst_transmission
from studio.spots import clusters
from studio.tables import INSET

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Row:
    """One metric of one design.

    Attributes:
        key: stable identifier (``h_s``).
        label: name shown to the designer.
        value: a number, a bool (yes/no facts), a short text, or None when not available.
        unit: unit shown after the value (``mm``, ``deg``, ``%``), or ``""``.
        digits: decimals shown.
        note: short explanation (definition, or why not feasible); shown as a tooltip.
        warn: what is wrong with the value for a leg that is to be built ("" if nothing): the row is marked.
        severe: the warning is about a dead point (marked red, and said above the table), not a weak value.
        undefined: why the value is not a figure of this leg ("" if it is): a gait number of a path that does not
            walk (no single landing/take-off pair), the RTCLM's shape error against a curve its stages do not use;
            shown dimmed with the reason first in its tooltip.
    """

    key: str
    label: str
    value: float | bool | str | None
    unit: str = ""
    digits: int = 2
    note: str = ""
    warn: str = ""
    severe: bool = False
    undefined: str = ""

    def text(self) -> str:
        """The value as shown: ``yes``/``no``, ``-`` for missing, ``none`` for +inf."""
        v = self.value
        if v is None:
            return "-"
        if isinstance(v, bool):
            return "yes" if v else "no"
        if isinstance(v, str):
            return v
        if math.isnan(v):
            return "NaN"
        if math.isinf(v):
            return "none" if v > 0 else "-inf"
        return f"{v:.{self.digits}f}"


def evaluate_solution(solution: Solution, target: Target, period: float,
                      obstacle: tuple[float, float] = DEFAULT_OBSTACLE, trunk: float = DEFAULT_TRUNK) -> Evaluation:
    """Every paper metric of a solved population, via ``core.analysis.evaluate`` (crank period ``period``, s), with
    the walking view's obstacle and quadruped ``trunk`` (mm; psi4 was always the 450 mm trunk's while the view
    drew the one set, a Jansen leg's 102 mm: 41.3 % shown for 10.0 %; QA session 38).

    A target without a time law (a curve of points only) is compared at the best cyclic shift.
    """
    return evaluate_paths(solution.point, solution.leg, solution.dleg, solution.violation, target=target,
                          period=period, obstacle=obstacle, trunk=trunk, phase_optimal=not target.has_time)


def shape_error(ev: Evaluation, i: int = 0) -> float:
    """The MSE row: time-aligned, or at the best cyclic shift when that was computed (untimed target)."""
    phase = float(ev.mse_phase[i])
    return phase if np.isfinite(phase) else float(ev.mse[i])


def min_transmission_angle(solution: Solution, i: int = 0) -> float:
    """Worst transmission angle over the cycle and every dyad: ``min(mu, pi - mu)`` (rad), NaN if none (core's
    ``worst_transmission``, the metric ``transmission`` a pick can require, in degrees there)."""
    return float(worst_transmission(solution.mu_min[i : i + 1], solution.mu_max[i : i + 1])[0])


def gait_text(ev: Evaluation, i: int = 0) -> tuple[str, str]:
    """The Gait constraints row of member i: ``("1 unmet", "landing angle theta1 >= 15 deg")``, ``"all met"``, or
    ``"5 not defined"`` where there is no bench trajectory to measure them on (core's ``gait_verdict``, which
    ``clm evaluate`` reads too)."""
    unmet, undefined = gait_verdict(ev.constraints[i])
    said = ([f"{len(unmet)} unmet"] if unmet else []) + ([f"{len(undefined)} not defined"] if undefined else [])
    note = "; ".join(CONSTRAINT_TEXT[n] for n in unmet)
    if undefined:
        note += ("; " if note else "") + f"not defined ({', '.join(undefined)}): no well-defined bench trajectory"
    return ("; ".join(said) or "all met"), (note or "Eq. 30-31 all met")


MARGIN_SHARE = 0.01  # a crank or dyad margin under this share of the path width comes close to a dead point


def motion_warnings(mu: float, crank: float, dyad: float, width: float) -> dict[str, tuple[str, bool]]:
    """Per Metrics row key, a warning about how the linkage moves and whether it is severe (a dead point): the
    worst transmission angle ``mu`` (deg) under 10 or 40, the crank and dyad margins (mm) under 1 % of the path
    ``width`` (mm). Nothing for undefined values (a design that does not assemble says so elsewhere)."""
    out: dict[str, tuple[str, bool]] = {}
    if math.isfinite(mu) and mu < MU_DEAD:
        out["mu_min"] = (f"close to a dead point (under {MU_DEAD:g} deg): {DEAD_POINT_RISK}", True)
    elif math.isfinite(mu) and mu < MU_USUAL:
        out["mu_min"] = (f"below the usual {MU_USUAL:g} deg: the linkage transmits force poorly there", False)
    room = MARGIN_SHARE * width if math.isfinite(width) and width > 0 else 0.0
    for key, v, what in (("crank_margin", crank, "the crank"), ("dyad_margin", dyad, "a dyad")):
        if math.isfinite(v) and 0.0 <= v < room:
            out[key] = (f"{what} comes within {v:.2f} mm of a dead point (under 1 % of the path width)", False)
    return out


def clearance_rows(c: Clearance | None, i: int = 0) -> tuple[Row, ...]:
    """The ground clearance row (none where the leg frame is a pantograph's, whose bars are not modelled): red, and
    said above the table, when a joint goes below the ground the foot stands on."""
    if c is None:
        return ()
    j = c.lowest(i)
    value = float(c.height[i, j]) if j >= 0 else None
    note = (f"how far the lowest point after the foot ({c.names[j]}) stays above the ground the foot stands on"
            if j >= 0 else "not defined: the design does not assemble")
    warn = c.text(i) if c.warning(i) else ""  # the lowest joint named first: the value is its own
    return (Row("clearance", "Ground clearance", value, "mm", 1, note=note, warn=warn, severe=bool(warn)),)


def other_mode_row(title: str, solution: Solution, ev: Evaluation, clearance: Clearance, stance_shift: float,
                   i: int = 0, height: tuple[str, float] | None = None) -> Row:
    """The RTCLM's other mode in one row (``title``: "Auxiliary mode"): whether it moves, its crossing height
    (``height``: its name and target, ``("h4", 220.0)``), worst transmission angle, ground clearance and how far
    its stance level lies from this mode's (``stance_shift``, mm, > 0: lower), marked like the rows of this mode
    when it does not assemble, is near a dead point or strikes the ground (rehearsal 5: the studio's opening
    RTCLM looked clean in the primary mode and was 5.6 deg from a dead point in the auxiliary one; rehearsal 6:
    a design loaded from a study's RTCLM case showed h6 and not the h4 it was judged on)."""
    if solution.violation[i] != 0.0:
        return Row("other_mode", title, "does not assemble", note=why_infeasible(ev, i) or "",
                   warn="the leg's other mode does not assemble: it cannot switch", severe=True)
    mu = math.degrees(min_transmission_angle(solution, i))
    if not math.isfinite(stance_shift):  # this mode has no stance to compare with (it does not assemble)
        shift = "stance not comparable"
    elif abs(stance_shift) >= 0.5:
        shift = f"stance {abs(stance_shift):.0f} mm {'lower' if stance_shift > 0 else 'higher'}"
    else:
        shift = "stance level the same"
    h_m = float(ev.h_m[i])
    said = f"{height[0]} {h_m:.1f} mm, " if height is not None and math.isfinite(h_m) else ""
    value = f"{said}μ {mu:.1f}°, clearance {float(clearance.value[i]):.0f} mm, {shift}"
    target = (f"{height[0]} {h_m:.2f} mm (target {height[1]:g}, off by {abs(h_m - height[1]):.3g}); "
              if said and height is not None else "")
    note = f"{title}: {target}worst transmission angle {mu:.1f} deg; ground clearance {clearance.text(i)}"
    if math.isfinite(stance_shift):
        note += (f"; its stance level lies {abs(stance_shift):.1f} mm {'below' if stance_shift > 0 else 'above'} this "
                 f"mode's, so the trunk {'rises' if stance_shift > 0 else 'drops'} by that much when the leg switches")
    warn, severe = clearance.warning(i), bool(clearance.warning(i))
    if not warn:
        crank = float(solution.crank_margin[i])
        warn, severe = motion_warnings(mu, crank, math.inf, math.inf).get("mu_min", ("", False))
    return Row("other_mode", title, value, note=note, warn=warn, severe=severe)


# The rows read from the stance and the swing: numbers of a gait only when the path walks.
GAIT_KEYS = frozenset({"h_s", "S", "S_paper", "I", "theta1", "theta2", "l_s", "h_m", "h_bar", "psi2", "psi4", "gait"})


def metric_rows(solution: Solution, ev: Evaluation, i: int = 0,
                height: tuple[str, float] | None = None, stride: float | None = None,
                extra: tuple[Row, ...] = ()) -> tuple[Row, ...]:
    """The Metrics table of member i: the paper's metrics, then the kinematic facts, then ``extra`` (the ground
    clearance, the RTCLM's other mode). ``height``: the RTCLM mode's name for h_m and its target (``("h6",
    50.0)``), which the crossing-height row then names. ``stride``: the target cycloid's L when it is the paper's
    300 mm, for S as Appendix B prints it (h_s / 300 mm)."""
    deg = math.degrees
    h_m = float(ev.h_m[i])
    h_label, h_note = "Crossing height hₘ", "max swing height, walking trajectory"
    if height is not None:
        name, goal = height
        h_label = f"{name} (crossing height hₘ)"
        h_note = f"the RTCLM's {name}: target {goal:g} mm, off by {abs(h_m - goal):.3g} mm (Target panel)"
    gait, gait_note = gait_text(ev, i)
    why = why_infeasible(ev, i)
    margin = solution.dyad_margin[i]
    margin = margin[np.isfinite(margin)]
    crank, dyad = float(solution.crank_margin[i]), float(margin.min()) if len(margin) else math.nan
    # Undefined where a dyad cannot close: it read 0.0 deg, unmarked, for a design that does not assemble.
    mu = deg(min_transmission_angle(solution, i)) if solution.violation[i] == 0 else math.nan
    warns = motion_warnings(mu, crank, dyad, float(ev.width[i])) if solution.violation[i] == 0 else {}
    rows = (
        # Not "Feasible": beside "Gait constraints: 1 unmet" on the paper's X3 it read as a contradiction.
        Row("feasible", "Assembles and walks", bool(ev.feasible[i]), note=why or "assembles; one landing and take-off"),
        Row("why", "Why not", why or "-", note="reason the bench trajectory is not well defined"),
        # The RTCLM's is dimmed: 196 mm in the auxiliary mode was the largest number on a projector (rehearsal 7).
        Row("mse", "MSE (shape error)", shape_error(ev, i), "mm",
            note="mean distance to the target, sample against sample (design frame)" if height is None else
            "against the Target panel's curve, which the RTCLM stages do not use (they drive h6 and h4)",
            undefined="" if height is None else "not one of the RTCLM's figures"),
        Row("h_s", "Body fluctuation hₛ", float(ev.h_s[i]), "mm", note="max - min of y over the stance"),
        Row("S", "Straightness S", float(ev.S[i]), "%", note="h_s / l_s"),
        *((Row("S_paper", "S as in Appendix B", 100.0 * float(ev.h_s[i]) / stride, "%",
               note=f"h_s / {stride:g} mm, the target's stride: the paper's S (Appendix B prints 1.93 % for X3; its "
                    "rounded parameters give 1.95 % here); S above divides by this design's own stance length "
                    "l_s"),) if stride else ()),
        Row("I", "Impact I", float(ev.I[i]), "mm/s", note="|dy/dt| sin(theta1) at landing"),
        Row("theta1", "Landing angle θ₁", deg(float(ev.theta1[i])), "deg", 1),
        Row("theta2", "Take-off angle θ₂", deg(float(ev.theta2[i])), "deg", 1),
        Row("l_s", "Stance length lₛ", float(ev.l_s[i]), "mm"),
        Row("h_m", h_label, h_m, "mm", note=h_note),
        Row("h_bar", "Mean swing height h̄", float(ev.h_bar[i]), "mm"),
        Row("psi2", f"ψ₂({ev.obstacle[0]:g}, {ev.obstacle[1]:g})", 100.0 * float(ev.psi2[i]), "%", 1,
            note="obstacle crossing probability, biped module"),
        Row("psi4", f"ψ₄({ev.obstacle[0]:g}, {ev.obstacle[1]:g})", 100.0 * float(ev.psi4[i]), "%", 1,
            note="obstacle crossing probability, quadruped"),
        Row("width", "Path width l", float(ev.width[i]), "mm", note="x_max - x_min, design frame"),
        Row("y_min", "Lowest path y", float(ev.y_min[i]), "mm", note="lowest point, design frame (target: -H)"),
        Row("gait", "Gait constraints", gait, note=gait_note),
        Row("violation", "Assembly violation", float(solution.violation[i]), "mm",
            note="assembly shortfall, 0 if it assembles"),
        Row("crank_margin", "Crank margin", crank, "mm", note="> 0: the crank turns fully",
            warn=warns.get("crank_margin", ("", False))[0]),
        Row("dyad_margin", "Assembly margin", dyad, "mm", note="closest approach of any dyad to its stretched/folded "
            "limit", warn=warns.get("dyad_margin", ("", False))[0]),
        # "-", not "NaN", where it does not turn fully: at the ends of its assembled range a dyad is at a dead point
        # (0 deg), which the violation rows say (QA, session 38).
        Row("mu_min", "Min transmission angle μ", mu if solution.violation[i] == 0 else None, "deg", 1,
            note="min over dyads and cycle of min(mu, 180 - mu)", warn=warns.get("mu_min", ("", False))[0],
            severe=warns.get("mu_min", ("", False))[1],
            undefined="" if solution.violation[i] == 0 else "not defined: it does not assemble over the whole cycle"),
        *extra,
    )
    if solution.violation[i] == 0 and not ev.feasible[i]:
        # It assembles but does not walk: the stance these come from is not one (a paper preset read I = 387 mm/s
        # as a property of the leg; rehearsal 7).
        why_not = f"not defined: {why or 'the path does not walk'}"
        rows = tuple(replace(r, undefined=why_not) if r.key in GAIT_KEYS else r for r in rows)
    return rows


def stance_mask(ev: Evaluation, n_samples: int, i: int = 0) -> NDArray[np.bool_] | None:
    """``(n_samples,)`` True on the stance half-cycle [t1, t2] (cyclic), or None without feature points."""
    t1, t2 = ev.times[i, 0], ev.times[i, 1]
    if not (ev.feasible[i] and np.isfinite(t1) and np.isfinite(t2)):
        return None
    q1, q2 = t1 * n_samples / ev.period, t2 * n_samples / ev.period
    span = (q2 - q1) % n_samples
    return np.asarray((np.arange(n_samples) - q1) % n_samples <= span)


MERGE = 0.04  # feature points closer than this fraction of their spread share one label (``t1=t4``)
SAME = 0.005  # ... and are said to coincide (``=``) when closer than this one; else they are listed (``t2,t3``)


def feature_labels(ev: Evaluation, i: int = 0, tol: float | None = None) -> tuple[tuple[str, tuple[float, float]], ...]:
    """Feature points t1 ... t8 of member i as ``(label, (x, y))``; points that would print over each other
    share one label at the first one: closer than ``tol`` mm, by default ``MERGE`` of the points' spread. Those
    that coincide (within ``SAME`` of the spread) are joined by ``=`` (``t6=t7=t8`` for a single-peak swing,
    ``t1=t4`` when the stance starts where it is lowest), the others listed (``t2=t5,t3``: QA, session 38, Klann's
    "t2=t3=t5" hid that t3, the lowest point, is 2.2 mm below t2). Empty without feature points."""
    if not ev.feasible[i]:
        return ()
    pts = np.asarray(ev.points[i], dtype=np.float64)
    finite = pts[np.isfinite(pts).all(axis=1)]
    spread = float(np.ptp(finite, axis=0).max()) if len(finite) else 0.0
    if tol is None:
        tol = max(MERGE * spread, 1e-6)
    same = min(tol, max(SAME * spread, 1e-6))
    named = [(name, (float(p[0]), float(p[1]))) for name, p in zip(FEATURE_NAMES, ev.points[i], strict=True)
             if np.isfinite(p).all()]
    xy = [q for _, q in named]
    return tuple((listed([named[k] for k in g], same), xy[g[0]]) for g in clusters(xy, tol))


def listed(members: list[tuple[str, tuple[float, float]]], same: float) -> str:
    """Names at points: those within ``same`` mm of an earlier one joined to it by ``=``, the groups by ``,``."""
    return ",".join("=".join(members[k][0] for k in g) for g in clusters([q for _, q in members], same))


def metrics_html(rows: tuple[Row, ...]) -> str:
    """The table as HTML; each row carries ``data-key`` and its value cell ``data-value`` for tests. A row with a
    warning is marked (amber, red for a dead point; ``data-warn``) with the warning first in its tooltip, and a
    dead point is said in a line above the table."""
    cells = []
    for r in rows:
        color = ("#b91c1c" if r.severe else "#b45309") if r.warn else ""
        mark = f' data-warn="{"severe" if r.severe else "weak"}" style="color:{color}"' if r.warn else ""
        if r.undefined and not r.warn:
            mark = ' data-undefined="1" style="opacity:0.45"'
        title = f"⚠ {r.warn}. {r.note}" if r.warn else r.note
        title = f"{r.undefined}. {title}" if r.undefined else title
        cells.append(
            f'<tr data-key="{html.escape(r.key, quote=True)}"{mark} title="{html.escape(title, quote=True)}">'
            f'<td style="padding:1px 8px 1px 0">{"⚠ " if r.warn else ""}{html.escape(r.label)}</td>'
            f'<td data-value="{html.escape(r.text(), quote=True)}" style="text-align:right;'
            f'font-variant-numeric:tabular-nums;padding:1px 4px">{html.escape(r.text())}</td>'
            f'<td style="opacity:0.7">{html.escape(r.unit)}</td></tr>'
        )
    dead = [r for r in rows if r.severe]
    banner = "".join(
        f'<div class="clm-dead-point" style="color:#b91c1c;font-size:0.85em;padding:2px 0">⚠ {html.escape(r.label)} '
        f"{html.escape(r.text())}{' ' + html.escape(r.unit) if r.unit else ''}: {html.escape(r.warn)}.</div>"
        for r in dead)
    return (
        banner + f'<table class="clm-metrics" style="{INSET};font-size:0.85em">' + "".join(cells) + "</table>"
    )
