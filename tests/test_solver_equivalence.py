"""The numba kernel computes what the numpy reference computes, for every design and every input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.kinematics import kernel as solver_numba
from core.kinematics import reference as solver_numpy
from core.kinematics.mechanisms.stephenson import STEPHENSON1, STEPHENSON3
from core.kinematics.model import ATTACH, CRANK, DYAD, GROUND
from core.kinematics.presets import PRESETS
from core.kinematics.solver import Solution, sample_angles, solve

TOL = 1e-9
BASES = {
    "stephenson1": (STEPHENSON1, np.array(PRESETS["stephenson1/X3"].values)),
    "stephenson3": (STEPHENSON3, np.array(PRESETS["stephenson3/paper"].values)),
}
FIELDS = ("joints", "djoints", "point", "dpoint", "leg", "dleg", "dyad_margin", "mu_min", "mu_max", "crank_margin")
EDITS = ["nan", "zero", "negate", "halve"]
KERNEL_OUTPUTS = ("pos", "dpos", "point", "dpoint", "valid", "mmin", "cmin", "cmax", "neg")


def assert_close(got, want, what: str) -> None:
    """Identical NaN and inf pattern, finite values within 1e-9 relative to ``1 + |want|``."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape, what
    if want.dtype == np.bool_:
        np.testing.assert_array_equal(got, want, err_msg=what, strict=True)
        return
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want), err_msg=f"{what}: NaN pattern")
    inf = np.isinf(want)
    np.testing.assert_array_equal(np.isinf(got), inf, err_msg=f"{what}: inf pattern")
    np.testing.assert_array_equal(got[inf], want[inf], err_msg=f"{what}: inf signs")
    fin = np.isfinite(want)
    err = np.abs(got[fin] - want[fin]) / (1.0 + np.abs(want[fin]))
    assert err.max(initial=0.0) <= TOL, f"{what}: max relative error {err.max():.3g}"


def assert_same_solution(got: Solution, want: Solution) -> None:
    for name in FIELDS:
        assert_close(getattr(got, name), getattr(want, name), name)
    np.testing.assert_array_equal(got.valid, want.valid)
    assert_close(got.violation, want.violation, "violation")
    np.testing.assert_array_equal(got.feasible, want.feasible)


def assert_identical(a, b, what: str = "") -> None:
    """Bit-for-bit the same arrays (NaN where NaN), or both None."""
    if a is None or b is None:
        assert a is None and b is None, what
        return
    np.testing.assert_array_equal(a, b, err_msg=what, strict=True)


def population(mech: str, seed: int, pop: int, scale: float, n_nan_rows: int = 0) -> np.ndarray:
    """``(pop, n_params)`` a base design jittered by ``scale`` (relative), some rows NaN."""
    _, base = BASES[mech]
    rng = np.random.default_rng(seed)
    params = base * (1.0 + scale * rng.uniform(-1.0, 1.0, (pop, base.size)))
    params[rng.choice(pop, size=min(n_nan_rows, pop), replace=False)] = np.nan
    return params


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_matches_the_reference(name):
    preset = PRESETS[name]
    kw = {"output": preset.output}
    want = solve(preset.mechanism, np.array(preset.values), 360, backend="numpy", **kw)
    got = solve(preset.mechanism, np.array(preset.values), 360, backend="numba", **kw)
    assert_same_solution(got, want)


@pytest.mark.parametrize("mech", sorted(BASES))
def test_a_wide_population_with_unassemblable_and_nan_members_matches_the_reference(mech):
    mechanism, _ = BASES[mech]
    params = population(mech, seed=7, pop=60, scale=0.25, n_nan_rows=3)
    want = solve(mechanism, params, 360, backend="numpy")
    got = solve(mechanism, params, 360, backend="numba")
    # The population exercises every path: assembling, failing part of the cycle, NaN rows.
    assert want.feasible.any() and (~want.valid.all(axis=1) & want.valid.any(axis=1)).any()
    assert np.isinf(want.violation).sum() == 3
    assert_same_solution(got, want)


