"""The solver's contract on the Stephenson legs: fidelity, rigidity, exact derivatives, NaN safety."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.kinematics.mechanisms.stephenson import STEPHENSON1, STEPHENSON3
from core.kinematics.model import OutputStage
from core.kinematics.presets import PAPER_PANTOGRAPH, PRESETS
from core.kinematics.solver import solve

BACKENDS = ["numpy", "numba"]
X3 = np.array(PRESETS["stephenson1/X3"].values)
S3 = np.array(PRESETS["stephenson3/paper"].values)


@pytest.mark.parametrize("backend", BACKENDS)
def test_x3_path_matches_the_paper_position_targets(backend):
    sol = solve(STEPHENSON1, X3, 360, backend=backend)
    x, y = sol.point[0, :, 0], sol.point[0, :, 1]
    assert sol.violation[0] == 0.0 and sol.valid.all()
    assert abs((x.max() - x.min()) - 298.94) <= 0.05
    assert abs(y.min() - (-101.04)) <= 0.05


def test_spec_construction_of_stephenson1_by_hand():
    """Joints of one sample rebuilt from spec §1's formulas, step by step."""
    b, g, xa, ya, *r = X3
    r = [None, *r]  # 1-based like the paper
    n, i = 12, 5
    phi = g + 2 * np.pi * i / n
    u = np.array([np.cos(phi), np.sin(phi)])

    def rot90(v):
        return np.array([-v[1], v[0]])

    def dyad(p, q, l1, l2, side):
        d = np.linalg.norm(q - p)
        e = (q - p) / d
        a = (l1**2 - l2**2 + d**2) / (2 * d)
        return p + a * e + side * np.sqrt(l1**2 - a**2) * rot90(e)

    A = np.array([xa, ya])
    D = A + r[4] * np.array([np.cos(b), np.sin(b)])
    B = A + r[1] * u
    C = dyad(B, D, r[2], r[3], +1)
    F = A + r[5] * u + r[6] * rot90(u)
    e = (C - D) / np.linalg.norm(C - D)
    E = D + r[7] * e - r[8] * rot90(e)
    G = dyad(E, F, r[9], r[10], -1)
    w = (G - F) / np.linalg.norm(G - F)
    P = F + r[11] * w + r[12] * rot90(w)
    sol = solve(STEPHENSON1, X3, n, backend="numpy")
    names = sol.joint_names
    for name, want in zip("ADBCFEGP", (A, D, B, C, F, E, G, P), strict=True):
        np.testing.assert_allclose(sol.joints[0, i, names.index(name)], want, atol=1e-9)


def test_leg_frame_is_the_pantograph_image_of_the_design_frame():
    sol = solve(STEPHENSON1, X3, 90, output=PAPER_PANTOGRAPH, backend="numpy")
    np.testing.assert_allclose(sol.leg, np.array([300.0, 0.0]) - sol.point, atol=1e-12)
    np.testing.assert_allclose(sol.dleg, -sol.dpoint, atol=1e-12)
    ident = solve(STEPHENSON1, X3, 90, output=OutputStage(), backend="numpy")
    np.testing.assert_array_equal(ident.leg, ident.point)


def _jitter(base, seed, scale):
    rng = np.random.default_rng(seed)
    return base * (1 + scale * rng.uniform(-1, 1, base.shape))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), which=st.sampled_from(["s1", "s3"]))
def test_rigid_distances_are_preserved_over_the_cycle(seed, which):
    mech, base = (STEPHENSON1, X3) if which == "s1" else (STEPHENSON3, S3)
    params = _jitter(base, seed, 0.03)[None]
    sol = solve(mech, params, 120, backend="numpy")
    ok = sol.violation == 0
    if not ok.any():
        return
    names = sol.joint_names
    for body in mech.bodies():
        idx = [names.index(p) for p in body]
        for a in range(len(idx)):
            for c in range(a + 1, len(idx)):
                d = np.linalg.norm(sol.joints[ok][:, :, idx[a]] - sol.joints[ok][:, :, idx[c]], axis=-1)
                assert np.ptp(d, axis=1).max() < 1e-9


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), which=st.sampled_from(["s1", "s3"]))
def test_derivatives_match_central_differences(seed, which):
    mech, base = (STEPHENSON1, X3) if which == "s1" else (STEPHENSON3, S3)
    params = _jitter(base, seed, 0.03)
    if solve(mech, params, 72, backend="numpy").violation[0] > 0:
        return
    h = 1e-6
    gi = mech.param_names.index("g")
    plus, minus = params.copy(), params.copy()
    plus[gi] += h
    minus[gi] -= h
    sol = solve(mech, params, 72, backend="numpy")
    fd = (solve(mech, plus, 72, backend="numpy").joints - solve(mech, minus, 72, backend="numpy").joints) / (2 * h)
    # Away from dead centres the exact derivative and the central difference agree closely.
    scale = np.abs(sol.djoints).max()
    assert np.abs(fd - sol.djoints).max() <= 1e-5 * scale


