"""Reference interpreter of a compiled mechanism in plain numpy (the test oracle).

Vectorized over the population and the samples, one construction step at a time.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from core.mechanisms.model import ATTACH, CRANK, DYAD, GROUND

F64 = NDArray[np.float64]


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
    with np.errstate(invalid="ignore", divide="ignore"):
        for j, (kind, a, b, side) in enumerate(ops):
            v0, v1, v2 = (vals[:, j, k][:, None] for k in range(3))
            if kind == GROUND:
                c, s = np.cos(v2), np.sin(v2)
                x = np.stack([c * v0 - s * v1, s * v0 + c * v1], axis=-1)
                x = np.broadcast_to(x, (pop, n, 2))
                pos[:, :, j] = x + (pos[:, :, a] if a >= 0 else 0.0)
                dpos[:, :, j] = 0.0
            elif kind == CRANK:
                phi = v2 + theta[None, :]
                c, s = np.cos(phi), np.sin(phi)
                r = np.stack([c * v0 - s * v1, s * v0 + c * v1], axis=-1)
                pos[:, :, j] = pos[:, :, a] + r
                dpos[:, :, j] = rot90(r)
            elif kind == DYAD:
                p, q = pos[:, :, a], pos[:, :, b]
                l1, l2 = v0, v1
                neg += np.maximum(0.0, -vals[:, j, 0]) + np.maximum(0.0, -vals[:, j, 1])
                w = q - p
                d2 = dot(w, w)
                d = np.sqrt(d2)
                e = w / d[..., None]
                along = (l1 * l1 - l2 * l2 + d2) / (2.0 * d)
                h = np.sqrt(l1 * l1 - along * along)
                x = p + along[..., None] * e + (side * h)[..., None] * rot90(e)
                a1, a2 = x - p, x - q
                r1, r2 = dot(a1, dpos[:, :, a]), dot(a2, dpos[:, :, b])
                det = cross(a1, a2)
                dx = np.stack(
                    [(r1 * a2[..., 1] - r2 * a1[..., 1]) / det, (a1[..., 0] * r2 - a2[..., 0] * r1) / det], -1
                )
                pos[:, :, j] = x
                dpos[:, :, j] = dx
                margin[:, :, j] = np.minimum(d - np.abs(l1 - l2), l1 + l2 - d)
                cos_mu[:, :, j] = (l1 * l1 + l2 * l2 - d2) / (2.0 * l1 * l2)
            elif kind == ATTACH:
                p, q = pos[:, :, a], pos[:, :, b]
                dp, dq = dpos[:, :, a], dpos[:, :, b]
                w = q - p
                length = np.sqrt(dot(w, w))
                e = w / length[..., None]
                dw = dq - dp
                de = (dw - e * dot(e, dw)[..., None]) / length[..., None]
                pos[:, :, j] = p + v0[..., None] * e + v1[..., None] * rot90(e)
                dpos[:, :, j] = dp + v0[..., None] * de + v1[..., None] * rot90(de)
    return pos, dpos, margin, cos_mu, neg
