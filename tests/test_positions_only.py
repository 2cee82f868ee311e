"""``solve(..., derivatives=False)``: the same paths and cycle statistics, no derivatives, on both backends."""

from __future__ import annotations

import numpy as np
import pytest

from core.kinematics.mechanisms import MECHANISMS
from core.kinematics.presets import PAPER_PANTOGRAPH, PRESETS
from core.kinematics.solver import solve

TOL = 1e-9
SAME = ("point", "leg", "violation", "dyad_margin", "mu_min", "mu_max", "crank_margin")


def population(name: str, pop: int = 40, seed: int = 3) -> np.ndarray:
    """A preset of the mechanism, jittered by 0.1 % (first ten) or 8 % (some unassemblable), one row NaN,
    one with a negative length."""
    preset = next(p for p in PRESETS.values() if p.mechanism.name == name and solve(p.mechanism, p.values).feasible[0])
    rng = np.random.default_rng(seed)
    scale = np.where(np.arange(pop) < 10, 0.001, 0.08)[:, None]
    params = np.asarray(preset.values) * (1.0 + scale * rng.standard_normal((pop, preset.mechanism.n_params)))
    params[1, 0] = np.nan
    params[2, 1] = -abs(params[2, 1])
    return params


def close(got: np.ndarray, want: np.ndarray, what: str) -> None:
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want), err_msg=f"{what}: NaN pattern")
    fin = np.isfinite(want)
    np.testing.assert_array_equal(got[~fin & ~np.isnan(want)], want[~fin & ~np.isnan(want)], err_msg=what)
    err = np.abs(got[fin] - want[fin]) / (1.0 + np.abs(want[fin]))
    assert err.max(initial=0.0) <= TOL, f"{what}: max relative error {err.max():.3g}"


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_paths_match_the_full_solve(name: str, backend: str) -> None:
    m = MECHANISMS[name]
    params = population(name)
    full = solve(m, params, 90, output=PAPER_PANTOGRAPH, joints=True, backend=backend)
    fast = solve(m, params, 90, output=PAPER_PANTOGRAPH, joints=True, derivatives=False, backend=backend)
    assert fast.dpoint is None and fast.dleg is None and fast.djoints is None
    assert fast.joints is not None and full.joints is not None
    for field in SAME:
        close(getattr(fast, field), getattr(full, field), field)
    close(fast.joints, full.joints, "joints")
    np.testing.assert_array_equal(fast.valid, full.valid)
    np.testing.assert_array_equal(fast.feasible, full.feasible)
    # The population mixes assemblable and broken designs, so the comparison covers both.
    assert fast.feasible.any() and not fast.feasible.all()


def test_backends_agree_without_derivatives() -> None:
    m = MECHANISMS["stephenson1"]
    params = population("stephenson1", pop=64, seed=5)
    a = solve(m, params, 120, output=PAPER_PANTOGRAPH, joints=False, derivatives=False, backend="numba")
    b = solve(m, params, 120, output=PAPER_PANTOGRAPH, joints=False, derivatives=False, backend="numpy")
    assert a.joints is None and b.joints is None
    for field in SAME:
        close(getattr(a, field), getattr(b, field), field)
    np.testing.assert_array_equal(a.valid, b.valid)


def test_one_design_is_a_population_of_one() -> None:
    preset = PRESETS["stephenson1/X3"]
    one = solve(preset.mechanism, np.asarray(preset.values), 360, output=preset.output, derivatives=False)
    many = solve(preset.mechanism, np.tile(preset.values, (3, 1)), 360, output=preset.output, derivatives=False)
    assert one.point.shape == (1, 360, 2)
    np.testing.assert_array_equal(many.point[1], one.point[0])
    width = one.point[0, :, 0].max() - one.point[0, :, 0].min()
    assert abs(width - 298.94) < 0.05


def test_a_later_solve_never_writes_into_paths_still_held() -> None:
    # 400 designs x 360 samples: path blocks above the size from which the kernel keeps them.
    m = MECHANISMS["stephenson1"]
    a, b = population("stephenson1", pop=400, seed=7), population("stephenson1", pop=400, seed=8)
    first = solve(m, a, 360, output=PAPER_PANTOGRAPH, joints=False, derivatives=False)
    held = first.point[:, :, 1]  # a view of the block: keeps it in use
    want = held.copy()
    blocks = {first.point.ctypes.data}
    del first
    second = solve(m, b, 360, output=PAPER_PANTOGRAPH, joints=False, derivatives=False)
    assert not np.shares_memory(second.point, held)
    np.testing.assert_array_equal(held, want)
    want_b = second.point.copy()
    blocks.add(second.point.ctypes.data)
    del held, second
    # Nothing refers to either block any more: the next solve reuses one, with correct values.
    third = solve(m, b, 360, output=PAPER_PANTOGRAPH, joints=False, derivatives=False)
    assert third.point.ctypes.data in blocks
    np.testing.assert_array_equal(third.point, want_b)
