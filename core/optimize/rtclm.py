"""RTCLM stepwise design (paper §4.2) as registered problems: ``rtclm1`` then ``rtclm2``.

Both evaluate a population of RTCLM design vectors (``core.kinematics.mechanisms.rtclm``, 13 entries) in
the primary mode (Watt-I six-bar driven at A, h6 = its walking-trajectory h_m) and the
auxiliary mode (four-bar E-H-F-G driven at H, h4 = its h_m). Metrics (``(pop,)``):

- ``dh6 = |h6 - h6_target|``, ``dh4 = |h4 - h4_target|`` (mm): the paper's Eq. 27 objectives as
  absolute deviations (the paper squares them; its stop threshold [0.5, 0.5] and its tables
  speak of deviations in mm, so the absolute value is the natural unit here);
- ``violation`` (primary assembly and coupling), ``aux_violation`` (auxiliary assembly): 0 when the
  mode assembles, else ``ASSEMBLY_TIER`` + the shortfall in mm (``objectives.tiered``);
- ``crank1``, ``crank2``: Eq. 29 (mm, <= 0 satisfied; crank AB, crank HF);
- ``order_6``, ``theta1_6``, ``theta2_6`` and ``order_4``, ``theta1_4``, ``theta2_4``: Eq. 30 for
  each mode (rad, <= 0 satisfied: cyclic order t1 -> t2 -> t5 -> t4, 15 degrees minus the
  landing / take-off angle);
- ``eq31_height_4``, ``eq31_psi2_4``: Eq. 31 for the auxiliary mode (``h_m / 4 - h_bar`` in mm
  and ``0.2 - psi2(25, 25)``, <= 0 satisfied);
- ``clearance_6``, ``clearance_4``: each mode's ground clearance (mm, ``core.analysis.clearance``): how far the
  leg's lowest joint but the foot stays above the ground the foot stands on; held >= ``clearance_min`` (0 by
  default) in each mode a subtask holds: our addition, not the paper's (docs/rtclm.md, "Ground clearance");
- ``h6``, ``h4``, ``mean_height_6/4``, ``psi2_6/4``, ``S_6/4``, ``I_6/4`` for reports.

Subtask 1 (``rtclm1``) drives h6 to its target: objective dh6, constraints Eqs. 29-30 of the primary mode
(assembly, crank AB turns fully, its Eq. 30); ``auxiliary=True`` adds the auxiliary mode's. Subtask 2
(``rtclm2``) drives h4: objectives (dh4, dh6), the subtask-1 result held as ``dh6 <= h6_tol``, and
Eq. 31 added (auxiliary mode), as the paper adds it in its second subtask. Stop early at
``stop_below = (0.5, 0.5)`` (paper).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from core.analysis.clearance import Clearance
from core.analysis.evaluate import Evaluation, evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, RTCLM_PRIMARY, crank_conditions, switching_state
from core.kinematics.model import Mechanism
from core.optimize.objectives import ASSEMBLY_TIER, quantize_all, tiered
from core.optimize.problem import ASSEMBLY, Constraint, Metrics, ProblemSpec, register, transmission_limits

F64 = NDArray[np.float64]

# The RTCLM's two modes (one 13-parameter leg locked two ways) and the height each one's h_m is (paper §4.2).
MODE_HEIGHT = {RTCLM_PRIMARY.name: "h6", RTCLM_AUXILIARY.name: "h4"}
H6_TARGET = 50.0  # mm, paper §4.2.3
H4_CASES = {1: 220.0, 2: 240.0, 3: 260.0, 4: 280.0, 5: 300.0}  # mm, cases 1-5
STOP = (0.5, 0.5)  # mm, the paper's early-stop threshold
# Subtask 2 holds |h6 - h6_target| <= H6_HOLD while it searches for h4; the stop rule (and the pick
# among the members that met it) then demands 0.5 mm. A hold of 0.5 mm leaves a feasible region
# so thin that subtask 2 often stalls in a pocket below the h4 target (measured: 2 of 4 runs of
# cases 1 and 5 reached it with 0.5 mm, 6 of 6 with 5 mm).
H6_HOLD = 5.0

LABELS: dict[str, str] = {
    "dh6": "|h6 - h6_t| (mm)",
    "dh4": "|h4 - h4_t| (mm)",
    "h6": "h6, primary h_m (mm)",
    "h4": "h4, auxiliary h_m (mm)",
    "crank1": "Eq. 29 crank AB (mm)",
    "crank2": "Eq. 29 crank HF (mm)",
    # Tiered (objectives.tiered), so not mm: 0 when the mode assembles with a valid path, else 1000 + the shortfall
    # (mm, and 1 per extra turn of a crossing path). "(mm)" made a case-4 preset that assembles read "1001 mm".
    "transmission_6": "primary mode's worst transmission angle (deg)",
    "transmission_4": "auxiliary mode's worst transmission angle (deg)",
    "clearance_6": "primary mode's ground clearance (mm)",
    "clearance_4": "auxiliary mode's ground clearance (mm)",
    "violation": "primary mode violation (0 ok, 1000+ not)",
    "aux_violation": "auxiliary mode violation (0 ok, 1000+ not)",
    # Eq. 30-31 by what they measure, each <= 0 when met: "order_6 ≤ 0 · theta1_6 ≤ 0" read as unfinished.
    **{f"{key}_{m}": f"Eq. {what}, {mode}{unit}"
       for m, mode in (("6", "primary"), ("4", "auxiliary"))
       for key, what, unit in (("order", "30 order t1→t2→t5→t4", " (rad)"),
                               ("theta1", "30 15° − landing angle", " (rad)"),
                               ("theta2", "30 15° − take-off angle", " (rad)"),
                               ("eq31_height", "31 h_m/4 − h̄", " (mm)"),
                               ("eq31_psi2", "31 0.2 − ψ2(25, 25)", ""))},
}


def _finite(v: F64) -> F64:
    # Eq. 29's second line is +inf where the frame EH does not exist: a large finite value instead.
    return np.where(np.isfinite(v), v, ASSEMBLY_TIER)


def mode_metrics(ev: Evaluation, suffix: str) -> Metrics:
    """Gait metrics and Eq. 30-31 values of one mode's evaluation, names ending in ``suffix``."""
    c = ev.constraints
    return {
        f"h{suffix}": ev.h_m,
        f"mean_height_{suffix}": ev.h_bar,
        f"psi2_{suffix}": ev.psi2,
        f"order_{suffix}": c[:, 0],
        f"theta1_{suffix}": c[:, 1],
        f"theta2_{suffix}": c[:, 2],
        f"eq31_height_{suffix}": c[:, 3],
        f"eq31_psi2_{suffix}": c[:, 4],
        f"S_{suffix}": ev.S,
        f"I_{suffix}": ev.I,
        f"transmission_{suffix}": ev.transmission,
        f"clearance_{suffix}": ev.clearance,
    }