def test_unassemblable_design_gives_nan_and_positive_violation():
    bad = X3.copy()
    bad[STEPHENSON1.param_names.index("r2")] = 30.0  # B-C too short to reach C from D
    sol = solve(STEPHENSON1, np.stack([X3, bad]), 90, backend="numpy")
    assert sol.violation[0] == 0 and sol.violation[1] > 0
    assert np.isnan(sol.point[1]).any() and not sol.valid[1].all()
    assert np.isfinite(sol.point[0]).all()


def test_violation_shrinks_continuously_towards_assembly():
    i = STEPHENSON1.param_names.index("r2")
    r2 = np.linspace(30.0, X3[i], 200)
    params = np.repeat(X3[None], r2.size, axis=0)
    params[:, i] = r2
    v = solve(STEPHENSON1, params, 180, backend="numpy").violation
    failing = v > 0
    assert failing[0] and not failing[-1]
    # Monotone non-increasing as the link lengthens, with no jumps larger than the step.
    assert np.all(np.diff(v) <= 1e-12)
    assert np.abs(np.diff(v)).max() <= 3.0 * (r2[1] - r2[0])  # Lipschitz: no jumps
    # Zero exactly where the crank-loop closes for every sample.
    first_zero = np.argmax(~failing)
    assert v[first_zero - 1] < 1.0


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_non_finite_parameters_never_raise(value):
    bad = X3.copy()
    bad[5] = value
    sol = solve(STEPHENSON1, np.stack([bad, X3]), 36, backend="numpy")
    assert np.isinf(sol.violation[0]) and np.isnan(sol.point[0]).all()
    assert sol.violation[1] == 0


def test_negative_lengths_count_as_violation():
    bad = X3.copy()
    bad[STEPHENSON1.param_names.index("r9")] *= -1
    sol = solve(STEPHENSON1, bad, 36, backend="numpy")
    assert sol.violation[0] >= abs(bad[STEPHENSON1.param_names.index("r9")])


def test_inputs_are_not_mutated_and_single_equals_batch():
    params = np.stack([X3, _jitter(X3, 1, 0.02), _jitter(X3, 2, 0.02)])
    before = params.copy()
    batch = solve(STEPHENSON1, params, 60, backend="numpy")
    np.testing.assert_array_equal(params, before)
    for k in range(3):
        one = solve(STEPHENSON1, params[k], 60, backend="numpy")
        np.testing.assert_array_equal(one.joints[0], batch.joints[k])
        np.testing.assert_array_equal(one.violation[0], batch.violation[k])


def test_crank_margin_is_grashof_of_the_first_loop():
    sol = solve(STEPHENSON1, X3, 12, backend="numpy")
    b, g, xa, ya, r1, r2, r3, r4 = X3[:8]
    want = min(r2 + r3 - (r4 + r1), abs(r4 - r1) - abs(r2 - r3))
    assert sol.crank_margin[0] == pytest.approx(want)
    assert sol.crank_margin[0] > 0


def test_transmission_angles_and_margins_are_consistent():
    sol = solve(STEPHENSON1, X3, 360, backend="numpy")
    assert sol.dyad_names == ("C", "G")
    assert np.all(sol.mu_min <= sol.mu_max)
    assert np.all((0 < sol.mu_min) & (sol.mu_max < np.pi))
    assert np.all(sol.dyad_margin > 0)


def test_bodies_of_stephenson1_are_the_six_links():
    bodies = {frozenset(b) for b in STEPHENSON1.bodies()}
    want = {frozenset(s) for s in ("AD", "ABF", "BC", "DCE", "EG", "FGP")}
    assert bodies == want


def test_wrong_parameter_count_is_a_clear_error():
    with pytest.raises(ValueError, match="16 parameters"):
        solve(STEPHENSON1, X3[:5], 10)


