"""Metric quantisation by hand: 10 significant digits, never finer than 1e-9; NaN and inf unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from core.optimize.objectives import quantize


@pytest.mark.parametrize(("value", "expected"), [
    (1.23456789012345, 1.234567890),  # 10 significant digits
    (-1.23456789016, -1.234567890),
    (123456.789012345, 123456.7890),
    (9.87654321098e7, 98765432.11),
    (3.4e-11, 0.0),  # below the 1e-9 floor
    (1.23456e-8, 1.2e-8),  # steps of 1e-9, not 10 significant digits
    (0.0, 0.0),
])
def test_quantize_by_hand(value: float, expected: float) -> None:
    assert quantize(np.array([value]))[0] == pytest.approx(expected, rel=1e-14, abs=1e-20)


def test_noise_below_the_tenth_digit_compares_equal_and_specials_pass() -> None:
    a, b = quantize(np.array([2.0 / 3.0, 2.0 / 3.0 + 1e-14]))
    assert a == b
    out = quantize(np.array([np.nan, np.inf, -np.inf]))
    assert np.isnan(out[0]) and out[1] == np.inf and out[2] == -np.inf
