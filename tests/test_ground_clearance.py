"""Ground clearance: closed forms on a four-bar whose foot is a point we know the lowest level of, invariants
(a shifted or scaled leg, a mirrored output, batch against one at a time), the fused kernel against the numpy
path, and the RTCLM problems' constraint."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis.clearance import ground_clearance
from core.analysis.evaluate import evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms.fourbar import FOURBAR
from core.kinematics.model import OutputStage
from core.kinematics.presets import get
from core.optimize.problem import make_problem

NAMES = FOURBAR.param_names


def fourbar(tracked: str = "P", **values: float) -> Design:
    base = dict(b=0.0, g=0.0, x_a=0.0, y_a=0.0, r1=30.0, r2=150.0, r3=150.0, r4=120.0, r5=60.0, r6=30.0)
    base.update(values)
    return Design(dataclasses.replace(FOURBAR, tracked=tracked), np.array([[base[n] for n in NAMES]]))


def clearance_of(design: Design, backend: str = "numba") -> float:
    return float(evaluate(design, 360, backend=backend).clearance[0])  # type: ignore[arg-type]


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_foot_on_the_crank_tip_stands_the_crank_length_below_its_pivot(backend: str) -> None:
    # The foot is B = A + r1 (cos, sin): its lowest level is y_a - r1; A and D (b = 0) sit at y_a and the coupler
    # point C stays above the ground line A-D, so the clearance is r1 exactly, at the pivot A.
    d = fourbar("B", y_a=17.0)
    assert clearance_of(d, backend) == pytest.approx(30.0, abs=1e-9)
    c = ground_clearance(d.solve(360), d.mechanism, d.output)
    assert c.names[c.lowest()] == "A" and c.warning() == ""
    assert c.text() == "30.0 mm (lowest point after the foot: A)"


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_frame_pivot_below_the_foot_is_an_upside_down_leg(backend: str) -> None:
    # D = A + r4 (cos b, sin b) with b = -90 deg: 120 mm below A, the foot (B) no lower than -30 mm.
    d = fourbar("B", b=-math.pi / 2)
    assert clearance_of(d, backend) == pytest.approx(-90.0, abs=1e-9)
    c = ground_clearance(d.solve(360), d.mechanism, d.output)
    assert c.warning().startswith("D (fixed) sits 90.0 mm below the ground the foot stands on")
    assert "the frame would reach the ground before the foot" in c.text()


def test_a_moving_joint_below_the_foot_strikes_the_ground() -> None:
    # The "foot" is the fixed pivot D (y = 0): the crank tip B sweeps down to -r1.
    d = fourbar("D")
    c = ground_clearance(d.solve(360), d.mechanism, d.output)
    assert float(c.value[0]) == pytest.approx(-30.0, abs=1e-9)
    assert c.warning() == "B dips 30.0 mm below the ground the foot stands on: the leg would strike the ground with it"


def test_not_defined_without_a_rigid_leg_frame_or_an_assembly() -> None:
    x3 = get("stephenson1/X3").design()  # a pantograph (k = -1) maps the foot alone
    assert math.isnan(clearance_of(x3)) and math.isnan(clearance_of(x3, "numpy"))
    broken = fourbar(r2=30.0, r3=30.0, r4=400.0)  # the loop cannot close
    assert math.isnan(clearance_of(broken)) and math.isnan(clearance_of(broken, "numpy"))
    c = ground_clearance(broken.solve(360), broken.mechanism, broken.output)
    assert c.text() == "n/a" and c.warning() == "" and c.lowest() == -1


def test_the_reference_walkers_stand_on_their_feet() -> None:
    # Jansen's and Klann's legs (Klann through a mirrored output) keep every joint above the ground they walk on.
    for name in ("jansen", "klann"):
        assert clearance_of(get(name).design()) > 20.0


@settings(max_examples=30, deadline=None)
@given(dy=st.floats(-300, 300), dx=st.floats(-300, 300), factor=st.floats(0.2, 5.0), mirror=st.booleans())
def test_shifted_scaled_or_mirrored_legs_keep_their_clearance(dy: float, dx: float, factor: float,
                                                              mirror: bool) -> None:
    base = fourbar("P", r5=60.0, r6=-80.0)
    c0 = clearance_of(base)
    assert np.isfinite(c0)
    assert clearance_of(fourbar("P", r5=60.0, r6=-80.0, x_a=dx, y_a=dy)) == pytest.approx(c0, abs=1e-6)
    assert clearance_of(base.scaled(factor)) == pytest.approx(c0 * factor, rel=1e-9, abs=1e-6)
    moved = Design(base.mechanism, base.params, OutputStage(1.0, dx, dy, mirror))
    assert clearance_of(moved) == pytest.approx(c0, abs=1e-9)


def test_a_batch_equals_each_design_alone_and_both_backends_agree() -> None:
    rng = np.random.default_rng(7)
    designs = [get(n).design() for n in ("jansen", "rtclm/case4", "rtclm/case1-CMOES", "rtclm/case4/auxiliary",
                                         "rtclm/case3")]
    mech = designs[1].mechanism
    params = np.vstack([designs[1].params, designs[2].params, designs[4].params,
                        mech.lower + (mech.upper - mech.lower) * rng.random((12, mech.n_params))])
    batch = Design(mech, params)
    fused = evaluate(batch, 360, backend="numba").clearance
    plain = evaluate(batch, 360, backend="numpy").clearance
    alone = np.array([clearance_of(Design(mech, params[i : i + 1])) for i in range(len(params))])
    solved = ground_clearance(batch.solve(360), mech, batch.output).value
    for other in (plain, alone, solved):
        np.testing.assert_allclose(fused, other, rtol=0, atol=1e-9, equal_nan=True)
    assert np.isfinite(fused[:2]).all() and np.isnan(fused[2])
    assert fused[1] < -100.0  # the paper's case-1 CMOES row, read with our conventions, is upside down
    for d in designs:
        assert clearance_of(d) == pytest.approx(clearance_of(d, "numpy"), abs=1e-9, nan_ok=True)


def test_the_rtclm_problems_hold_the_clearance_unless_told_not_to() -> None:
    upside_down = get("rtclm/case1-CMOES").design()
    for name in ("rtclm1", "rtclm2"):
        spec = make_problem(name)
        held = {c.metric: c.lower for c in spec.constraints if c.metric.startswith("clearance")}
        assert held == ({"clearance_6": 0.0} if name == "rtclm1" else {"clearance_6": 0.0, "clearance_4": 0.0})
        metrics = spec.evaluate(upside_down)
        assert metrics["clearance_6"][0] < -100.0
        assert not any(c.metric.startswith("clearance") for c in make_problem(name, clearance=False).constraints)
        tall = make_problem(name, clearance_min=25.0)
        assert {c.lower for c in tall.constraints if c.metric.startswith("clearance")} == {25.0}
    assert "clearance_4" in {c.metric for c in make_problem("rtclm1", auxiliary=True).constraints}
    for bad in (math.nan, "10", True, 1e9):
        with pytest.raises((TypeError, ValueError), match="clearance_min"):
            make_problem("rtclm1", clearance_min=bad)
    with pytest.raises((TypeError, ValueError), match="clearance"):
        make_problem("rtclm2", clearance="yes")


def test_the_auxiliary_mode_counts_the_left_legs_locked_crank_and_rocker() -> None:
    # Review of session 30: in the auxiliary mode both legs are locked in the switching state; this design's left
    # crank tip B stood 7.8 mm in the ground while the right leg's clearance read 14.3 mm, and rtclm2 took it.
    from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, switching_state
    from core.optimize.rtclm import mode_clearance, rtclm_metrics
    from studio.state import build_view
    from studio.target import TargetSpec

    params = np.array([[51.7282, 233.6429, 170.5449, 182.2574, 139.7624, 35.0462, 143.3577, 97.3132, 177.134,
                        59.374, 148.9073, 106.7225, 2.2563]])
    aux = Design(RTCLM_AUXILIARY, params)
    ground = float(aux.solve(360).leg[0, :, 1].min())
    left_b = float(switching_state(params)["B"][0, 1, 1])
    right = float(evaluate(aux).clearance[0])  # the mechanism's own joints: the right leg
    assert right == pytest.approx(14.34, abs=0.01) and left_b - ground == pytest.approx(-7.754, abs=0.001)
    assert float(rtclm_metrics(params)["clearance_4"][0]) == pytest.approx(left_b - ground, abs=1e-9)
    assert not make_problem("rtclm2").evaluate_metrics(aux)["clearance_4"][0] >= 0.0  # now refused
    c = mode_clearance(ground_clearance(aux.solve(360), aux.mechanism, aux.output), aux.mechanism, params)
    assert c.warning().startswith("B of the left leg (fixed) sits 7.8 mm below the ground")
    row = next(r for r in build_view(aux, None, TargetSpec()).rows if r.key == "clearance")
    assert row.severe and row.warn == c.warning()
    # The primary mode's left leg is the same mechanism half a turn later: nothing to add.
    primary = Design(get("rtclm/case4").mechanism, params)
    c6 = ground_clearance(primary.solve(360), primary.mechanism, primary.output)
    assert mode_clearance(c6, primary.mechanism, params) is c6


def test_the_auxiliary_clearance_is_one_rule_in_the_metrics_and_the_words() -> None:
    # The objective (rtclm_metrics) and what the studio and clm evaluate say (mode_clearance) read the same value
    # for every member, including those that do not assemble (NaN in both).
    from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY
    from core.optimize.rtclm import mode_clearance, rtclm_metrics

    base = get("rtclm/case4").design().params
    rng = np.random.default_rng(7)
    left_low = np.array([[51.7282, 233.6429, 170.5449, 182.2574, 139.7624, 35.0462, 143.3577, 97.3132, 177.134,
                          59.374, 148.9073, 106.7225, 2.2563]])  # its left B is lowest (the test above)
    near = left_low * rng.uniform(0.99, 1.01, size=(20, base.shape[1]))
    params = np.vstack([base * rng.uniform(0.85, 1.15, size=(40, base.shape[1])), left_low, near])
    got = rtclm_metrics(params)["clearance_4"]
    right = evaluate(Design(RTCLM_AUXILIARY, params)).clearance
    assert (got < right - 0.1).sum() >= 5  # members whose left leg decides
    aux = Design(RTCLM_AUXILIARY, params)
    want = mode_clearance(ground_clearance(aux.solve(360), aux.mechanism, aux.output), aux.mechanism, params).value
    assert np.isnan(got).any() and (~np.isnan(got)).sum() >= 10  # both kinds are in the sample
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6, equal_nan=True)
