"""The size of a leg relative to the paper's: built-in millimetre figures follow the target's stride.

The paper designs a leg for a 300 mm stride (the cycloid's L). The mechanisms' global bounds, the
subtask boxes' minimum half-widths (20, 10, 5 mm), Eq. 20's ±10 mm band and the default limits of
Eqs. 22-23 are sized for it. For a target of width W every such figure is multiplied by
``k = W / 300`` (figures in mm^2 by k^2), so a leg half the size gets the same search at half the
size. Figures a user types (a configuration's limits, a box table's d, ``[bounds]``) are kept as typed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from core.kinematics.model import Mechanism
from core.kinematics.params import Param

F64 = NDArray[np.float64]

PAPER_STRIDE = 300.0  # mm: the width of the paper's target, the size every built-in figure is for
# A target this close to the paper's width is the paper's size: a CSV export of its cycloid reads 299.999 mm, and every
# bound and limit moved by a millionth ("the paper's x 1" in the notes).
SAME_SIZE = 1e-3
# The power of k a metric's limit scales with: lengths and speeds (mm, mm/s at the same period) k, areas k^2.
POWERS: dict[str, int] = {"f1": 1, "mse": 1, "f2": 2, "f3": 2, "h_s": 1, "I": 1, "l_s": 1, "width": 1,
                          "y_min": 1, "crank_margin": 1, "violation_mm": 1}


def stride_scale(width: float) -> float:
    """``k = width / 300``: the size of a leg whose target is ``width`` mm wide, relative to the paper's.

    1 (the paper's figures) within ``SAME_SIZE`` of it, and for a width that is not a positive finite number (a
    degenerate target).
    """
    w = float(width)
    k = w / PAPER_STRIDE if np.isfinite(w) and w > 0.0 else 1.0
    return 1.0 if abs(k - 1.0) < SAME_SIZE else k


def scaled_limit(metric: str, value: float, k: float) -> float:
    """A limit on ``metric`` given for the paper's leg, for a leg of scale ``k`` (S, angles: unchanged)."""
    return float(value) * float(k) ** POWERS.get(metric, 0)


def sized_bounds(mechanism: Mechanism, k: float = 1.0) -> tuple[F64, F64]:
    """``(n_params,)`` lower and upper global bounds for a leg of scale ``k`` (mm, rad).

    Every non-angle whose bounds are ``sized`` (the registered ones) is multiplied by k; angles and
    typed bounds are kept.
    """
    lo, hi = mechanism.lower.copy(), mechanism.upper.copy()
    if k != 1.0:
        m = np.array([p.sized and p.kind != "angle" for p in mechanism.params], dtype=bool)
        lo[m] *= k
        hi[m] *= k
    return lo, hi


def entry_bounds(param: Param, k: float = 1.0) -> tuple[float, float]:
    """The values a designer may type for ``param`` on a leg of scale ``k`` (mm; angles: their bounds).

    The paper's bounds and the same sized to the leg, whichever reaches further: a leg half the paper's
    size takes a 15 mm crank, and a design made for the paper's size still loads.
    """
    if not param.sized or param.kind == "angle" or k == 1.0:
        return param.lo, param.hi
    return min(param.lo, param.lo * k), max(param.hi, param.hi * k)