# In the auxiliary mode both legs are locked in the switching state, the left half a turn on: its A, D, E, H and its
# four-bar sit at the right leg's heights, its crank tip B and rocker tip C do not (the review of session 30 found a
# design whose left B stood 7.8 mm in the ground while the right leg's clearance read 14.3 mm).
LEFT_LOCKED = ("B of the left leg", "C of the left leg")


def left_locked(params: F64) -> F64:
    """``(pop, 2)`` heights (mm, design frame) of the left leg's B and C in the switching state; NaN where there is
    no switching state."""
    st = switching_state(params)
    return np.stack([st["B"][:, 1, 1], st["C"][:, 1, 1]], axis=1)


def mode_clearance(c: Clearance, mechanism: Mechanism, params: F64) -> Clearance:
    """A mode's ground clearance of both legs: the auxiliary mode's with the left leg's locked B and C added."""
    return c.with_fixed(LEFT_LOCKED, left_locked(params)) if mechanism.name == RTCLM_AUXILIARY.name else c


def case_h4(preset: str | None) -> float | None:
    """The h4 target of the RTCLM case a preset was made for (``Preset.case``; case 3: 260 mm, paper §4.2), else
    None (no preset, or one made for no case)."""
    from core.kinematics import presets

    p = presets.PRESETS.get(preset) if preset is not None else None
    return H4_CASES.get(p.case) if p is not None and p.case is not None else None


