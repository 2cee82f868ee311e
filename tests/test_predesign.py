"""Predesign X0: analytic placement moves the tracked point's design-frame path onto the target."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis import fourier
from core.kinematics.design import Design
from core.kinematics.mechanisms import get as get_mechanism
from core.kinematics.presets import get
from core.optimize import make_problem
from core.optimize.objectives import shape_metrics
from core.optimize.predesign import apply_placement, place, placement

N = 120


def path(design: Design) -> np.ndarray:
    return design.solve(N, joints=False, backend="numpy").point


def test_stephenson_placement_plan_matches_its_construction() -> None:
    m = get_mechanism("stephenson1")
    plan = placement(m)
    names = m.param_names
    assert [names[i] for i in np.flatnonzero(plan.directions)] == ["b"]
    assert [names[i] for i in np.flatnonzero(plan.phases)] == ["g"]
    assert [(names[ix], names[iy], absolute) for ix, iy, _, _, absolute in plan.points] == [("x_a", "y_a", True)]
    assert [names[i] for i in np.flatnonzero(plan.scaled)] == [f"r{k}" for k in range(1, 13)]
    # Stephenson-III's third ground pivot hangs off A along b: also placeable.
    assert np.flatnonzero(placement(get_mechanism("stephenson3")).directions).tolist() == [0]


def test_rtclm_has_no_analytic_placement() -> None:
    with pytest.raises(ValueError, match="no analytic placement"):
        placement(get_mechanism("rtclm_primary"))


@given(
    scale=st.floats(0.6, 1.6),
    rotation=st.floats(-np.pi, np.pi),
    tx=st.floats(-200.0, 200.0),
    ty=st.floats(-200.0, 200.0),
    shift=st.integers(0, N - 1),
)
@settings(max_examples=15, deadline=None)
@pytest.mark.parametrize("preset", ["stephenson1/X3", "stephenson1/X0", "stephenson3/paper", "jansen", "klann",
                                    "watt1/paper", "fourbar/chebyshev"])  # jansen: ground operands "-a", "-l"
def test_placed_design_traces_the_transformed_path_exactly(scale: float, rotation: float, tx: float, ty: float,
                                                           shift: int, preset: str) -> None:
    d = get(preset).design()
    sim = fourier.Similarity(scale=np.array([scale]), rotation=np.array([rotation]),
                             translation=np.array([[tx, ty]]), shift=np.array([shift]),
                             phase=np.array([2 * np.pi * shift / N]), rms=np.array([0.0]))
    placed = Design(d.mechanism, apply_placement(placement(d.mechanism), d.params, sim), d.output)
    np.testing.assert_allclose(path(placed), fourier.apply_similarity(sim, path(d)), atol=1e-8)


def test_placing_a_moved_design_recovers_its_path_on_the_target() -> None:
    x3 = get("stephenson1/X3").design()
    sim = fourier.Similarity(np.array([1.4]), np.array([0.7]), np.array([[40.0, -90.0]]), np.array([33]),
                             np.array([2 * np.pi * 33 / N]), np.array([0.0]))
    moved = Design(x3.mechanism, apply_placement(placement(x3.mechanism), x3.params, sim), x3.output)
    assert shape_metrics(moved, n_samples=N)["f1"][0] > 100.0
    back, _ = place(moved, n_samples=N, backend="numpy", fit="lsq")
    # The least-squares placement of X3's shape is where X3 already nearly is (the paper placed it by hand).
    err = shape_metrics(Design(x3.mechanism, back, x3.output), n_samples=N)["f1"][0]
    assert err <= shape_metrics(x3, n_samples=N)["f1"][0] + 0.3


def test_extent_fit_puts_width_and_lowest_point_on_the_target() -> None:
    designs = [get(n).design() for n in ("stephenson1/X0", "stephenson1/X1", "stephenson1/direct-min-I")]
    d = Design(designs[0].mechanism, np.vstack([x.params for x in designs]), designs[0].output)
    placed, _ = place(d, n_samples=N, backend="numpy", fit="extent")
    m = shape_metrics(Design(d.mechanism, placed, d.output), n_samples=N)
    np.testing.assert_allclose(m["width"], 300.0, atol=1e-8)
    np.testing.assert_allclose(m["y_min"], -100.0, atol=1e-8)


def test_unassemblable_members_are_left_nan_for_the_repair_to_keep() -> None:
    x3 = get("stephenson1/X3").design()
    bad = x3.params.copy()
    bad[0, 4] = 400.0
    out, _ = place(Design(x3.mechanism, np.vstack([x3.params, bad]), x3.output), n_samples=N, backend="numpy")
    assert np.isfinite(out[0]).all() and np.isnan(out[1]).all()


def test_predesign_problem_scores_shape_and_placed_error() -> None:
    spec = make_problem("predesign", n_samples=N, backend="numpy")
    assert spec.objectives == ("fd", "f1") and spec.repair is not None
    x0, x3 = get("stephenson1/X0").design(), get("stephenson1/X3").design()
    both = Design(x0.mechanism, np.vstack([x0.params, x3.params]), x0.output)
    m = spec.evaluate_metrics(both)
    assert (m["fd"] >= 0).all()
    assert m["fd"][1] < m["fd"][0]  # X3's shape is closer to the cycloid than X0's
    repaired = spec.repair(both)
    np.testing.assert_allclose(spec.repair(Design(x0.mechanism, repaired, x0.output)), repaired, atol=1e-6)
