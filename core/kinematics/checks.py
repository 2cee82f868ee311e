"""Checks at the public API's boundary: argument types and ranges, with errors that name the argument.

The hot path never raises on odd *designs* (NaN rows and a violation); these checks refuse odd *calls*
(a sample count of 0, a NaN period, strings as parameters) before any work, with ValueError or TypeError.
Array checks are O(size) vectorized numpy: they cost nothing next to a solve.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
from numpy.typing import NDArray

MAX_SAMPLES = 100_000  # joints alone take n_samples * n_joints * 32 bytes per design
BACKENDS = ("auto", "numpy", "numba")
# The largest magnitude (mm, rad, s) a scalar argument may take: beyond a kilometre the geometry is
# floating-point noise, and 1e300-sized periods or ratios overflow speeds to inf.
MAX_ABS = 1e6


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


def flag(x: Any, name: str) -> bool:
    """A boolean (Python or numpy); 'no', 0 or None are refused rather than read by truthiness."""
    if not isinstance(x, bool | np.bool_):
        raise TypeError(f"{name} must be true or false, got {type(x).__name__} {x!r}")
    return bool(x)


def instance(x: Any, cls: type, name: str) -> None:
    """TypeError naming the argument unless ``x`` is a ``cls``."""
    if not isinstance(x, cls):
        article = "an" if cls.__name__[0] in "AEIOU" else "a"
        raise TypeError(f"{name} must be {article} {cls.__name__}, got {type(x).__name__}")


def real_array(values: Any, name: str = "params", copy: bool = True) -> NDArray[np.float64]:
    """Real numbers as a float64 array (a copy, unless ``copy=False`` and ``values`` already is one).

    Floats of any width and integers convert (an integer length is a length); strings, booleans,
    complex numbers, dates, ``Decimal`` and other objects raise TypeError, as do masked entries
    (a mask would be dropped silently).
    """
    if isinstance(values, str | bytes):
        raise TypeError(f"{name} must be real numbers, got a string")
    if isinstance(values, np.ma.MaskedArray) and np.ma.is_masked(values):
        raise TypeError(f"{name} must be real numbers, got a masked array with masked entries")
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as e:  # ragged nesting
        raise TypeError(f"{name} must be a rectangular array of real numbers ({e})") from None
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be real numbers (float or int), got dtype {a.dtype}")
    return np.array(a, dtype=np.float64) if copy else np.asarray(a, dtype=np.float64)


def real(x: Any, name: str, positive: bool = False, nonnegative: bool = False, maximum: float = math.inf) -> float:
    """A finite real number (optionally > 0 or >= 0, and <= maximum); bools and strings are refused."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    if nonnegative and not v >= 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    if not v <= maximum:
        raise ValueError(f"{name} must be <= {maximum:g}, got {v:g}")
    return v


def pair(x: Any, name: str) -> tuple[Any, Any]:
    """Two items (a tuple, list or array of length 2); TypeError/ValueError naming the argument."""
    if isinstance(x, str | bytes) or not hasattr(x, "__len__"):
        raise TypeError(f"{name} must be a pair of numbers, got {type(x).__name__} {x!r}")
    if len(x) != 2:
        raise ValueError(f"{name} must be a pair of numbers, got {len(x)} values")
    return x[0], x[1]
