"""Checks at the public API's boundary: argument types and ranges, with errors that name the argument.

The hot path never raises on odd *designs* (NaN rows and a violation); these checks refuse odd *calls*
(a sample count of 0, a NaN period, strings as parameters) before any work, with ValueError or TypeError.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
from numpy.typing import NDArray

MAX_SAMPLES = 100_000  # joints alone take n_samples * n_joints * 32 bytes per design
BACKENDS = ("auto", "numpy", "numba")


def samples(n: Any, minimum: int = 1, even: bool = False, name: str = "n_samples") -> int:
    """``n`` as an int in [minimum, MAX_SAMPLES] (and even, if asked)."""
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {type(n).__name__} {n!r}")
    n = int(n)
    if not minimum <= n <= MAX_SAMPLES:
        raise ValueError(f"{name} must be between {minimum} and {MAX_SAMPLES}, got {n}")
    if even and n % 2:
        raise ValueError(f"{name} must be even (t + T/2 must fall on a sample), got {n}")
    return n


def backend(b: Any) -> str:
    if b not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {b!r}")
    return str(b)


def real_array(values: Any, name: str = "params") -> NDArray[np.float64]:
    """Real numbers as a float64 array (a copy); TypeError for strings, booleans, complex, dates or objects."""
    if isinstance(values, str | bytes):
        raise TypeError(f"{name} must be real numbers, got a string")
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as e:  # ragged nesting
        raise TypeError(f"{name} must be a rectangular array of real numbers ({e})") from None
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be real numbers (float or int), got dtype {a.dtype}")
    return np.array(a, dtype=np.float64)


def real(x: Any, name: str, positive: bool = False, nonnegative: bool = False) -> float:
    """A finite real number (optionally > 0 or >= 0); bools and strings are refused."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    if nonnegative and not v >= 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    return v
