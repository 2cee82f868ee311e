"""Reference interpreter of a compiled mechanism in plain numpy (the test oracle).

Vectorized over the population and the samples, one construction step at a time, with the
plain vector formulas of the model (``core.kinematics.model``); ``core.kinematics.kernel`` is the
fast kernel it checks and shares no arithmetic with. For speed only: the population is solved
in blocks of designs whose points stay in cache, each coordinate an array ``(designs,
n_samples)``, and ``reduce`` keeps of a block only the tracked point and the cycle statistics;
the per-design constants of every step are computed once per population (``Constants``), the
steps write into preallocated scratch rows (``out=``, no temporaries), and products of a
per-design 2 x 2 matrix with a point are stacked matrix products (numpy broadcasts a column
against a row about three times slower than it multiplies equal shapes).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from core.kinematics.blocks import Pool
from core.kinematics.model import ATTACH, CRANK, DYAD, GROUND

F64 = NDArray[np.float64]

# Elements (designs x samples) per block: every array of a block is below 128 KiB, glibc's
# default threshold above which each allocation is a fresh mapping, faulted in page by page.
BLOCK_ELEMENTS = 16000
# Scratch rows of ``place`` (each ``(designs, n_samples)``).
WORK_ROWS = 8


def place(
    ops: NDArray[np.int64], vals: F64, theta: F64, store: F64, work: F64 | None = None
) -> Iterator[tuple[int, F64, F64]]:
    """Place the points of a block of designs, step by step.

    Args:
        ops: ``(n_steps, 4)`` checked step rows ``[kind, a, b, side]`` (see ``Program``).
        vals: ``(designs, n_steps, 3)`` operand values (mm, rad).
        theta: ``(n_samples,)`` input crank angles (rad).
        store: ``(n_steps, 4, designs, n_samples)``, filled with x, y, dx, dy of every point
            (mm, mm/rad); with 2 rows instead of 4, positions only (no derivative work).
        work: ``(WORK_ROWS, designs, n_samples)`` scratch (allocated if None).

    Yields:
        For each dyad, once placed: its index, its assembly margin ``min(d - |l1 - l2|,
        l1 + l2 - d)`` (mm) and the cosine of its transmission angle, each ``(designs,
        n_samples)``, with d = |PQ|; valid until the next step.
    """
    if work is None:
        work = np.empty((WORK_ROWS,) + store.shape[2:])
    return steps(ops, constants(vals), angles(theta), store, work)


def chord(px: F64, py: F64, qx: F64, qy: F64, wx: F64, wy: F64, d2: F64, d: F64, ex: F64, ey: F64,
          tmp: F64) -> None:
    """Into the given rows: w = Q - P, d2 = |w|^2, d = |w| (may be d2's row), e = w / d (tmp: scratch,
    may be ex's row)."""
    np.subtract(qx, px, out=wx)
    np.subtract(qy, py, out=wy)
    np.multiply(wx, wx, out=d2)
    d2 += np.multiply(wy, wy, out=tmp)
    np.sqrt(d2, out=d)
    np.divide(wx, d, out=ex)
    np.divide(wy, d, out=ey)


class Constants(NamedTuple):
    """The per-design constants of every step of a population, computed at once (a few operations
    per population instead of several per step and block): ``(designs, n_steps)``, with u, v the
    operands 0 and 1 (for a dyad, l1 and l2), unless noted."""

    vals: F64  # (designs, n_steps, 3) the operands
    ru: F64  # R(angle) (u, v) of ground and crank steps
    rv: F64
    turn: F64  # (designs, n_steps, 2, 2) [[ru, -rv], [rv, ru]] (see ``rotate``)
    attach: F64  # (designs, n_steps, 2, 2) [[u, -v], [v, u]]
    k1: F64  # l1^2 - l2^2
    l1sq: F64  # l1^2
    dl: F64  # |l1 - l2|
    sl: F64  # l1 + l2
    s12: F64  # l1^2 + l2^2
    den: F64  # 2 l1 l2

    def rows(self, r: slice) -> Constants:
        return Constants(*(a[r] for a in self))


def constants(vals: F64) -> Constants:
    """``Constants`` of operands ``(designs, n_steps, 3)``."""
    u, v, angle = vals[:, :, 0], vals[:, :, 1], vals[:, :, 2]
    c, s = np.cos(angle), np.sin(angle)
    ru, rv = c * u - s * v, s * u + c * v
    uu, vv = u * u, v * v
    return Constants(
        vals, ru, rv, rotations(ru, rv), rotations(u, v), uu - vv, uu, np.abs(u - v), u + v, uu + vv, 2.0 * u * v
    )


def angles(theta: F64) -> F64:
    """``(2, n)`` cos and sin of the sample angles."""
    return np.stack([np.cos(theta), np.sin(theta)])


def steps(ops: NDArray[np.int64], k: Constants, cs: F64, store: F64, work: F64) -> Iterator[tuple[int, F64, F64]]:
    """``place`` from the block's ``Constants`` and ``cs = angles(theta)``, with scratch ``work``."""
    derivatives = store.shape[1] == 4
    x, y = store[:, 0], store[:, 1]
    dx, dy = (store[:, 2], store[:, 3]) if derivatives else (store[:, :0], store[:, :0])
    vals = k.vals
    for j, (kind, a, b, side) in enumerate(ops):
        v0, v1 = vals[:, j, 0:1], vals[:, j, 1:2]
        if kind == GROUND:
            # X = O + R(angle) (u, v), fixed over the cycle.
            np.add(k.ru[:, j : j + 1], x[a] if a >= 0 else 0.0, out=x[j])
            np.add(k.rv[:, j : j + 1], y[a] if a >= 0 else 0.0, out=y[j])
            if derivatives:
                dx[j], dy[j] = 0.0, 0.0
        elif kind == CRANK:
            # X = O + R(phase + theta) (u, v) = O + R(theta) r with r = R(phase) (u, v); dX = rot90(X - O).
            rx, ry = rotate(k.turn[:, j], cs, pair(work, 0))
            np.add(x[a], rx, out=x[j])
            np.add(y[a], ry, out=y[j])
            if derivatives:
                np.negative(ry, out=dx[j])
                dy[j] = rx
        elif kind == DYAD:
            # X = P + along e + (side h) rot90(e), e = (Q - P) / d, rot90(e) = (-e_y, e_x).
            # Written into the work rows (out=): no temporary arrays.
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            wx, wy, d2, d, ex, ey, along, sh = work[:8]
            chord(px, py, qx, qy, wx, wy, d2, d, ex, ey, tmp=ex)
            np.add(k.k1[:, j : j + 1], d2, out=along)
            along /= np.multiply(2.0, d, out=sh)
            np.multiply(along, along, out=sh)
            np.subtract(k.l1sq[:, j : j + 1], sh, out=sh)
            np.sqrt(sh, out=sh)
            if side != 1:
                sh *= side
            # x = (px + along ex) - sh ey, y = (py + along ey) + sh ex
            np.multiply(along, ex, out=x[j])
            x[j] += px
            x[j] -= np.multiply(sh, ey, out=wx)
            np.multiply(along, ey, out=y[j])
            y[j] += py
            y[j] += np.multiply(sh, ex, out=wx)
            if derivatives:
                # Differentiate |X - P|^2 = l1^2, |X - Q|^2 = l2^2: a 2 x 2 system in dX.
                a1x, a1y, a2x, a2y = x[j] - px, y[j] - py, x[j] - qx, y[j] - qy
                r1 = a1x * dx[a] + a1y * dy[a]
                r2 = a2x * dx[b] + a2y * dy[b]
                det = a1x * a2y - a1y * a2x
                np.divide(r1 * a2y - r2 * a1y, det, out=dx[j])
                np.divide(a1x * r2 - a2x * r1, det, out=dy[j])
            margin, cos_mu = wx, wy
            np.subtract(d, k.dl[:, j : j + 1], out=margin)
            np.minimum(margin, np.subtract(k.sl[:, j : j + 1], d, out=ex), out=margin)
            np.subtract(k.s12[:, j : j + 1], d2, out=cos_mu)
            cos_mu /= k.den[:, j : j + 1]
            yield j, margin, cos_mu
        else:  # ATTACH: X = P + u e + v rot90(e), e = (Q - P) / |Q - P|.
            px, py, qx, qy = x[a], y[a], x[b], y[b]
            wx, wy, length, tmp = work[:4]
            e = pair(work, 4)
            ex, ey = e[:, 0], e[:, 1]
            chord(px, py, qx, qy, wx, wy, length, length, ex, ey, tmp)
            # X - P = [[u, -v], [v, u]] e, as a stack of 2 x 2 products (see ``rotate``).
            r = np.matmul(k.attach[:, j], e, out=pair(work, 0))  # wx, wy are done with
            np.add(px, r[:, 0], out=x[j])
            np.add(py, r[:, 1], out=y[j])
            if derivatives:
                # de = (dw - e (e . dw)) / |w|
                dwx, dwy = dx[b] - dx[a], dy[b] - dy[a]
                t = ex * dwx + ey * dwy
                dex, dey = (dwx - ex * t) / length, (dwy - ey * t) / length
                np.subtract(dx[a] + v0 * dex, v1 * dey, out=dx[j])
                np.add(dy[a] + v0 * dey, v1 * dex, out=dy[j])


def pair(work: F64, row: int) -> F64:
    """Scratch rows row and row + 1 of ``work`` as one ``(designs, 2, n)`` array."""
    return work[row : row + 2].reshape(work.shape[1], 2, work.shape[2])


def rotate(m: F64, cs: F64, out: F64 | None = None) -> tuple[F64, F64]:
    """``R(theta) r`` for every design and sample: x and y ``(designs, n)`` from
    ``m = [[r_x, -r_y], [r_y, r_x]]`` ``(designs, 2, 2)`` (see ``rotations``) and
    ``cs = (cos theta, sin theta)`` ``(2, n)``.

    As a stack of 2 x 2 products ``m @ cs``: numpy broadcasts a column against a row about three
    times slower, and a stacked matmul gives each design the same bits whatever the batch (a
    single 2-D matmul would not).
    """
    out = np.matmul(m, cs, out=out)
    return out[:, 0], out[:, 1]


def rotations(a: F64, b: F64) -> F64:
    """``[[a, -b], [b, a]]`` ``(..., 2, 2)`` for every element of a, b ``(...)``."""
    m = np.empty(a.shape + (2, 2))
    m[..., 0, 0] = a
    m[..., 0, 1] = -b
    m[..., 1, 0] = b
    m[..., 1, 1] = a
    return m


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
        consts, cs = constants(vals), angles(theta)
        for rows in blocks(pop, n):
            store = np.empty((n_steps, 4, rows.stop - rows.start, n))
            work = np.empty((WORK_ROWS, rows.stop - rows.start, n))
            for j, m, c in steps(ops, consts.rows(rows), cs, store, work):
                margin[rows, :, j], cos_mu[rows, :, j] = m, c
            pos[rows] = store[:, :2].transpose(2, 3, 0, 1)
            dpos[rows] = store[:, 2:].transpose(2, 3, 0, 1)
    return pos, dpos, margin, cos_mu, negative_lengths(ops, vals)


# Slabs of ``reduce``, reused from call to call once nothing refers to them (``core.kinematics.blocks``).
_SLABS = Pool()


def reduce(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, want_joints: bool, derivatives: bool = True
) -> tuple[F64 | None, F64 | None, F64, F64 | None, NDArray[np.bool_], F64, F64, F64, F64]:
    """``run`` reduced to the outputs of ``core.kinematics.kernel.run`` (see there for shapes).

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
    # The paths, the points of a block and the scratch rows (both reused from block to block) in
    # one allocation, itself reused from call to call once nothing refers to it (``core.kinematics.blocks``).
    n_paths, n_coords = (2, 4) if derivatives else (1, 2)
    n_rows = min(pop, block_rows(n))
    n_store = n_steps * n_coords * n_rows * n
    slab = _SLABS.take(n_paths * pop * n * 2 + n_store + WORK_ROWS * n_rows * n)
    paths = slab[: n_paths * pop * n * 2].reshape(n_paths, pop, n, 2)
    store = slab[n_paths * pop * n * 2 :][:n_store].reshape(n_steps, n_coords, n_rows, n)
    work = slab[n_paths * pop * n * 2 + n_store :].reshape(WORK_ROWS, n_rows, n)
    point, dpoint = paths[0], (paths[1] if derivatives else None)
    valid = np.empty((pop, n), dtype=np.bool_)
    mmin, cmin = np.full((pop, n_steps), np.inf), np.full((pop, n_steps), np.inf)
    cmax = np.full((pop, n_steps), -np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        consts, cs = constants(vals), angles(theta)
        for rows in blocks(pop, n):
            block = store[:, :, : rows.stop - rows.start]
            for j, margin, cos_mu in steps(ops, consts.rows(rows), cs, block, work[:, : rows.stop - rows.start]):
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
