"""Reference interpreter of a compiled mechanism in plain numpy (the test oracle).

Vectorized over the population and the samples, one construction step at a time, with the
plain vector formulas of the model (``core.mechanisms.model``); ``core.solver_numba`` is the
fast kernel it checks and shares no arithmetic with. For speed only: the population is solved
in blocks of designs whose points stay in cache, each coordinate an array ``(designs,
n_samples)``, and ``reduce`` keeps of a block only the tracked point and the cycle statistics.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from core.mechanisms.model import ATTACH, CRANK, DYAD, GROUND

F64 = NDArray[np.float64]

# Elements (designs x samples) per block: every array of a block is below 128 KiB, glibc's
# default threshold above which each allocation is a fresh mapping, faulted in page by page.
BLOCK_ELEMENTS = 16000


def place(ops: NDArray[np.int64], vals: F64, theta: F64, store: F64) -> Iterator[tuple[int, F64, F64]]:
    """Place the points of a block of designs, step by step.

    Args:
        ops: ``(n_steps, 4)`` checked step rows ``[kind, a, b, side]`` (see ``Program``).
        vals: ``(designs, n_steps, 3)`` operand values (mm, rad).
        theta: ``(n_samples,)`` input crank angles (rad).
        store: ``(n_steps, 4, designs, n_samples)``, filled with x, y, dx, dy of every point
            (mm, mm/rad); with 2 rows instead of 4, positions only (no derivative work).

    Yields:
        For each dyad, once placed: its index, its assembly margin ``min(d - |l1 - l2|,
        l1 + l2 - d)`` (mm) and the cosine of its transmission angle, each ``(designs,
        n_samples)``, with d = |PQ|.
    """
    derivatives = store.shape[1] == 4
    x, y = store[:, 0], store[:, 1]
    dx, dy = (store[:, 2], store[:, 3]) if derivatives else (store[:, :0], store[:, :0])
    cs = np.stack([np.cos(theta), np.sin(theta)])
    for j, (kind, a, b, side) in enumerate(ops):
        v0, v1, v2 = vals[:, j, 0:1], vals[:, j, 1:2], vals[:, j, 2:3]
        if kind == GROUND:
            # X = O + R(angle) (u, v), fixed over the cycle.
            cg, sg = np.cos(v2), np.sin(v2)
            x[j] = cg * v0 - sg * v1 + (x[a] if a >= 0 else 0.0)
            y[j] = sg * v0 + cg * v1 + (y[a] if a >= 0 else 0.0)
            if derivatives:
                dx[j], dy[j] = 0.0, 0.0
        elif kind == CRANK:
            # X = O + R(phase + theta) (u, v) = O + R(theta) r with r = R(phase) (u, v); dX = rot90(X - O).
            cp, sp = np.cos(v2), np.sin(v2)
            rx, ry = rotate(cp * v0 - sp * v1, sp * v0 + cp * v1, cs)
            np.add(x[a], rx, out=x[j])
            np.add(y[a], ry, out=y[j])
            if derivatives:
                np.negative(ry, out=dx[j])
                dy[j] = rx
        elif kind == DYAD:
            # X = P + along e + (side h) rot90(e), e = (Q - P) / d, rot90(e) = (-e_y, e_x).
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            l1, l2 = v0, v1
            wx, wy = qx - px, qy - py
            d2 = wx * wx + wy * wy
            d = np.sqrt(d2)
            ex, ey = wx / d, wy / d
            along = (l1 * l1 - l2 * l2 + d2) / (2.0 * d)
            sh = side * np.sqrt(l1 * l1 - along * along)
            np.subtract(px + along * ex, sh * ey, out=x[j])
            np.add(py + along * ey, sh * ex, out=y[j])
            if derivatives:
                # Differentiate |X - P|^2 = l1^2, |X - Q|^2 = l2^2: a 2 x 2 system in dX.
                a1x, a1y, a2x, a2y = x[j] - px, y[j] - py, x[j] - qx, y[j] - qy
                r1 = a1x * dx[a] + a1y * dy[a]
                r2 = a2x * dx[b] + a2y * dy[b]
                det = a1x * a2y - a1y * a2x
                np.divide(r1 * a2y - r2 * a1y, det, out=dx[j])
                np.divide(a1x * r2 - a2x * r1, det, out=dy[j])
            yield j, np.minimum(d - np.abs(l1 - l2), l1 + l2 - d), (l1 * l1 + l2 * l2 - d2) / (2.0 * l1 * l2)
        else:  # ATTACH: X = P + u e + v rot90(e), e = (Q - P) / |Q - P|.
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            wx, wy = qx - px, qy - py
            length = np.sqrt(wx * wx + wy * wy)
            ex, ey = wx / length, wy / length
            np.subtract(px + v0 * ex, v1 * ey, out=x[j])
            np.add(py + v0 * ey, v1 * ex, out=y[j])
            if derivatives:
                # de = (dw - e (e . dw)) / |w|
                dwx, dwy = dx[b] - dx[a], dy[b] - dy[a]
                t = ex * dwx + ey * dwy
                dex, dey = (dwx - ex * t) / length, (dwy - ey * t) / length
                np.subtract(dx[a] + v0 * dex, v1 * dey, out=dx[j])
                np.add(dy[a] + v0 * dey, v1 * dex, out=dy[j])


def rotate(rx: F64, ry: F64, cs: F64) -> tuple[F64, F64]:
    """``R(theta) r`` for every design and sample: x and y ``(designs, n)`` from r ``(designs, 1)``
    and ``cs = (cos theta, sin theta)`` ``(2, n)``.

    As a stack of 2 x 2 products ``[[r_x, -r_y], [r_y, r_x]] @ cs``: numpy broadcasts a column
    against a row about three times slower, and a stacked matmul gives each design the same
    bits whatever the batch (a single 2-D matmul would not).
    """
    m = np.stack([np.concatenate([rx, -ry], axis=1), np.concatenate([ry, rx], axis=1)], axis=1)
    out = m @ cs
    return out[:, 0], out[:, 1]


def check(ops: NDArray[np.int64], tracked: int | None = None) -> None:
    """Reject a malformed program (a step of unknown kind, or using a later or missing point).

    Raises:
        ValueError: naming the first bad step.
    """
    if ops.ndim != 2 or ops.shape[1] != 4:
        raise ValueError(f"malformed program: ops of shape {ops.shape}")
    if tracked is not None and not 0 <= tracked < len(ops):
        raise ValueError(f"malformed program: tracked point {tracked} of {len(ops)}")
    for j, (kind, a, b, _) in enumerate(ops):
        uses_a = kind in (CRANK, DYAD, ATTACH) or a >= 0
        uses_b = kind in (DYAD, ATTACH)
        if kind not in (GROUND, CRANK, DYAD, ATTACH) or (uses_a and not 0 <= a < j) or (uses_b and not 0 <= b < j):
            raise ValueError(f"malformed program: step {j} has an unknown kind or point")


def negative_lengths(ops: NDArray[np.int64], vals: F64) -> F64:
    """``(pop,)`` total amount by which dyad lengths are negative (mm); NaN where one is NaN."""
    neg = np.zeros(vals.shape[0])
    for j in np.flatnonzero(ops[:, 0] == DYAD):
        neg += np.maximum(0.0, -vals[:, j, 0]) + np.maximum(0.0, -vals[:, j, 1])
    return neg


def blocks(pop: int, n_samples: int) -> Iterator[slice]:
    """Row slices of at most ``block_rows(n_samples)`` designs."""
    step = block_rows(n_samples)
    for i0 in range(0, pop, step):
        yield slice(i0, min(pop, i0 + step))


def block_rows(n_samples: int) -> int:
    """Designs per block: ``BLOCK_ELEMENTS // n_samples``, at least one."""
    return max(1, BLOCK_ELEMENTS // max(n_samples, 1))


def run(ops: NDArray[np.int64], vals: F64, theta: F64) -> tuple[F64, F64, F64, F64, F64]:
    """Every point and the dyads' statistics, for every design and sample.

    Args:
        ops: ``(n_steps, 4)`` compiled step rows (see ``Program``).
        vals: ``(pop, n_steps, 3)`` operand values (mm, rad).
        theta: ``(n_samples,)`` input crank angles (rad).

    Returns:
        pos, dpos: ``(pop, n_samples, n_steps, 2)`` positions (mm) and d/dtheta (mm/rad).
        margin: ``(pop, n_samples, n_steps)`` assembly margin of each dyad
            ``min(d - |l1 - l2|, l1 + l2 - d)`` (mm; NaN for other steps).
        cos_mu: ``(pop, n_samples, n_steps)`` cosine of each dyad's transmission angle.
        neg: ``(pop,)`` total amount by which dyad lengths are negative (mm).

    Raises:
        ValueError: for a malformed program.
    """
    check(ops)
    pop, n_steps = vals.shape[:2]
    n = theta.shape[0]
    pos, dpos = np.empty((pop, n, n_steps, 2)), np.empty((pop, n, n_steps, 2))
    margin, cos_mu = np.full((pop, n, n_steps), np.nan), np.full((pop, n, n_steps), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        for rows in blocks(pop, n):
            store = np.empty((n_steps, 4, rows.stop - rows.start, n))
            for j, m, c in place(ops, vals[rows], theta, store):
                margin[rows, :, j], cos_mu[rows, :, j] = m, c
            pos[rows] = store[:, :2].transpose(2, 3, 0, 1)
            dpos[rows] = store[:, 2:].transpose(2, 3, 0, 1)
    return pos, dpos, margin, cos_mu, negative_lengths(ops, vals)


def reduce(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, want_joints: bool, derivatives: bool = True
) -> tuple[F64 | None, F64 | None, F64, F64 | None, NDArray[np.bool_], F64, F64, F64, F64]:
    """``run`` reduced to the outputs of ``core.solver_numba.run`` (see there for shapes).

    mmin, cmin, cmax are the min or max over samples ignoring NaN (+inf, +inf, -inf where no
    sample has a value, and for steps other than dyads); valid is True where every coordinate
    of every point is finite.

    Args:
        ops, vals, theta: see ``run``.
        tracked: index of the tracked point.
        want_joints: also return every joint (else None for pos and dpos).
        derivatives: also compute d/dtheta (else None for dpos and dpoint, and no work for them).

    Returns:
        pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg.

    Raises:
        ValueError: for a malformed program.
    """
    check(ops, tracked)
    pop, n_steps = vals.shape[:2]
    n = theta.shape[0]
    pos = np.empty((pop, n, n_steps, 2)) if want_joints else None
    dpos = np.empty((pop, n, n_steps, 2)) if want_joints and derivatives else None
    # The paths and the points of a block (reused from block to block) in one allocation: glibc
    # keeps freed memory up to twice the largest block recently freed, so the next call reuses
    # it instead of faulting fresh pages in.
    n_paths, n_coords = (2, 4) if derivatives else (1, 2)
    n_rows = min(pop, block_rows(n))
    slab = np.empty(n_paths * pop * n * 2 + n_steps * n_coords * n_rows * n)
    paths = slab[: n_paths * pop * n * 2].reshape(n_paths, pop, n, 2)
    store = slab[n_paths * pop * n * 2 :].reshape(n_steps, n_coords, n_rows, n)
    point, dpoint = paths[0], (paths[1] if derivatives else None)
    valid = np.empty((pop, n), dtype=np.bool_)
    mmin, cmin = np.full((pop, n_steps), np.inf), np.full((pop, n_steps), np.inf)
    cmax = np.full((pop, n_steps), -np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        for rows in blocks(pop, n):
            block = store[:, :, : rows.stop - rows.start]
            for j, margin, cos_mu in place(ops, vals[rows], theta, block):
                # fmin and fmax skip NaN.
                np.fmin.reduce(margin, axis=1, initial=np.inf, out=mmin[rows, j])
                np.fmin.reduce(cos_mu, axis=1, initial=np.inf, out=cmin[rows, j])
                np.fmax.reduce(cos_mu, axis=1, initial=-np.inf, out=cmax[rows, j])
            valid[rows] = np.isfinite(block[:, :2]).all(axis=(0, 1))
            # Coordinate by coordinate: one strided copy each (a transposed copy is slower).
            for k in range(2):
                point[rows, :, k] = block[tracked, k]
                if dpoint is not None:
                    dpoint[rows, :, k] = block[tracked, 2 + k]
                if pos is not None:
                    pos[rows, :, :, k] = block[:, k].transpose(1, 2, 0)
                if dpos is not None:
                    dpos[rows, :, :, k] = block[:, 2 + k].transpose(1, 2, 0)
    return pos, dpos, point, dpoint, valid, mmin, cmin, cmax, negative_lengths(ops, vals)