def test_a_mirrored_output_stage_reflects_x_about_o_then_scales():
    stage = OutputStage(k=-0.5, ox=150.0, oy=20.0, mirror=True)
    p = np.array([[[10.0, 30.0], [200.0, -40.0]]])
    # O + k M (P - O) with M = diag(-1, 1)
    want = np.stack([150.0 - 0.5 * -(p[..., 0] - 150.0), 20.0 - 0.5 * (p[..., 1] - 20.0)], -1)
    np.testing.assert_allclose(stage.apply(p), want, atol=1e-12)
    np.testing.assert_allclose(stage.apply_derivative(p), p * np.array([0.5, -0.5]), atol=1e-12)
    assert OutputStage.from_dict(stage.to_dict()) == stage
    assert OutputStage.from_dict({"k": -0.5, "ox": 150.0, "oy": 20.0}).mirror is False  # older files
    assert "mirror" not in OutputStage(k=-1.0).to_dict()


@settings(max_examples=60, deadline=None)
@given(k=st.floats(-5, 5).filter(lambda v: abs(v) > 1e-3), ox=st.floats(-500, 500), oy=st.floats(-500, 500),
       mirror=st.booleans(), seed=st.integers(0, 2**31))
def test_invert_takes_the_leg_frame_back_to_the_design_frame(k, ox, oy, mirror, seed):
    stage = OutputStage(k=k, ox=ox, oy=oy, mirror=mirror)
    p = np.random.default_rng(seed).uniform(-400, 400, (7, 2))
    np.testing.assert_allclose(stage.invert(stage.apply(p)), p, atol=1e-9)
    np.testing.assert_allclose(stage.apply(stage.invert(p)), p, atol=1e-9)


def test_the_paper_pantograph_inverts_a_foot_path_about_its_centre():
    # k = -1 about (150, 0) is its own inverse: (x, y) -> (300 - x, -y)
    p = np.array([[0.0, 0.0], [150.0, 100.0], [300.0, 0.0]])
    np.testing.assert_allclose(PAPER_PANTOGRAPH.invert(p), [[300.0, 0.0], [150.0, -100.0], [0.0, 0.0]], atol=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_both_backends_map_the_leg_frame_through_a_mirror(backend):
    stage = OutputStage(k=-1.0, ox=150.0, oy=0.0, mirror=True)
    sol = solve(STEPHENSON1, X3, 90, output=stage, backend=backend)
    np.testing.assert_allclose(sol.leg, stage.apply(sol.point), atol=1e-12)
    np.testing.assert_allclose(sol.dleg, stage.apply_derivative(sol.dpoint), atol=1e-12)
    np.testing.assert_allclose(sol.leg[..., 0], sol.point[..., 0], atol=1e-12)  # k = -1 and mirror: x kept


def test_only_a_dyad_from_a_crank_point_closes_a_crank_loop():
    # Q rides on the crank line A->B but is an attachment, not the crank: the dyad Q-D is no crank loop, even
    # though Q's first parent is a ground point as a crank's is.
    from core.kinematics.mechanisms.fourbar import FOURBAR
    from core.kinematics.model import Attach, Dyad, Mechanism
    from core.kinematics.solver import _crank_dyads

    steps = (*FOURBAR.steps, Attach("Q", "A", "B", 10.0, 0.0), Dyad("E", "Q", "D", 150.0, 150.0, +1))
    mech = Mechanism(name="fourbar_q", title="four-bar with a second dyad", params=FOURBAR.params, steps=steps,
                     tracked="P")
    ops = mech.compile().ops
    loops = _crank_dyads(ops.tobytes(), ops.shape[0])
    names = [mech.joint_names[j] for j, _, _ in loops]
    assert names == ["C"]


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_dyad_that_closes_at_no_sample_has_no_transmission_angle(backend: str):
    # r4 = 400 mm: dyad C is short by 268 mm everywhere. Its angle read 0..0 or 180..180 (the law of cosines
    # clipped to [-1, 1]), which clm simulate printed as if it were the mechanism's.
    x = X3.copy()
    x[STEPHENSON1.param_names.index("r4")] = 400.0
    sol = solve(STEPHENSON1, x, 90, backend=backend)
    assert sol.dyad_margin[0, 0] < -200
    assert np.isnan(sol.mu_min[0, 0]) and np.isnan(sol.mu_max[0, 0])
    good = solve(STEPHENSON1, X3, 90, backend=backend)
    assert np.isfinite(good.mu_min).all() and np.isfinite(good.mu_max).all()
