"""Shape error: mean Euclidean distance sample i against sample i, and its best-cyclic-shift variant."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis.shape import mse, mse_phase_optimal
from core.analysis.targets import compound_cycloid

TARGET = compound_cycloid(120)[0]


@settings(max_examples=30, deadline=None)
@given(st.floats(-100, 100), st.floats(-100, 100), st.integers(0, 119))
def test_closed_forms(dx: float, dy: float, k: int) -> None:
    # a curve against itself is 0; against a translated copy, exactly the translation's length
    assert mse(TARGET, TARGET)[0] == 0.0
    assert mse(TARGET + [dx, dy], TARGET)[0] == pytest.approx(np.hypot(dx, dy), abs=1e-9)
    # a cyclically shifted copy is 0 at the right shift
    err, shift = mse_phase_optimal(np.roll(TARGET, k, 0), TARGET)
    assert err[0] == pytest.approx(0.0, abs=1e-12)
    assert shift[0] == (-k) % 120 or mse(np.roll(TARGET, k, 0), np.roll(TARGET, -shift[0], 0))[0] == 0.0


def test_phase_optimal_is_the_minimum_over_shifts_and_batches() -> None:
    rng = np.random.default_rng(0)
    pop = TARGET[None] + rng.normal(0, 5, (5, 120, 2))
    pop[3] = np.roll(pop[3], 40, 0)
    pop[4, 7] = np.nan
    err, shift = mse_phase_optimal(pop, TARGET)
    aligned = mse(pop, TARGET)
    for i in range(4):
        every = [mse(pop[i], np.roll(TARGET, -k, 0))[0] for k in range(120)]
        assert err[i] == pytest.approx(min(every), rel=1e-12)
        assert every[shift[i]] == pytest.approx(err[i], rel=1e-12)
        assert err[i] <= aligned[i]
    assert shift[3] == 80
    assert np.isnan(err[4]) and np.isnan(aligned[4])


def test_shapes_must_match() -> None:
    with pytest.raises(ValueError, match="same"):
        mse(TARGET, TARGET[:-1])


@settings(max_examples=60, deadline=None)
@given(st.integers(3, 48), st.integers(1, 4), st.integers(0, 2**32 - 1), st.booleans())
def test_the_compiled_search_matches_every_shift_tried_in_numpy(n: int, pop: int, seed: int, periodic: bool) -> None:
    # The kernel stops a shift's sum once it passes the best so far and starts from a coarse guess; the answer
    # must still be the exhaustive one: the least error, at the smallest shift that gives it.
    rng = np.random.default_rng(seed)
    target = rng.normal(0, 50, (n, 2))
    noise = rng.normal(0, 3, (pop, n, 2))
    if periodic and n % 3 == 0:  # path and target made of three equal thirds: three shifts tie (up to rounding)
        target = np.tile(target[: n // 3], (3, 1))
        noise = np.tile(noise[:, : n // 3], (1, 3, 1))
    paths = np.roll(target, rng.integers(0, n), 0)[None] + noise
    if pop > 1:
        paths[-1, rng.integers(0, n)] = np.nan
    err, shift = mse_phase_optimal(paths, target)
    for j in range(pop):
        every = np.array([mse(paths[j], np.roll(target, -k, 0))[0] for k in range(n)])
        if np.isnan(every).all():
            assert np.isnan(err[j]) and shift[j] == 0
            continue
        assert err[j] == every[shift[j]]  # the error at that shift, summed as mse sums it
        assert err[j] <= every.min() * (1 + 1e-12)  # the least, up to the order of a sum's terms
