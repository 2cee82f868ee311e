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
