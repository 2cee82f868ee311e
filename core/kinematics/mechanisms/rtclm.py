"""RTCLM: the paper's reconfigurable seven-bar leg (§4.1), in primary and auxiliary mode.

A Watt-I six-bar with a second motor at H (spec §1, docs/rtclm.md). Points, in the leg
frame with the crank pivot A at the origin:

- B = A + r1 (cos phi, sin phi); D = (x_d, y_d); C = dyad(B, D, r2, r3, +1).
- Coupler B-C carries E = B + a1 e - b1 rot90(e), e = unit(C - B) (E right of B->C).
- Rocker D-C carries the motor pivot H and, through the crank HF = r6 locked at the angle
  phi_h to the rocker, the point F: with e = unit(C - D), H = D + h_u e + h_v rot90(e) and
  F = H + r6 R(phi_h) e.
- G = dyad(E, F, r4, r5, +1); foot P = F + a3 w - b3 rot90(w), w = unit(G - F).

Primary mode (H locked): D-C-H-F is one rigid body, the Watt six-bar is driven at A.
Auxiliary mode (A locked): A, B, C, D, E, H are frame, the four-bar E-H-F-G is driven at H.

Coupling of the two legs (same dimensions, cranks pi apart): the switching state is the
right-leg crank angle Phi_r with y_E(Phi_r) = y_E(Phi_r + pi) (feet at one height); the
rocker point h = (h_u, h_v) is the unique point whose vector E->H is the same for both legs
there. So EH is derived, and the paper's 13th entry Delta x_EH is replaced by phi_h
(docs/rtclm.md shows why Delta x_EH cannot be free). Both mechanisms describe the right
leg; the left leg is the same mechanism half a crank turn later (primary mode) or the
congruent four-bar shifted along x by E^l - E^r (auxiliary mode).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.params import Param, angle, length, offset, position

F64 = NDArray[np.float64]

# Assembly branches (documented in docs/rtclm.md): C left of B->D, G left of E->F.
SIDE_C = 1
SIDE_G = 1

# Root-finding grid over half a crank turn and bisection steps (bracket 2pi/N_GRID/2^N_BISECT).
N_GRID = 96
N_BISECT = 52

PARAMS: tuple[Param, ...] = (
    length("r1", "crank AB", 30.0, 100.0),
    length("r2", "coupler BC", 50.0, 250.0),
    length("r3", "rocker DC", 50.0, 250.0),
    length("r4", "link EG", 50.0, 250.0),
    length("r5", "link GF (carries the foot)", 50.0, 250.0),
    length("r6", "crank HF (second motor at H)", 20.0, 100.0),
    position("x_d", "ground pivot D, x", -150.0, 150.0),
    position("y_d", "ground pivot D, y", -150.0, 150.0),
    offset("a1", "coupler point E, along B->C", 50.0, 350.0),
    offset("b1", "coupler point E, across B->C (to the right)", 50.0, 350.0),
    offset("a3", "foot P, along F->G", 50.0, 300.0),
    offset("b3", "foot P, across F->G (to the right)", 50.0, 300.0),
    angle("phi_h", "locked angle of crank HF from the rocker direction D->C (replaces Delta x_EH)"),
)

DERIVED: tuple[str, ...] = (
    "s_phi",  # switching-state crank angle Phi_A of the right leg (rad)
    "h_u", "h_v",  # H in the rocker frame D->C (mm)
    "f_u", "f_v",  # F in the rocker frame D->C (mm)
    "hf_phase",  # absolute angle of crank HF in the right leg's switching state (rad)
    "x_b", "y_b", "x_c", "y_c", "x_e", "y_e", "x_h", "y_h",  # right leg's switching state (mm)
    "dx_eh", "dy_eh",  # the common vector E->H of both legs (mm)
)
_COL = {n: i for i, n in enumerate(DERIVED)}


def _rot(v: F64, ang: F64) -> F64:
    c, s = np.cos(ang), np.sin(ang)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _loop_xy(params: F64, phi: F64) -> tuple[F64, F64, F64, F64, F64]:
    """Component form of :func:`first_loop` (no stacking: the grid search is its hot path)."""
    r1, r2, r3 = (params[:, i, None] for i in range(3))
    xd, yd = params[:, 6, None], params[:, 7, None]
    a1, b1 = params[:, 8, None], params[:, 9, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        bx, by = r1 * np.cos(phi), r1 * np.sin(phi)
        wx, wy = xd - bx, yd - by
        dist2 = wx * wx + wy * wy
        dist = np.sqrt(dist2)
        along = (r2 * r2 - r3 * r3 + dist2) / (2.0 * dist)
        h = SIDE_C * np.sqrt(r2 * r2 - along * along)
        cx = bx + (along * wx - h * wy) / dist
        cy = by + (along * wy + h * wx) / dist
        ux, uy = cx - bx, cy - by
        n = np.sqrt(ux * ux + uy * uy)
        ux, uy = ux / n, uy / n
        ex = bx + a1 * ux + b1 * uy
        ey = by + a1 * uy - b1 * ux
    return cx, cy, ex, ey, np.arctan2(cy - yd, cx - xd)


def first_loop(params: F64, phi: F64) -> tuple[F64, F64, F64]:
    """The first loop A-B-C-D and the coupler point E at crank angles phi.

    Args:
        params: ``(pop, 13)`` design vectors.
        phi: ``(pop, k)`` crank angles (rad).

    Returns:
        C, E: ``(pop, k, 2)`` (mm; NaN where the loop does not assemble) and the rocker
        angle psi of D->C ``(pop, k)`` (rad).
    """
    cx, cy, ex, ey, psi = _loop_xy(params, phi)
    return np.stack([cx, cy], axis=-1), np.stack([ex, ey], axis=-1), psi


COUPLING_FAILURE = "loop A-B-C-D cannot close over a whole turn of crank AB, so the legs have no switching state"


def first_loop_shortfall(params: F64) -> F64:
    """``(pop,)`` exact assembly shortfall of A-B-C-D over a whole crank turn (mm, 0 = assembles).

    |BD| sweeps [|AD - r1|, AD + r1]; the dyad B-C-D needs it inside [|r2 - r3|, r2 + r3].
    """
    r1, r2, r3 = params[:, 0], params[:, 1], params[:, 2]
    ad = np.hypot(params[:, 6], params[:, 7])
    return np.maximum(0.0, np.abs(r2 - r3) - np.abs(ad - r1)) + np.maximum(0.0, ad + r1 - r2 - r3)


def _g(params: F64, phi: F64) -> F64:
    """y_E(phi) - y_E(phi + pi), ``(pop, k)``."""
    return _loop_xy(params, phi)[3] - _loop_xy(params, phi + np.pi)[3]


@numba.njit(cache=True)
def _y_e(p: F64, phi: float) -> float:  # pragma: no cover - compiled
    # y_E of the first loop at crank angle phi, as _loop_xy computes it (NaN where it does not assemble).
    r1, r2, r3, xd, yd, a1, b1 = p[0], p[1], p[2], p[6], p[7], p[8], p[9]
    bx, by = r1 * np.cos(phi), r1 * np.sin(phi)
    wx, wy = xd - bx, yd - by
    dist2 = wx * wx + wy * wy
    dist = np.sqrt(dist2)
    along = (r2 * r2 - r3 * r3 + dist2) / (2.0 * dist)
    h = SIDE_C * np.sqrt(r2 * r2 - along * along)
    cx = bx + (along * wx - h * wy) / dist
    cy = by + (along * wy + h * wx) / dist
    ux, uy = cx - bx, cy - by
    n = np.sqrt(ux * ux + uy * uy)
    return by + a1 * (uy / n) - b1 * (ux / n)


@numba.njit(cache=True)
def _sign(x: float) -> float:  # pragma: no cover - compiled
    return 1.0 if x > 0.0 else -1.0 if x < 0.0 else 0.0 if x == 0.0 else np.nan


@numba.njit(cache=True, error_model="numpy")
def _bisect(params: F64, lo: F64, hi: F64, g_lo: F64, steps: int) -> F64:  # pragma: no cover - compiled
    # Bisection of g(phi) = y_E(phi) - y_E(phi + pi) on [lo, hi], one design at a time: the numpy loop paid
    # ~100 calls of array overhead per design, which dominated evaluating one RTCLM design (~5 ms).
    out = np.empty(lo.shape[0])
    for i in range(lo.shape[0]):
        p, a, b, ga = params[i], lo[i], hi[i], g_lo[i]
        for _ in range(steps):
            mid = 0.5 * (a + b)
            gm = _y_e(p, mid) - _y_e(p, mid + np.pi)
            if _sign(gm) == _sign(ga):
                a, ga = mid, gm
            else:
                b = mid
        out[i] = 0.5 * (a + b)
    return out


def switching_angle(params: F64) -> F64:
    """``(pop,)`` the right leg's switching crank angle Phi_A^r in [0, 2 pi) (rad), NaN if none.

    g(phi) = y_E(phi) - y_E(phi + pi) is antiperiodic, so its roots come in pairs phi0,
    phi0 + pi: one state with the legs swapped. Rules (docs/rtclm.md): among several pairs
    the crossing with the steepest grid slope; within a pair the right leg is the one with
    the smaller x_E.
    """
    pop = params.shape[0]
    grid = np.linspace(0.0, np.pi, N_GRID + 1)
    g = _g(params, np.broadcast_to(grid, (pop, N_GRID + 1)))
    with np.errstate(invalid="ignore"):
        change = (np.sign(g[:, :-1]) * np.sign(g[:, 1:]) <= 0) & np.isfinite(g[:, :-1] + g[:, 1:])
        slope = np.where(change, np.abs(g[:, 1:] - g[:, :-1]), -1.0)
    k = np.argmax(slope, axis=1)
    found = slope[np.arange(pop), k] >= 0.0
    lo, hi = grid[k].copy(), grid[k + 1].copy()
    g_lo = np.ascontiguousarray(g[np.arange(pop), k])
    with np.errstate(invalid="ignore", divide="ignore"):
        phi0 = _bisect(np.ascontiguousarray(params), lo, hi, g_lo, N_BISECT)
    _, e0, _ = first_loop(params, phi0[:, None])
    _, e1, _ = first_loop(params, phi0[:, None] + np.pi)
    phi_r = np.where(e0[:, 0, 0] <= e1[:, 0, 0], phi0, phi0 + np.pi)
    return np.where(found, phi_r, np.nan)


def switching_state(params: F64) -> dict[str, F64]:
    """Both legs in the switching state.

    Args:
        params: ``(pop, 13)`` design vectors (mm, rad).

    Returns:
        ``{"phi": (pop, 2), "A" ... "F": (pop, 2, 2), "psi": (pop, 2), "h": (pop, 2),
        "f": (pop, 2), "eh": (pop, 2)}``: leg axis 0 = right, 1 = left; crank angles
        Phi_A, points (mm), rocker angles psi (rad), H and F in the rocker frame and the
        common vector E->H (mm). NaN where no switching state exists.
    """
    params = np.atleast_2d(np.asarray(params, dtype=np.float64))
    pop = params.shape[0]
    phi_r = switching_angle(params)
    phi = np.stack([phi_r, phi_r + np.pi], axis=1)
    c, e, psi = first_loop(params, phi)
    # (R(psi_l) - R(psi_r)) h = E_l - E_r, and R(a) - R(b) = 2 sin((a-b)/2) R((a+b)/2 + pi/2).
    half = 0.5 * (psi[:, 1] - psi[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        h = _rot(e[:, 1] - e[:, 0], -(0.5 * (psi[:, 0] + psi[:, 1]) + 0.5 * np.pi)) / (2.0 * np.sin(half))[:, None]
    r6, phi_h = params[:, 5], params[:, 12]
    f = h + r6[:, None] * np.stack([np.cos(phi_h), np.sin(phi_h)], axis=-1)
    d = np.broadcast_to(params[:, None, 6:8], (pop, 2, 2))
    hh = d + _rot(np.broadcast_to(h[:, None], (pop, 2, 2)), psi)
    ff = d + _rot(np.broadcast_to(f[:, None], (pop, 2, 2)), psi)
    r1 = params[:, 0, None, None]
    b = r1 * np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    return {
        "phi": phi,
        "A": np.zeros((pop, 2, 2)),
        "B": b,
        "C": c,
        "D": d.copy(),
        "E": e,
        "H": hh,
        "F": ff,
        "psi": psi,
        "h": h,
        "f": f,
        "eh": hh[:, 0] - e[:, 0],
    }


def derive(params: F64) -> tuple[F64, F64]:
    """The coupling: design vectors -> derived values (``DERIVED``) and their violation.

    Never raises. Violation (mm) = exact shortfall of the first loop over a whole turn (then
    no switching state is guaranteed; the derived row is NaN), +inf for non-finite input,
    1e-9 in the measure-zero degenerate cases (equal rocker angles of both legs).

    Args:
        params: ``(pop, 13)``.

    Returns:
        derived ``(pop, len(DERIVED))``, violation ``(pop,)``.
    """
    params = np.atleast_2d(np.asarray(params, dtype=np.float64))
    pop = params.shape[0]
    finite = np.all(np.isfinite(params), axis=1)
    safe = np.where(finite[:, None], params, 1.0)
    short = first_loop_shortfall(safe)
    s = switching_state(safe)
    out = np.full((pop, len(DERIVED)), np.nan)
    out[:, _COL["s_phi"]] = s["phi"][:, 0]
    out[:, _COL["h_u"]], out[:, _COL["h_v"]] = s["h"][:, 0], s["h"][:, 1]
    out[:, _COL["f_u"]], out[:, _COL["f_v"]] = s["f"][:, 0], s["f"][:, 1]
    out[:, _COL["hf_phase"]] = s["psi"][:, 0] + safe[:, 12]
    for p in "bceh":
        out[:, _COL[f"x_{p}"]], out[:, _COL[f"y_{p}"]] = s[p.upper()][:, 0, 0], s[p.upper()][:, 0, 1]
    out[:, _COL["dx_eh"]], out[:, _COL["dy_eh"]] = s["eh"][:, 0], s["eh"][:, 1]
    bad = (short > 0.0) | ~finite
    out[bad] = np.nan
    viol = np.where(finite, short, np.inf)
    viol = np.where((viol == 0.0) & ~np.isfinite(out).all(axis=1), 1e-9, viol)
    return out, viol


def crank_conditions(params: F64) -> F64:
    """The paper's Eq. 29 as constraint values ``(pop, 2)`` (mm, <= 0 satisfied).

    Column 0: crank AB turns fully in A-B-C-D (r1 + 2 max(r2, r3, |AD|) - r2 - r3 - |AD|).
    Column 1: crank HF turns fully in E-H-F-G (r6 + 2 max(r4, r5, |EH|) - r4 - r5 - |EH|)
    with |EH| the derived frame length; +inf where it does not exist.
    """
    params = np.atleast_2d(np.asarray(params, dtype=np.float64))
    r1, r2, r3, r4, r5, r6 = (params[:, i] for i in range(6))
    ad = np.hypot(params[:, 6], params[:, 7])
    derived, _ = derive(params)
    eh = np.hypot(derived[:, _COL["dx_eh"]], derived[:, _COL["dy_eh"]])
    c0 = r1 + 2.0 * np.maximum(np.maximum(r2, r3), ad) - (r2 + r3 + ad)
    c1 = r6 + 2.0 * np.maximum(np.maximum(r4, r5), eh) - (r4 + r5 + eh)
    return np.stack([c0, np.where(np.isfinite(c1), c1, np.inf)], axis=1)


# The foot link is the same in both modes: dyad E-G-F, foot P on F-G.
_FOOT = (Dyad("G", "E", "F", "r4", "r5", SIDE_G), Attach("P", "F", "G", "a3", "-b3"))

RTCLM_PRIMARY = Mechanism(
    name="rtclm_primary",
    title="RTCLM, primary mode (Watt-I six-bar driven at A)",
    params=PARAMS,
    steps=(
        Ground("A", 0.0, 0.0),
        Ground("D", "x_d", "y_d"),
        Crank("B", "A", "r1", 0.0, phase="s_phi"),
        Dyad("C", "B", "D", "r2", "r3", SIDE_C),
        Attach("E", "B", "C", "a1", "-b1"),
        Attach("H", "D", "C", "h_u", "h_v"),
        Attach("F", "D", "C", "f_u", "f_v"),
        *_FOOT,
    ),
    tracked="P",
    derived=DERIVED,
    derive=derive,
    derive_failure=COUPLING_FAILURE,
    doc=(
        "Right leg, H locked: rigid rocker D-C-H-F, Watt-I six-bar driven at A; sample 0 is the "
        "switching state (crank phase Phi_A^r). The left leg is the same mechanism pi later."
    ),
    held_cranks=(("H", "F"),),
)

RTCLM_AUXILIARY = Mechanism(
    name="rtclm_auxiliary",
    title="RTCLM, auxiliary mode (four-bar E-H-F-G driven at H)",
    params=PARAMS,
    steps=(
        Ground("A", 0.0, 0.0),
        Ground("B", "x_b", "y_b"),
        Ground("C", "x_c", "y_c"),
        Ground("D", "x_d", "y_d"),
        Ground("E", "x_e", "y_e"),
        Ground("H", "x_h", "y_h"),
        Crank("F", "H", "r6", 0.0, phase="hf_phase"),
        *_FOOT,
    ),
    tracked="P",
    derived=DERIVED,
    derive=derive,
    derive_failure=COUPLING_FAILURE,
    doc=(
        "Right leg, A locked in the switching state: A, B, C, D, E, H are frame and crank HF "
        "drives the four-bar E-H-F-G; sample 0 is the switching state. The left leg's four-bar "
        "is congruent, shifted along x by E^l - E^r."
    ),
    # The primary mode's crank AB, coupler B-C-E and rocker D-C-H, held still: the same leg, locked another way.
    locked=(("A", "B"), ("B", "C", "E"), ("D", "C", "H")),
)