@settings(max_examples=30, deadline=None)
@given(
    mech=st.sampled_from(sorted(BASES)),
    seed=st.integers(0, 2**32 - 1),
    pop=st.integers(1, 12),
    scale=st.sampled_from([0.0, 0.01, 0.05, 0.2, 0.5]),
    n_samples=st.sampled_from([1, 2, 7, 64, 360]),
    n_nan_rows=st.integers(0, 2),
)
def test_random_populations_match_the_reference(mech, seed, pop, scale, n_samples, n_nan_rows):
    mechanism, _ = BASES[mech]
    params = population(mech, seed, pop, scale, n_nan_rows)
    want = solve(mechanism, params, n_samples, backend="numpy")
    got = solve(mechanism, params, n_samples, backend="numba")
    assert_same_solution(got, want)


def _operands(mech: str, params: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    mechanism, _ = BASES[mech]
    prog = mechanism.compile()
    return prog.ops, np.ascontiguousarray(prog.operands(mechanism.internal(params)[0])), prog.tracked


@settings(max_examples=40, deadline=None)
@given(
    mech=st.sampled_from(sorted(BASES)),
    seed=st.integers(0, 2**32 - 1),
    edits=st.lists(
        st.tuples(st.integers(0, 3), st.integers(0, 7), st.integers(0, 2), st.sampled_from(EDITS)),
        min_size=1,
        max_size=4,
    ),
    derivatives=st.booleans(),
)
def test_odd_operands_match_the_reference_entry_by_entry(mech, seed, edits, derivatives):
    """NaN, zero, negated and shrunk operands anywhere (not whole rows): same outputs as the reference."""
    ops, vals, tracked = _operands(mech, population(mech, seed, 4, 0.02))
    for i, j, k, edit in edits:
        vals[i, j, k] = {"nan": np.nan, "zero": 0.0, "negate": -vals[i, j, k], "halve": 0.5 * vals[i, j, k]}[edit]
    theta = sample_angles(48)
    got = solver_numba.run(ops, vals, theta, tracked, True, False, derivatives)
    want = solver_numpy.reduce(ops, vals, theta, tracked, True, derivatives)
    for name, g, w in zip(KERNEL_OUTPUTS, got, want, strict=True):
        if name in ("dpos", "dpoint") and not derivatives:
            assert g is None and w is None, name
        else:
            assert_close(g, w, name)


@settings(max_examples=25, deadline=None)
@given(
    mech=st.sampled_from(sorted(BASES)),
    seed=st.integers(0, 2**32 - 1),
    where=st.tuples(st.integers(0, 2), st.integers(0, 7), st.integers(0, 2)),
    value=st.sampled_from([np.inf, -np.inf]),
)
def test_infinite_operands_never_raise_and_flag_the_same_samples(mech, seed, where, value):
    """An infinite operand: inf and NaN may differ in form, but the same samples are non-finite."""
    ops, vals, tracked = _operands(mech, population(mech, seed, 3, 0.02))
    vals[where] = value
    theta = sample_angles(32)
    pos, dpos, point, _, valid, *_rest, neg = solver_numba.run(ops, vals, theta, tracked, True, False)
    ref_pos, _, ref_point, _, ref_valid, *_ref_rest, ref_neg = solver_numpy.reduce(ops, vals, theta, tracked, True)
    np.testing.assert_array_equal(valid, ref_valid)
    np.testing.assert_array_equal(np.isfinite(pos), np.isfinite(ref_pos))
    np.testing.assert_array_equal(np.isfinite(point), np.isfinite(ref_point))
    assert_close(neg, ref_neg, "neg")


@pytest.mark.parametrize("mech", sorted(BASES))
def test_batch_equals_a_loop_over_single_designs(mech):
    mechanism, _ = BASES[mech]
    params = population(mech, seed=3, pop=25, scale=0.2, n_nan_rows=2)
    batch = solve(mechanism, params, 90, backend="numba")
    for i in range(params.shape[0]):
        one = solve(mechanism, params[i], 90, backend="numba")
        for name in (*FIELDS, "valid", "violation"):
            assert_identical(getattr(one, name)[0], getattr(batch, name)[i], f"{name}[{i}]")


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_inputs_are_not_mutated(backend):
    params = population("stephenson1", seed=5, pop=10, scale=0.2, n_nan_rows=2)
    before = params.copy()
    solve(STEPHENSON1, params, 30, backend=backend)
    assert_identical(params, before)
    ops, vals, tracked = _operands("stephenson1", params)
    theta = sample_angles(30)
    copies = (ops.copy(), vals.copy(), theta.copy())
    if backend == "numba":
        solver_numba.run(ops, vals, theta, tracked, True, True)
    else:
        solver_numpy.reduce(ops, vals, theta, tracked, True)
        solver_numpy.reduce(ops, vals, theta, tracked, False, derivatives=False)
    for a, b in zip((ops, vals, theta), copies, strict=True):
        assert_identical(a, b)


@pytest.mark.parametrize("mech", sorted(BASES))
@pytest.mark.parametrize("joints", [False, True])
def test_serial_and_parallel_kernels_agree_bit_for_bit(mech, joints):
    # More designs than one parallel chunk, so several threads and chunk edges are involved.
    ops, vals, tracked = _operands(mech, population(mech, seed=11, pop=150, scale=0.2, n_nan_rows=5))
    theta = sample_angles(45)
    serial = solver_numba.run(ops, vals, theta, tracked, joints, False)
    parallel = solver_numba.run(ops, vals, theta, tracked, joints, True)
    for name, a, b in zip(KERNEL_OUTPUTS, serial, parallel, strict=True):
        assert_identical(a, b, name)


@pytest.mark.parametrize("mech", sorted(BASES))
def test_without_joints_the_tracked_point_is_the_same(mech):
    mechanism, _ = BASES[mech]
    params = population(mech, seed=2, pop=20, scale=0.2, n_nan_rows=1)
    full = solve(mechanism, params, 120, backend="numba", joints=True)
    lean = solve(mechanism, params, 120, backend="numba", joints=False)
    assert lean.joints is None and lean.djoints is None
    assert full.joints is not None
    for name in ("point", "dpoint", "leg", "dleg", "valid", "violation", "dyad_margin", "mu_min", "mu_max"):
        assert_identical(getattr(lean, name), getattr(full, name), name)
    assert_identical(full.point, full.joints[:, :, mechanism.compile().tracked])


def test_kernel_without_joints_allocates_no_joint_arrays():
    ops, vals, tracked = _operands("stephenson1", population("stephenson1", 0, 3, 0.0))
    out = solver_numba.run(ops, vals, sample_angles(16), tracked, False, False)
    assert out[0] is None and out[1] is None
    assert out[2].shape == (3, 16, 2) and out[4].dtype == np.bool_


@pytest.mark.parametrize(
    "rows",
    [
        [[GROUND, -1, -1, 0], [DYAD, 0, 2, 1], [CRANK, 0, -1, 0]],  # uses a later point
        [[GROUND, -1, -1, 0], [CRANK, -1, -1, 0]],  # crank without a pivot
        [[GROUND, -1, -1, 0], [ATTACH, 0, -1, 0]],  # attachment without Q
        [[GROUND, -1, -1, 0], [7, 0, -1, 0]],  # unknown step kind
    ],
)
def test_a_malformed_program_is_a_clear_error(rows):
    ops = np.array(rows, dtype=np.int64)
    for solver in (solver_numba.run, solver_numpy.reduce):
        with pytest.raises(ValueError, match="malformed program"):
            solver(ops, np.zeros((1, len(rows), 3)), sample_angles(4), 0, False, False)


def test_a_tracked_point_outside_the_program_is_a_clear_error():
    ops, vals, _ = _operands("stephenson1", population("stephenson1", 0, 1, 0.0))
    for solver in (solver_numba.run, solver_numpy.reduce):
        with pytest.raises(ValueError, match="malformed program"):
            solver(ops, vals, sample_angles(4), len(ops), False, False)