def rtclm_metrics(params: F64, h6_target: float = H6_TARGET, h4_target: float = H4_CASES[1],
                  n_samples: int = 360, backend: str = "auto", auxiliary: bool = True) -> Metrics:
    """Every RTCLM metric of ``(pop, 13)`` design vectors (see the module doc).

    Args:
        params: design vectors r1 ... r6, x_d, y_d, a1, b1, a3, b3, phi_h (mm, rad).
        h6_target, h4_target: target crossing heights (mm).
        n_samples: crank samples per revolution.
        backend: solver backend.
        auxiliary: also evaluate the auxiliary mode (dh4 and its constraints are NaN otherwise).
    """
    params = np.atleast_2d(np.asarray(params, dtype=np.float64))
    prim = evaluate(Design(RTCLM_PRIMARY, params), n_samples, backend=backend)  # type: ignore[arg-type]
    out = mode_metrics(prim, "6")
    cranks = crank_conditions(params)
    out["crank1"] = cranks[:, 0]
    out["crank2"] = _finite(cranks[:, 1])
    out["violation"] = tiered(prim.violation)
    out["dh6"] = np.abs(prim.h_m - h6_target)
    if auxiliary:
        aux = evaluate(Design(RTCLM_AUXILIARY, params), n_samples, backend=backend)  # type: ignore[arg-type]
        out.update(mode_metrics(aux, "4"))
        # Both legs, by the one rule (``mode_clearance``): the right leg's lowest joint, the left one's locked B and C.
        right = Clearance(aux.clearance[:, None], ("right leg",), np.zeros(1, dtype=bool), aux.y_min)
        with np.errstate(invalid="ignore"):
            both = mode_clearance(right, RTCLM_AUXILIARY, params).value
        out["clearance_4"] = np.where(np.isnan(aux.clearance), np.nan, both)
        out["aux_violation"] = tiered(aux.violation)
        out["dh4"] = np.abs(aux.h_m - h4_target)
    else:
        out["dh4"] = np.full(params.shape[0], np.nan)
    return quantize_all(out)


def _eq30(suffix: str) -> tuple[Constraint, ...]:
    return tuple(Constraint(f"{n}_{suffix}", upper=0.0) for n in ("order", "theta1", "theta2"))


def _eq29_30(eq30: bool, auxiliary: bool = True) -> tuple[Constraint, ...]:
    if not auxiliary:
        return (ASSEMBLY, Constraint("crank1", upper=0.0)) + (_eq30("6") if eq30 else ())
    cons = (ASSEMBLY, Constraint("aux_violation", upper=0.0), Constraint("crank1", upper=0.0),
            Constraint("crank2", upper=0.0))
    return cons + (_eq30("6") + _eq30("4") if eq30 else ())


def clearance_limits(on: bool, minimum: float, modes: int) -> tuple[Constraint, ...]:
    """The ``clearance`` / ``clearance_min`` options: each of the first ``modes`` modes' ground clearance at
    least ``minimum`` mm (none when off); ValueError for a minimum that is not a number within +-1e6 mm."""
    if not isinstance(on, bool):
        raise ValueError(f"clearance must be true or false, got {on!r}")
    if isinstance(minimum, bool) or not isinstance(minimum, (int, float)) or not abs(minimum) <= 1e6:
        raise ValueError(f"clearance_min must be a length in mm within +-1e6, got {minimum!r}")
    return tuple(Constraint(m, lower=float(minimum)) for m in ("clearance_6", "clearance_4")[:modes]) if on else ()


