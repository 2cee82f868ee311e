"""Search boxes of the subtasks obey spec §6: x ± max(s|x|, d), angles d = s·π, clipped, g wraps."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.kinematics.mechanisms.stephenson import STEPHENSON1, STEPHENSON3
from core.kinematics.presets import PRESETS
from core.optimize.box import SUBTASK_STEPS, Box, global_box, periodic_mask, search_box

MECHS = {m.name: m for m in (STEPHENSON1, STEPHENSON3)}


def centers(draw: st.DrawFn, mech_name: str) -> np.ndarray:
    m = MECHS[mech_name]
    # Mostly inside the global bounds, sometimes outside (a hand-made design), angles anywhere.
    return np.array([draw(st.floats(p.lo - 100.0, p.hi + 100.0)) for p in m.params])


@st.composite
def box_cases(draw: st.DrawFn) -> tuple[str, np.ndarray, float, float]:
    name = draw(st.sampled_from(sorted(MECHS)))
    return name, centers(draw, name), draw(st.floats(0.01, 1.0)), draw(st.floats(0.01, 200.0))


def test_subtask_steps_are_the_papers() -> None:
    assert SUBTASK_STEPS == {1: (0.2, 20.0), 2: (0.1, 10.0), 3: (0.05, 5.0)}


def test_only_the_full_turn_angles_wrap() -> None:
    names = [n for n, p in zip(STEPHENSON1.param_names, periodic_mask(STEPHENSON1), strict=True) if p]
    assert names == ["b", "g"]


@given(box_cases())
@settings(max_examples=150, deadline=None)
def test_box_is_the_spec_neighbourhood_clipped_to_global_bounds(case: tuple[str, np.ndarray, float, float]) -> None:
    name, x, s, d = case
    m = MECHS[name]
    box = search_box(m, x, s, d)
    for j, p in enumerate(m.params):
        h = max(s * abs(box.center[j]), s * np.pi if p.kind == "angle" else d)
        if box.periodic[j]:
            assert -np.pi <= box.center[j] < np.pi
            turns = (box.center[j] - x[j]) / (2 * np.pi)
            assert turns == pytest.approx(round(turns), abs=1e-9)  # the centre is x wrapped
            assert box.lower[j] == pytest.approx(box.center[j] - min(h, np.pi), abs=1e-12)
            assert box.upper[j] == pytest.approx(box.center[j] + min(h, np.pi), abs=1e-12)
        else:
            c = min(max(x[j], p.lo), p.hi)  # a centre outside the bounds is clipped onto them first
            assert box.center[j] == c
            assert box.lower[j] == max(c - h, p.lo)
            assert box.upper[j] == min(c + h, p.hi)
            assert p.lo <= box.lower[j] <= c <= box.upper[j] <= p.hi
        assert box.lower[j] < box.upper[j]


@given(box_cases(), st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_decoded_members_stay_in_the_box_and_wrap_into_pm_pi(
    case: tuple[str, np.ndarray, float, float], seed: int
) -> None:
    name, x, s, d = case
    m = MECHS[name]
    box = search_box(m, x, s, d, fixed=("r4",))
    X = np.random.default_rng(seed).uniform(box.xl, box.xu, (20, box.n_var))
    params = box.decode(X)
    assert box.contains(params).all()
    free = np.flatnonzero(~box.fixed & ~box.periodic & (box.upper - box.lower > 1e-6))
    if free.size:  # one coordinate beyond its bound: out of the box
        out = params.copy()
        out[:, free[0]] = box.upper[free[0]] + 1.0
        assert not box.contains(out).any()
    per = box.periodic
    assert ((params[:, per] >= -np.pi) & (params[:, per] < np.pi)).all()
    assert (params[:, m.param_names.index("r4")] == box.center[m.param_names.index("r4")]).all()
    np.testing.assert_allclose(box.encode(params), X, atol=1e-9)


def test_paper_x0_crank_phase_box_crosses_pi_instead_of_being_clipped() -> None:
    x0 = np.array(PRESETS["stephenson1/X0"].values)  # g = 3.14, next to +pi
    box = search_box(STEPHENSON1, x0, *SUBTASK_STEPS[1])
    g = STEPHENSON1.param_names.index("g")
    assert box.upper[g] - box.lower[g] == pytest.approx(2 * 0.2 * np.pi)
    # The paper's X1 phase (g = 3.22 > pi) lies in subtask 1's box around X0 (not clipped at pi).
    x1 = np.array(PRESETS["stephenson1/X1"].values)
    assert box.lower[g] <= box.encode(x1[None])[0, g] <= box.upper[g]
    assert box.decode(box.encode(x1[None]))[0, g] == pytest.approx(3.22 - 2 * np.pi)


def test_global_box_and_fixed_parameters() -> None:
    x = np.array(PRESETS["stephenson1/X3"].values)
    box = global_box(STEPHENSON1, x, fixed=("x_a", "y_a"))
    assert box.n_var == STEPHENSON1.n_params - 2
    np.testing.assert_array_equal(box.lower, STEPHENSON1.lower)
    np.testing.assert_array_equal(box.upper, STEPHENSON1.upper)
    params = box.decode(np.zeros((1, box.n_var)))
    assert params[0, 2] == x[2] and params[0, 3] == x[3]


def test_box_json_round_trip() -> None:
    box = search_box(STEPHENSON1, np.array(PRESETS["stephenson1/X2"].values), 0.1, 10.0, fixed=("b",))
    back = Box.from_dict(box.to_dict())
    for f in ("lower", "upper", "center", "bound_lo", "bound_hi", "periodic", "fixed"):
        np.testing.assert_array_equal(getattr(back, f), getattr(box, f))


@pytest.mark.parametrize("s, d", [(0.0, 20.0), (0.2, 0.0), (np.nan, 1.0), (0.2, np.inf)])
def test_bad_box_rule_is_refused(s: float, d: float) -> None:
    with pytest.raises(ValueError, match="box scale"):
        search_box(STEPHENSON1, np.array(PRESETS["stephenson1/X2"].values), s, d)


def test_unknown_fixed_parameter_is_named() -> None:
    with pytest.raises(ValueError, match="'r99'"):
        search_box(STEPHENSON1, np.array(PRESETS["stephenson1/X2"].values), 0.1, 10.0, fixed=("r99",))


def test_a_box_with_every_parameter_fixed_is_refused() -> None:
    everything = STEPHENSON1.param_names
    x = np.array(PRESETS["stephenson1/X2"].values)
    with pytest.raises(ValueError, match="every parameter of stephenson1 is fixed"):
        global_box(STEPHENSON1, x, everything)
    with pytest.raises(ValueError, match="every parameter of stephenson1 is fixed"):
        search_box(STEPHENSON1, x, 0.1, 10.0, everything)
    assert global_box(STEPHENSON1, x, everything[1:]).n_var == 1
