"""RTCLM: the two-leg coupling (conditions (1) and (2) of spec §1), both modes, presets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from core.kinematics.mechanisms.rtclm import (
    PARAMS,
    RTCLM_AUXILIARY,
    RTCLM_PRIMARY,
    SIDE_G,
    _loop_xy,
    _y_e,
    crank_conditions,
    derive,
    first_loop,
    first_loop_shortfall,
    switching_angle,
    switching_state,
)
from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.presets.rtclm import OURS, PAPER_ROWS, PRESETS
from core.kinematics.solver import solve

N = 360
WORKING = [k for k, r in PAPER_ROWS.items() if np.isfinite(r.ours).all()]


def _h_m(y: np.ndarray) -> np.ndarray:
    """PRIVATE stand-in for core.analysis.gait's h_m until it lands (spec §5): max WT swing height.

    y: (pop, n) leg-frame heights at uniform crank angles, n even. The stance half-cycle
    [t1, t2] is the lower one of those bounded by roots of y(t) - y(t + T/2); over the swing
    the WT height above ground is y(t) - y(t - T/2).
    """
    y = np.atleast_2d(y)
    pop, n = y.shape
    half = n // 2
    out = np.full(pop, np.nan)
    for i in range(pop):
        yi = y[i]
        if not np.isfinite(yi).all():
            continue
        r = yi - np.roll(yi, -half)
        roots = np.flatnonzero(np.sign(r) != np.sign(np.roll(r, -1)))
        if roots.size == 0:
            continue
        means = [yi[(k + 1 + np.arange(half)) % n].mean() for k in roots]
        k = roots[int(np.argmin(means))]
        swing = (k + 1 + half + np.arange(half)) % n
        out[i] = (yi - np.roll(yi, half))[swing].max()
    return out


def _x(name: str) -> np.ndarray:
    return np.array([PRESETS[f"rtclm/{name}"].values])


def _dist(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    return np.linalg.norm(p - q, axis=-1)


@st.composite
def first_loop_designs(draw: st.DrawFn) -> np.ndarray:
    """Random designs whose loop A-B-C-D turns fully (the rest anywhere in the bounds)."""
    r1 = draw(st.floats(30.0, 100.0))
    r2, r3 = draw(st.floats(50.0, 250.0)), draw(st.floats(50.0, 250.0))
    lo, hi = abs(r2 - r3) + r1, r2 + r3 - r1
    assume(hi - lo > 1.0)
    ad = lo + draw(st.floats(0.01, 0.99)) * (hi - lo)
    ang = draw(st.floats(-math.pi, math.pi))
    rest = [draw(st.floats(p.lo, p.hi)) for p in PARAMS[8:]]
    lengths = [draw(st.floats(50.0, 250.0)), draw(st.floats(50.0, 250.0)), draw(st.floats(20.0, 100.0))]
    return np.array([[r1, r2, r3, *lengths, ad * math.cos(ang), ad * math.sin(ang), *rest]])


@st.composite
def working_designs(draw: st.DrawFn) -> np.ndarray:
    """Small perturbations of the presets that assemble in both modes."""
    base = _x(draw(st.sampled_from(WORKING)))[0].copy()
    base[:12] *= 1.0 + np.array([draw(st.floats(-0.01, 0.01)) for _ in range(12)])
    base[12] += draw(st.floats(-0.05, 0.05))
    return base[None]


def test_private_h_m_on_a_sine_is_twice_the_amplitude() -> None:
    theta = 2 * np.pi * np.arange(720) / 720
    # y(t) - y(t - T/2) = 2 sin: the swing reaches twice the amplitude above the landing point.
    assert _h_m(30.0 * np.sin(theta))[0] == pytest.approx(60.0, abs=1e-3)


@settings(max_examples=60, deadline=None)
@given(first_loop_designs())
def test_switching_state_puts_both_feet_at_one_height_with_one_vector_eh(x: np.ndarray) -> None:
    s = switching_state(x)
    e, h, f = s["E"][0], s["H"][0], s["F"][0]
    scale = 1.0 + np.abs(np.concatenate([e, h, f])).max()
    assert abs(e[0, 1] - e[1, 1]) <= 1e-9 * scale  # condition (1): y_E^r == y_E^l
    np.testing.assert_allclose(h[1] - e[1], h[0] - e[0], rtol=0, atol=1e-9 * scale)  # EH^l == EH^r
    np.testing.assert_allclose(s["eh"][0], h[0] - e[0], rtol=0, atol=1e-9 * scale)
    # The auxiliary four-bars E-H-F-G are congruent: same frame vector, same crank HF = r6.
    np.testing.assert_allclose(_dist(h, f), [x[0, 5], x[0, 5]], rtol=1e-12)
    assert s["phi"][0, 1] == pytest.approx(s["phi"][0, 0] + np.pi)


@settings(max_examples=60, deadline=None)
@given(first_loop_designs())
def test_rocker_body_d_c_h_f_is_identical_for_both_legs(x: np.ndarray) -> None:
    s = switching_state(x)
    pts = {k: s[k][0] for k in "DCHF"}
    scale = 1.0 + max(np.abs(v).max() for v in pts.values())
    for a, b in (("D", "C"), ("D", "H"), ("D", "F"), ("C", "H"), ("C", "F"), ("H", "F")):
        d = _dist(pts[a], pts[b])
        assert abs(d[0] - d[1]) <= 1e-9 * scale, (a, b)
    # and with the same orientation (not mirrored): signed area of D, C, H
    u, v = pts["C"] - pts["D"], pts["H"] - pts["D"]
    sa = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    assert abs(sa[0] - sa[1]) <= 1e-9 * scale * scale


@settings(max_examples=60, deadline=None)
@given(first_loop_designs())
def test_switching_angle_is_a_root_and_right_leg_is_the_rear_one(x: np.ndarray) -> None:
    s = switching_state(x)
    _, e, _ = first_loop(x, s["phi"])
    assert abs(e[0, 0, 1] - e[0, 1, 1]) < 1e-9 * (1.0 + np.abs(e).max())
    assert e[0, 0, 0] <= e[0, 1, 0]


@settings(max_examples=50, deadline=None)
@given(first_loop_designs(), st.lists(st.floats(-2 * math.pi, 2 * math.pi), min_size=1, max_size=8))
def test_the_compiled_foot_height_is_the_first_loops(x: np.ndarray, angles: list[float]) -> None:
    # the bisection's numba y_E(phi) mirrors the numpy first loop's formula (kept side by side for speed)
    phi = np.array([angles])
    want = _loop_xy(x, phi)[3][0]
    got = np.array([_y_e(x[0], a) for a in angles])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(st.lists(first_loop_designs(), min_size=2, max_size=6))
def test_the_switching_angle_of_a_batch_equals_each_designs_own(rows: list[np.ndarray]) -> None:
    batch = switching_angle(np.concatenate(rows))
    alone = np.array([switching_angle(r)[0] for r in rows])
    assert np.array_equal(batch, alone, equal_nan=True)


@pytest.mark.parametrize("name", WORKING)
def test_every_rigid_distance_is_preserved_in_both_modes(name: str) -> None:
    for mech in (RTCLM_PRIMARY, RTCLM_AUXILIARY):
        sol = solve(mech, _x(name), N, backend="numpy")
        assert sol.violation[0] == 0.0
        assert sol.joints is not None
        idx = {n: i for i, n in enumerate(sol.joint_names)}
        for body in mech.bodies():
            for i, a in enumerate(body):
                for b in body[i + 1 :]:
                    d = _dist(sol.joints[0, :, idx[a]], sol.joints[0, :, idx[b]])
                    assert np.ptp(d) < 1e-9, (mech.name, a, b)


def test_the_rocker_d_c_h_f_is_one_body_in_the_primary_mode() -> None:
    assert ("D", "C", "H", "F") in RTCLM_PRIMARY.bodies()
    assert ("A", "B", "C", "D", "E", "H") in RTCLM_AUXILIARY.bodies()


@settings(max_examples=30, deadline=None)
@given(working_designs())
def test_sample_zero_of_both_modes_is_the_switching_state(x: np.ndarray) -> None:
    sp = solve(RTCLM_PRIMARY, x, N, backend="numpy")
    sa = solve(RTCLM_AUXILIARY, x, N, backend="numpy")
    assume(sp.violation[0] == 0.0 and sa.violation[0] == 0.0)
    assert sp.joints is not None and sa.joints is not None
    s = switching_state(x)
    ip, ia = list(sp.joint_names), list(sa.joint_names)
    for name in ia:
        np.testing.assert_allclose(sp.joints[0, 0, ip.index(name)], sa.joints[0, 0, ia.index(name)], atol=1e-9)
    for name in "BCDEHF":
        np.testing.assert_allclose(sp.joints[0, 0, ip.index(name)], s[name][0, 0], atol=1e-9)
        # The left leg is the same primary mechanism half a crank turn later.
        np.testing.assert_allclose(sp.joints[0, N // 2, ip.index(name)], s[name][0, 1], atol=1e-9)


def _aux_at(e: np.ndarray, h: np.ndarray, phase: float, x: np.ndarray) -> Mechanism:
    """An auxiliary four-bar with frame points and crank phase given as numbers."""
    return Mechanism(
        "aux_test",
        "aux_test",
        PARAMS,
        (
            Ground("E", float(e[0]), float(e[1])),
            Ground("H", float(h[0]), float(h[1])),
            Crank("F", "H", "r6", 0.0, phase=phase),
            Dyad("G", "E", "F", "r4", "r5", SIDE_G),
            Attach("P", "F", "G", "a3", "-b3"),
        ),
        "P",
    )


@pytest.mark.parametrize("name", WORKING[:4])
def test_left_auxiliary_foot_path_is_the_right_one_shifted_along_x(name: str) -> None:
    x = _x(name)
    s = switching_state(x)
    phase = float(s["psi"][0, 1] + x[0, 12])
    right = solve(_aux_at(s["E"][0, 0], s["H"][0, 0], phase, x), x, N, backend="numpy").leg[0]
    left = solve(_aux_at(s["E"][0, 1], s["H"][0, 1], phase, x), x, N, backend="numpy").leg[0]
    shift = s["E"][0, 1] - s["E"][0, 0]
    assert abs(shift[1]) < 1e-9
    np.testing.assert_allclose(left, right + shift, atol=1e-9)


@pytest.mark.parametrize("name", WORKING[:6])
def test_foot_derivative_matches_central_difference(name: str) -> None:
    n = 20000
    for mech in (RTCLM_PRIMARY, RTCLM_AUXILIARY):
        sol = solve(mech, _x(name), n, backend="numpy", joints=False)
        step = 2 * np.pi / n
        fd = (np.roll(sol.leg, -1, axis=1) - np.roll(sol.leg, 1, axis=1)) / (2 * step)
        scale = np.abs(sol.dleg).max()
        np.testing.assert_allclose(sol.dleg, fd, rtol=0, atol=1e-5 * scale)


def test_presets_assemble_exactly_where_documented() -> None:
    for key, row in PAPER_ROWS.items():
        for mech, ours in ((RTCLM_PRIMARY, row.ours[0]), (RTCLM_AUXILIARY, row.ours[1])):
            viol = solve(mech, np.array([row.values()]), N, backend="numpy", joints=False).violation[0]
            assert (viol == 0.0) == bool(np.isfinite(ours)), (key, mech.name, viol)
    assert len(WORKING) >= 10


@pytest.mark.parametrize("key", [k for k, r in PAPER_ROWS.items() if r.fit == "h6"])
def test_fitted_presets_give_the_papers_h6(key: str) -> None:
    row = PAPER_ROWS[key]
    sol = solve(RTCLM_PRIMARY, np.array([row.values()]), N, backend="numpy", joints=False)
    assert _h_m(sol.leg[:, :, 1])[0] == pytest.approx(row.h6, abs=0.05)


def test_presets_carry_the_printed_rows() -> None:
    assert len(PRESETS) == 2 * (len(PAPER_ROWS) + len(OURS)) == 82
    assert PAPER_ROWS["case1-NSGA-II"].printed.split()[-1] == "113.64"
    assert PAPER_ROWS["case5-DRLOS-EMCMO"].h6 == 50.13  # spec §7: printed h6 and h4 swapped
    for key, row in PAPER_ROWS.items():
        printed = [float(v) for v in row.printed.split()]
        assert len(printed) == 13
        v = PRESETS[f"rtclm/{key}"].values
        assert v[:4] == tuple(printed[:4]) and v[5:12] == tuple(printed[5:12]) and v[4] == abs(printed[4])
        assert PRESETS[f"rtclm/{key}/auxiliary"].values == v
        assert PRESETS[f"rtclm/{key}"].mechanism is RTCLM_PRIMARY
        assert PRESETS[f"rtclm/{key}/auxiliary"].mechanism is RTCLM_AUXILIARY


def test_derive_batch_equals_loop_and_is_nan_safe() -> None:
    rows = [PAPER_ROWS[k].values() for k in list(PAPER_ROWS)[:12]]
    x = np.array(rows + [[np.nan] * 13, [np.inf] + list(rows[0][1:])])
    before = x.copy()
    derived, viol = derive(x)
    np.testing.assert_array_equal(x, before)
    for i in range(len(x)):
        d1, v1 = derive(x[i : i + 1])
        np.testing.assert_allclose(d1[0], derived[i], rtol=1e-12, atol=1e-12)
        assert v1[0] == viol[i]
    assert np.isinf(viol[-2:]).all() and np.isnan(derived[-2:]).all()
    ok = viol == 0.0
    assert np.isfinite(derived[ok]).all() and np.isnan(derived[~ok]).all()


def test_derive_violation_grows_continuously_as_the_first_loop_opens() -> None:
    x = np.repeat(_x("case4"), 400, axis=0)
    lo = first_loop_shortfall(x[:1])[0]
    assert lo == 0.0
    x[:, 6] = np.linspace(135.0, 400.0, 400)  # pull D away until A-B-C-D cannot close
    _, viol = derive(x)
    short = first_loop_shortfall(x)
    np.testing.assert_array_equal(viol, short)
    assert viol[0] == 0.0 and viol[-1] > 0.0
    assert np.all(np.diff(viol) >= -1e-12) and np.abs(np.diff(viol)).max() < 1.0


def _drag_link(frame: float, *links: float) -> bool:
    """Grashof four-bar whose frame is the shortest link: every link turns fully (not Eq. 29's crank-rocker)."""
    return frame < min(links) and frame + max(links) < sum(links) - max(links)


@settings(max_examples=100, deadline=None)
@given(st.floats(30, 100), st.floats(50, 250), st.floats(50, 250), st.floats(-150, 150), st.floats(-150, 150))
def test_eq29_first_line_is_the_crank_rocker_condition(r1: float, r2: float, r3: float, xd: float, yd: float) -> None:
    x = np.array([[r1, r2, r3, 100.0, 100.0, 30.0, xd, yd, 100.0, 100.0, 100.0, 100.0, 0.0]])
    c0 = crank_conditions(x)[0, 0]
    short = first_loop_shortfall(x)[0]
    ad = math.hypot(xd, yd)
    assume(abs(c0) > 1e-6 and abs(abs(r2 - r3) - abs(ad - r1)) > 1e-6 and abs(ad + r1 - r2 - r3) > 1e-6)
    # Eq. 29 => AB turns fully; AB also turns fully (drag link) when the frame AD is the shortest.
    assert (c0 < 0 or _drag_link(ad, r1, r2, r3)) == (short == 0.0)


def test_eq29_by_hand() -> None:
    # |AD| = 5 * 30 = 150: 40 + 2 * 150 - (120 + 100 + 150) = -30 (crank turns fully).
    x = np.array([[40.0, 120.0, 100.0, 100.0, 100.0, 30.0, 90.0, 120.0, 100.0, 100.0, 100.0, 100.0, 0.0]])
    c = crank_conditions(x)[0]
    assert c[0] == pytest.approx(-30.0)
    eh = np.linalg.norm(switching_state(x)["eh"][0])
    assert c[1] == pytest.approx(30.0 + 2 * max(100.0, eh) - (200.0 + eh))
    x[0, 6:8] = 1000.0, 0.0  # the first loop cannot close: no EH
    assert crank_conditions(x)[0, 1] == np.inf


@pytest.mark.parametrize("name", WORKING)
def test_eq29_second_line_agrees_with_the_solvers_crank_margin(name: str) -> None:
    x = _x(name)
    c1 = crank_conditions(x)[0, 1]
    margin = solve(RTCLM_AUXILIARY, x, 8, backend="numpy", joints=False).crank_margin[0]
    eh = float(np.linalg.norm(switching_state(x)["eh"][0]))
    assert (c1 < 0 or _drag_link(eh, *x[0, 3:6])) == (margin > 0)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_row_with_no_coupling_solution_gets_the_derive_violation_not_nan(backend: str) -> None:
    # This printed row's auxiliary mode has no coupling solution: prepare() poisons its operands,
    # and the violation must be the derive violation (finite, positive), never NaN.
    p = PRESETS["rtclm/case1-CMOEMT/auxiliary"]
    sol = solve(p.mechanism, np.asarray(p.values), 90, output=p.output, backend=backend)
    internal, derive_viol = p.mechanism.internal(np.atleast_2d(p.values))
    assert not np.isfinite(p.mechanism.compile().operands(internal)).all()
    assert not sol.valid.any()
    assert sol.violation[0] == pytest.approx(float(derive_viol[0])) and 0.0 < sol.violation[0] < np.inf


def test_the_tiered_violations_are_not_labelled_as_millimetres() -> None:
    # The Pick panel read "primary assembly (mm) 1001" for case 4's preset, which assembles: 1000 is the tier and 1
    # an extra turn of its figure-eight path (docs/rtclm.md), neither a length.
    from core.kinematics.presets import get
    from core.optimize.problem import make_problem

    p = make_problem("rtclm2")
    m = p.evaluate_metrics(get("rtclm/case4").design())
    assert float(m["violation"][0]) == 1001.0
    for k in ("violation", "aux_violation"):
        assert "(mm)" not in p.labels[k] and "1000" in p.labels[k]


def test_our_own_preset_meets_case_1s_targets_in_both_modes() -> None:
    # The studio opens the RTCLM on it: no paper row reproduces, and the first feasible one read h6 159 mm for 50.
    from core.optimize.problem import make_problem

    problem = make_problem("rtclm2")
    m = problem.evaluate_metrics(PRESETS["rtclm/clm-case1"].design())
    assert float(m["dh6"][0]) <= 0.5 and float(m["dh4"][0]) <= 0.5  # the paper's stop threshold
    assert all(float(c.value(m[c.metric])[0]) <= 0.0 for c in problem.constraints)
    assert PRESETS["rtclm/clm-case1/auxiliary"].values == PRESETS["rtclm/clm-case1"].values
    assert "session 30" in PRESETS["rtclm/clm-case1"].source
    # Clear of dead points and of the ground in both modes (session 24's swept its rocker below the ground and came
    # 5.6 deg from a dead point in the auxiliary mode).
    for mode in ("6", "4"):
        assert float(m[f"transmission_{mode}"][0]) >= 20.0 and float(m[f"clearance_{mode}"][0]) > 100.0