def is_rtclm(mechanism: str) -> bool:
    """Whether the mechanism named is one of the RTCLM's modes."""
    return mechanism in MODE_HEIGHT


def _rtclm_only(m: Mechanism) -> str | None:
    """The RTCLM problems evaluate both modes of one 13-parameter design: the RTCLM's alone."""
    if is_rtclm(m.name):
        return None
    return "it measures the reconfigurable leg's two modes (h6 and h4), so it optimizes the RTCLM alone"


@register("rtclm1")
def rtclm1(h6_target: float = H6_TARGET, h4_target: float = H4_CASES[1], n_samples: int = 360,
           backend: str = "auto", eq30: bool = True, auxiliary: bool = False,
           transmission_min: float = 0.0, clearance: bool = True, clearance_min: float = 0.0) -> ProblemSpec:
    """RTCLM subtask 1: drive the primary-mode height h6 to its target (objective dh6).

    Args:
        auxiliary: also require the auxiliary mode to work (assembly, crank HF, its Eq. 30); by
            default subtask 1 holds only the primary mode's constraints (Eq. 29 crank AB, Eq. 30),
            which leaves subtask 2 a wider search (measured: it then reaches h4 far more often).
        transmission_min: a lower limit (deg) on the worst transmission angle of each mode it holds (0: none,
            the paper's).
        clearance, clearance_min: hold each mode's ground clearance >= clearance_min (mm): the foot is the leg's
            lowest point, so no other joint strikes the ground and the frame does not hang below the feet (our
            addition; ``clearance = false`` is the paper's problem).
    """

    def ev(design: Design) -> Metrics:
        return rtclm_metrics(design.params, h6_target, h4_target, n_samples, backend, auxiliary=auxiliary)

    angles = transmission_limits(transmission_min, ("transmission_6", "transmission_4")[: 1 + auxiliary])
    angles += clearance_limits(clearance, clearance_min, 1 + auxiliary)
    return ProblemSpec("rtclm1", ev, ("dh6",), _eq29_30(eq30, auxiliary) + angles, labels=LABELS,
                       misfit=_rtclm_only)


@register("rtclm2")
def rtclm2(h6_target: float = H6_TARGET, h4_target: float = H4_CASES[1], h6_tol: float = H6_HOLD,
           n_samples: int = 360, backend: str = "auto", eq30: bool = True, eq31: bool = True,
           transmission_min: float = 0.0, clearance: bool = True, clearance_min: float = 0.0) -> ProblemSpec:
    """RTCLM subtask 2: drive the auxiliary-mode height h4 (objectives dh4, dh6) under Eqs. 29-31.

    Args:
        h6_tol: the subtask-1 result held as a constraint, ``|h6 - h6_target| <= h6_tol`` (mm).
        transmission_min: a lower limit (deg) on both modes' worst transmission angles (0: none, the paper's).
        clearance, clearance_min: hold both modes' ground clearance >= clearance_min (mm; see ``rtclm1``).
    """

    def ev(design: Design) -> Metrics:
        return rtclm_metrics(design.params, h6_target, h4_target, n_samples, backend, auxiliary=True)

    cons = _eq29_30(eq30) + (Constraint("dh6", upper=h6_tol),)
    if eq31:
        cons += (Constraint("eq31_height_4", upper=0.0), Constraint("eq31_psi2_4", upper=0.0))
    cons += transmission_limits(transmission_min, ("transmission_6", "transmission_4"))
    cons += clearance_limits(clearance, clearance_min, 2)
    return ProblemSpec("rtclm2", ev, ("dh4", "dh6"), cons, labels=LABELS, misfit=_rtclm_only)
