"""Reference interpreter of a compiled mechanism in plain numpy (the test oracle).

Vectorized over the population and the samples, one construction step at a time. For speed
only, each point is held as contiguous x and y arrays ``(designs, n_samples)`` and the
population is solved in blocks that stay in cache; the arithmetic is exactly the plain
vector formulas of the model (same operations in the same order, so the same bits).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from core.mechanisms.model import ATTACH, CRANK, DYAD, GROUND

F64 = NDArray[np.float64]

# Elements (designs x samples) per block: a step's temporaries then fit in the L2 cache.
BLOCK_ELEMENTS = 8192


def rot90(v: F64) -> F64:
    """``(-v_y, v_x)`` on the trailing axis."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def dot(a: F64, b: F64) -> F64:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def cross(a: F64, b: F64) -> F64:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def run(ops: NDArray[np.int64], vals: F64, theta: F64) -> tuple[F64, F64, F64, F64, F64]:
    """Place every point for every design and sample.

    Args:
        ops: ``(n_steps, 4)`` compiled step rows (see ``Program``).
        vals: ``(pop, n_steps, 3)`` operand values (mm, rad).
        theta: ``(n_samples,)`` input crank angles (rad).

    Returns:
        pos, dpos: ``(pop, n_samples, n_joints, 2)`` positions (mm) and d/dtheta (mm/rad).
        margin: ``(pop, n_samples, n_steps)`` assembly margin of each dyad
            ``min(d - |l1 - l2|, l1 + l2 - d)`` (mm; NaN for other steps).
        cos_mu: ``(pop, n_samples, n_steps)`` cosine of each dyad's transmission angle.
        neg: ``(pop,)`` total amount by which dyad lengths are negative (mm).
    """
    pop, n_steps = vals.shape[:2]
    n = theta.shape[0]
    pos = np.full((pop, n, n_steps, 2), np.nan)
    dpos = np.full((pop, n, n_steps, 2), np.nan)
    margin = np.full((pop, n, n_steps), np.nan)
    cos_mu = np.full((pop, n, n_steps), np.nan)
    neg = np.zeros(pop)
    step = max(1, BLOCK_ELEMENTS // max(n, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        for i0 in range(0, pop, step):
            rows = slice(i0, min(pop, i0 + step))
            _run_block(ops, vals[rows], theta, pos[rows], dpos[rows], margin[rows], cos_mu[rows], neg[rows])
    return pos, dpos, margin, cos_mu, neg


def _run_block(ops: NDArray[np.int64], vals: F64, theta: F64, pos: F64, dpos: F64, margin: F64, cos_mu: F64,
               neg: F64) -> None:
    """Solve a block of designs into views of the outputs (``neg`` accumulated in place)."""
    pop = vals.shape[0]
    n = theta.shape[0]
    # Per point: x, y, dx, dy as (pop, n) arrays; NaN until placed, as in the outputs.
    nan = np.full((pop, n), np.nan)
    x, y, dx, dy = ([nan] * len(ops) for _ in range(4))
    for j, (kind, a, b, side) in enumerate(ops):
        v0, v1, v2 = (vals[:, j, k][:, None] for k in range(3))
        if kind == GROUND:
            c, s = np.cos(v2), np.sin(v2)
            gx, gy = c * v0 - s * v1, s * v0 + c * v1
            x[j] = np.broadcast_to(gx, (pop, n)) + (x[a] if a >= 0 else 0.0)
            y[j] = np.broadcast_to(gy, (pop, n)) + (y[a] if a >= 0 else 0.0)
            dx[j] = dy[j] = np.zeros((pop, n))
        elif kind == CRANK:
            phi = v2 + theta[None, :]
            c, s = np.cos(phi), np.sin(phi)
            rx, ry = c * v0 - s * v1, s * v0 + c * v1
            x[j], y[j] = x[a] + rx, y[a] + ry
            dx[j], dy[j] = -ry, rx
        elif kind == DYAD:
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            l1, l2 = v0, v1
            neg += np.maximum(0.0, -vals[:, j, 0]) + np.maximum(0.0, -vals[:, j, 1])
            wx, wy = qx - px, qy - py
            d2 = wx * wx + wy * wy
            d = np.sqrt(d2)
            ex, ey = wx / d, wy / d
            along = (l1 * l1 - l2 * l2 + d2) / (2.0 * d)
            sh = side * np.sqrt(l1 * l1 - along * along)
            # p + along e + (side h) rot90(e), rot90(e) = (-e_y, e_x)
            xx = px + along * ex + sh * -ey
            xy = py + along * ey + sh * ex
            a1x, a1y, a2x, a2y = xx - px, xy - py, xx - qx, xy - qy
            r1 = a1x * dx[a] + a1y * dy[a]
            r2 = a2x * dx[b] + a2y * dy[b]
            det = a1x * a2y - a1y * a2x
            x[j], y[j] = xx, xy
            dx[j], dy[j] = (r1 * a2y - r2 * a1y) / det, (a1x * r2 - a2x * r1) / det
            margin[:, :, j] = np.minimum(d - np.abs(l1 - l2), l1 + l2 - d)
            cos_mu[:, :, j] = (l1 * l1 + l2 * l2 - d2) / (2.0 * l1 * l2)
        elif kind == ATTACH:
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            wx, wy = qx - px, qy - py
            length = np.sqrt(wx * wx + wy * wy)
            ex, ey = wx / length, wy / length
            dwx, dwy = dx[b] - dx[a], dy[b] - dy[a]
            t = ex * dwx + ey * dwy
            dex, dey = (dwx - ex * t) / length, (dwy - ey * t) / length
            # p + u e + v rot90(e), and its derivative
            x[j], y[j] = px + v0 * ex + v1 * -ey, py + v0 * ey + v1 * ex
            dx[j], dy[j] = dx[a] + v0 * dex + v1 * -dey, dy[a] + v0 * dey + v1 * dex
        else:
            continue
        pos[:, :, j, 0], pos[:, :, j, 1] = x[j], y[j]
        dpos[:, :, j, 0], dpos[:, :, j, 1] = dx[j], dy[j]
