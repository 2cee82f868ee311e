"""The numpy reference's ``reduce`` is the plain reduction of its per-sample ``run``, bit for bit,
whatever the block size, and without derivatives it computes the same positions and nothing else."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.kinematics import kernel as solver_numba
from core.kinematics import reference as solver_numpy
from core.kinematics.presets import PRESETS
from core.kinematics.solver import sample_angles

# One preset per program (mechanism).
NAMES = sorted({p.mechanism.name: k for k, p in reversed(PRESETS.items())}.values())
OUTPUTS = ("pos", "dpos", "point", "dpoint", "valid", "mmin", "cmin", "cmax", "neg")
POSITIONS = ("pos", "point", "valid", "mmin", "cmin", "cmax", "neg")
EDITS = {
    "nan": lambda v: np.nan,
    "zero": lambda v: 0.0,
    "negate": lambda v: -v,
    "halve": lambda v: 0.5 * v,
    "inf": lambda v: np.inf,
    "-inf": lambda v: -np.inf,
}


def plain_reduce(ops, vals, theta, tracked):
    """The kernel's outputs from ``run``'s per-sample arrays, written out plainly (the body of
    ``kinematics.reduce_reference`` before ``reduce`` existed)."""
    pos, dpos, margin, cos_mu, neg = solver_numpy.run(ops, vals, theta)
    with np.errstate(invalid="ignore"):
        mmin = np.min(np.where(np.isnan(margin), np.inf, margin), axis=1, initial=np.inf)
        cmin = np.min(np.where(np.isnan(cos_mu), np.inf, cos_mu), axis=1, initial=np.inf)
        cmax = np.max(np.where(np.isnan(cos_mu), -np.inf, cos_mu), axis=1, initial=-np.inf)
    valid = np.isfinite(pos).all(axis=(-1, -2))
    return pos, dpos, pos[:, :, tracked], dpos[:, :, tracked], valid, mmin, cmin, cmax, neg


def operands(name: str, pop: int, scale: float, seed: int, n_nan_rows: int = 0):
    """ops, ``(pop, n_steps, 3)`` operands of a preset jittered by ``scale`` (some rows NaN), tracked."""
    preset = PRESETS[name]
    m = preset.mechanism
    rng = np.random.default_rng(seed)
    params = np.asarray(preset.values) * (1.0 + scale * rng.uniform(-1.0, 1.0, (pop, m.n_params)))
    params[rng.choice(pop, size=min(n_nan_rows, pop), replace=False)] = np.nan
    prog = m.compile()
    return prog.ops, np.ascontiguousarray(prog.operands(m.internal(params)[0])), prog.tracked


def assert_same_bits(got, want, names=OUTPUTS) -> None:
    for name, g, w in zip(names, got, want, strict=True):
        assert g is not None and w is not None, name
        np.testing.assert_array_equal(g, w, err_msg=name, strict=True)


@pytest.mark.parametrize("block", [1, 3 * 30 + 1, solver_numpy.BLOCK_ELEMENTS])
@pytest.mark.parametrize("name", NAMES)
def test_reduce_is_the_plain_reduction_of_run(name, block, monkeypatch):
    """Blocks of one design, of three (the last one short) and the default: the same bits."""
    monkeypatch.setattr(solver_numpy, "BLOCK_ELEMENTS", block)
    ops, vals, tracked = operands(name, pop=10, scale=0.25, seed=1, n_nan_rows=2)
    theta = sample_angles(30)
    want = plain_reduce(ops, vals, theta, tracked)
    # Assembling, partly failing and NaN members are all in the population.
    assert want[4].all(axis=1).any() and (~want[4]).any() and np.isnan(want[8]).sum() == 2
    assert_same_bits(solver_numpy.reduce(ops, vals, theta, tracked, True), want)
    lean = solver_numpy.reduce(ops, vals, theta, tracked, False)
    assert lean[0] is None and lean[1] is None
    assert_same_bits(lean[2:], want[2:], OUTPUTS[2:])


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(NAMES),
    seed=st.integers(0, 2**32 - 1),
    edits=st.lists(
        st.tuples(st.integers(0, 3), st.integers(0, 7), st.integers(0, 2), st.sampled_from(sorted(EDITS))),
        min_size=1,
        max_size=4,
    ),
    n_samples=st.sampled_from([1, 2, 7, 48]),
    block=st.sampled_from([1, 50, solver_numpy.BLOCK_ELEMENTS]),
)
def test_odd_operands_reduce_plainly(name, seed, edits, n_samples, block):
    """NaN, zero, negated, halved and infinite operands anywhere: still the plain reduction."""
    ops, vals, tracked = operands(name, pop=4, scale=0.02, seed=seed)
    for i, j, k, edit in edits:
        j = j % vals.shape[1]
        vals[i, j, k] = EDITS[edit](vals[i, j, k])
    theta = sample_angles(n_samples)
    want = plain_reduce(ops, vals, theta, tracked)
    old = solver_numpy.BLOCK_ELEMENTS
    try:
        solver_numpy.BLOCK_ELEMENTS = block
        got = solver_numpy.reduce(ops, vals, theta, tracked, True)
    finally:
        solver_numpy.BLOCK_ELEMENTS = old
    assert_same_bits(got, want)


@pytest.mark.parametrize("joints", [False, True])
@pytest.mark.parametrize("name", NAMES)
def test_without_derivatives_the_positions_are_the_same_bits(name, joints):
    ops, vals, tracked = operands(name, pop=30, scale=0.2, seed=4, n_nan_rows=2)
    theta = sample_angles(60)
    full = solver_numpy.reduce(ops, vals, theta, tracked, joints, derivatives=True)
    lean = solver_numpy.reduce(ops, vals, theta, tracked, joints, derivatives=False)
    assert lean[1] is None and lean[3] is None
    assert full[3] is not None and np.isfinite(full[3]).any()
    if joints:
        assert_same_bits([lean[i] for i in (0, 2, 4, 5, 6, 7, 8)], [full[i] for i in (0, 2, 4, 5, 6, 7, 8)], POSITIONS)
    else:
        assert lean[0] is None and full[0] is None
        assert_same_bits(lean[2:3] + lean[4:], full[2:3] + full[4:], POSITIONS[1:])


@pytest.mark.parametrize("shape", [(0, 16), (3, 0)])
def test_empty_populations_and_cycles_have_the_kernels_shapes_and_values(shape):
    pop, n_samples = shape
    ops, vals, tracked = operands("stephenson1/X3", pop=max(pop, 1), scale=0.0, seed=0)
    vals = np.repeat(vals, pop, axis=0) if pop else vals[:0]
    theta = sample_angles(n_samples)
    got = solver_numpy.reduce(ops, vals, theta, tracked, True)
    want = solver_numba.run(ops, vals, theta, tracked, True, False)
    assert_same_bits(got, want)


def test_the_reference_does_not_load_numba():
    """The oracle checks the kernel, so it must not share code with it."""
    code = "import sys, core.kinematics.reference; assert 'numba' not in sys.modules, 'numba loaded'"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_a_later_reduce_never_writes_into_paths_still_held():
    # 400 designs x 360 samples: slabs above the size from which the reference keeps them.
    ops, vals_a, tracked = operands(NAMES[0], 400, 0.02, seed=1)
    _, vals_b, _ = operands(NAMES[0], 400, 0.02, seed=2)
    theta = sample_angles(360)
    first = solver_numpy.reduce(ops, vals_a, theta, tracked, False, False)[2]
    held = first[:, :, 1]  # a view of the slab: keeps it in use
    want = held.copy()
    slabs = {first.ctypes.data}
    del first
    second = solver_numpy.reduce(ops, vals_b, theta, tracked, False, False)[2]
    assert not np.shares_memory(second, held)
    np.testing.assert_array_equal(held, want)
    want_b = second.copy()
    slabs.add(second.ctypes.data)
    del held, second
    # Nothing refers to either slab any more: the next call reuses one, with the same values.
    third = solver_numpy.reduce(ops, vals_b, theta, tracked, False, False)[2]
    assert third.ctypes.data in slabs
    np.testing.assert_array_equal(third, want_b)
