"""Fast interpreter of a compiled mechanism (numba); the results of ``core.kinematics.reference``.

One generic interpreter of the step program (never one kernel per topology). Per design the
steps run in the outer loop and the samples in the inner loop, on scratch rows ``x[j], y[j],
dx[j], dy[j]`` of shape ``(n_steps, n_samples)`` indexed directly (no per-step array views):
every inner loop is a branch-free elementwise pass that LLVM turns into SIMD code. The kind of
a step is decided outside it. The inner loops are compute-bound (multiply and divider throughput),
so the arithmetic is arranged for few operations per sample.

Where it differs from the reference's arithmetic, for speed (agreement ~1e-12, tested to 1e-9):
a dyad takes one sqrt and one divide per sample (see ``_dyad``); the derivative of a point on a
link is that of a rigid body, dX = dP + omega rot90(X - P), with the link's rotation rate omega
(the reference solves a 2 x 2 system, or differentiates a unit vector); an attachment on a dyad
link uses the link's length instead of measuring it; a crank rotates precomputed cos/sin of
theta. The cycle statistics of a dyad (margin, cosine of the transmission angle) are the
reference's formulas evaluated at the extreme |PQ|^2 of the cycle, found in the dyad's own loop.
With ``want_joints=False`` (the optimizer's path) nothing of size ``pop * n_samples * n_steps`` is
allocated. Coordinates are assumed below ~1e75 mm (beyond, products in ``_dyad`` overflow).

Memory: the step functions are compiled without reference counting (``_NO_RC``); while a design
is solved, the output rows of the next one are prefetched for writing (``_place``), so that its
stores do not wait on DRAM; the block of paths is reused from call to call once nothing refers
to it (``_PATHS``), so that its pages are not faulted in again.

``core.analysis.kernel.run_designs`` calls ``place`` directly (solve, then analyse each design
while its rows are in cache).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from core.kinematics.blocks import Pool
from core.kinematics.model import ATTACH, CRANK, DYAD, GROUND
from core.kinematics.steps import _JIT, _NO_RC, _attach, _crank, _dyad, _ground, _pos_part, _prefetch_part, _row

F64 = NDArray[np.float64]

# Designs per parallel task: scratch rows are allocated once per chunk, not per design.
_CHUNK = 64

@njit(**_JIT)
def scratch(n_steps, n):
    """Scratch rows: x, y, dx, dy ``(n_steps, n)``; d2 and finiteness accumulators ``(n,)``.

    Derivative rows start at 0: ground steps never write theirs.
    """
    return (np.empty((n_steps, n)), np.empty((n_steps, n)), np.zeros((n_steps, n)), np.zeros((n_steps, n)),
            np.empty(n), np.empty(n))


@njit(**_NO_RC)
def place(i, ops, vals, ct, st, links, x, y, dx, dy, d2row, mmin, cmin, cmax, neg, deriv):
    """Solve design i into the scratch rows; its cycle statistics into row i of mmin, cmin, cmax, neg.
    Without ``deriv`` the derivative rows are left untouched."""
    _place(i, ops, vals, ct, st, links, x, y, dx, dy, d2row, mmin, cmin, cmax, neg, deriv, ((0, 0, 0),))


@njit(**_NO_RC)
def _place(i, ops, vals, ct, st, links, x, y, dx, dy, d2row, mmin, cmin, cmax, neg, deriv, ahead):
    """``place``, prefetching for writing the cache lines of each range in the tuple ``ahead`` (see
    ``_lines``), a part at each step: the output rows of the next design, so that its stores hit
    the cache (written in a burst at the end of a design, their reads for ownership from DRAM
    would stall the core; spread over the steps they overlap the arithmetic). Tuples, not an
    array: faster."""
    total_neg = 0.0
    # Steps often share an angle (one crank phase, one frame angle): cache the last cos, sin.
    last, c, s = 0.0, 1.0, 0.0
    for j in range(ops.shape[0]):
        for lines in ahead:
            _prefetch_part(lines, j)
        kind, a, b, side = ops[j, 0], ops[j, 1], ops[j, 2], ops[j, 3]
        v0, v1, v2 = vals[i, j, 0], vals[i, j, 1], vals[i, j, 2]
        mmin[i, j] = np.inf
        cmin[i, j] = np.inf
        cmax[i, j] = -np.inf
        if kind == GROUND or kind == CRANK:
            if v2 != last:
                last, c, s = v2, np.cos(v2), np.sin(v2)
            if kind == GROUND:
                _ground(x, y, j, a, v0, v1, c, s)
            else:
                _crank(x, y, dx, dy, j, a, v0, v1, c, s, ct, st, deriv)
        elif kind == DYAD:
            total_neg += _pos_part(-v0) + _pos_part(-v1)
            mmin[i, j], cmin[i, j], cmax[i, j] = _dyad(x, y, dx, dy, d2row, j, a, b, side, v0, v1, deriv)
        else:  # ATTACH (run() rejects unknown kinds)
            ls, lc = links[j, 0], links[j, 1]
            _attach(x, y, dx, dy, j, a, b, v0, v1, ls >= 0, abs(vals[i, ls, lc]) if ls >= 0 else 1.0, deriv)
    neg[i] = total_neg


@njit(**_NO_RC)
def all_finite(x, y, tracked, sinks, acc):
    """acc[k] = 0 where every point of sample k is finite, else NaN.

    Every step turns a non-finite input point into a non-finite output point, so a sample has
    every point finite iff the tracked point and the other sinks (points no later step uses) are
    finite. x - x is 0 for finite x and NaN for inf and NaN.
    """
    for k in range(x.shape[1]):
        acc[k] = (x[tracked, k] - x[tracked, k]) + (y[tracked, k] - y[tracked, k])
    for sink in sinks:
        for k in range(x.shape[1]):
            acc[k] += (x[sink, k] - x[sink, k]) + (y[sink, k] - y[sink, k])


@njit(**_NO_RC)
def _emit(i, x, y, dx, dy, tracked, sinks, acc, want_joints, want_leg, stage, deriv,
          pos, dpos, point, dpoint, leg, dleg, valid):
    """Write design i's rows of the outputs from the scratch rows; point, dpoint, leg, dleg are
    flat ``(pop, 2 n)`` views (interleaved stores by index vectorize, [k, 0] / [k, 1] pairs do not).
    Without ``deriv`` nothing is written to dpos, dpoint, dleg."""
    n = x.shape[1]
    if sinks.shape[0] == 0:  # the tracked point alone decides
        for k in range(n):
            px, py = x[tracked, k], y[tracked, k]
            valid[i, k] = (px - px) + (py - py) == 0.0
            point[i, 2 * k] = px
            point[i, 2 * k + 1] = py
    else:
        all_finite(x, y, sinks[0], sinks[1:], acc)
        for k in range(n):
            px, py = x[tracked, k], y[tracked, k]
            valid[i, k] = (px - px) + (py - py) + acc[k] == 0.0
            point[i, 2 * k] = px
            point[i, 2 * k + 1] = py
    if deriv:
        for k in range(n):
            dpoint[i, 2 * k] = dx[tracked, k]
            dpoint[i, 2 * k + 1] = dy[tracked, k]
    if want_leg:
        _emit_leg(i, x, y, dx, dy, tracked, stage, deriv, leg, dleg)
    if want_joints:
        for k in range(n):
            for j in range(x.shape[0]):
                pos[i, k, j, 0] = x[j, k]
                pos[i, k, j, 1] = y[j, k]
    if want_joints and deriv:
        for k in range(n):
            for j in range(x.shape[0]):
                dpos[i, k, j, 0] = dx[j, k]
                dpos[i, k, j, 1] = dy[j, k]


# Like numpy: p * k rounded, then the add (no fused multiply-add; see _JIT).
@njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
def _emit_leg(i, x, y, dx, dy, tracked, stage, deriv, leg, dleg):
    """Design i's rows of leg, dleg: ``OutputStage.apply`` and ``apply_derivative``, operation for operation
    (stage = ``OutputStage.kernel_args()``)."""
    kx, ky = stage[0], stage[1]
    cx, cy = (1.0 - kx) * stage[2], (1.0 - ky) * stage[3]
    for k in range(x.shape[1]):
        leg[i, 2 * k] = x[tracked, k] * kx + cx
        leg[i, 2 * k + 1] = y[tracked, k] * ky + cy
    if deriv:
        for k in range(x.shape[1]):
            dleg[i, 2 * k] = dx[tracked, k] * kx
            dleg[i, 2 * k + 1] = dy[tracked, k] * ky


@njit(**_JIT)
def _designs(i0, i1, ops, vals, ct, st, tracked, sinks, links, want_joints, want_leg, stage, deriv,
             pos, dpos, point, dpoint, leg, dleg, valid, mmin, cmin, cmax, neg):
    """Solve designs i0 .. i1 - 1 into their rows of the outputs, with one set of scratch rows."""
    x, y, dx, dy, d2row, acc = scratch(ops.shape[0], ct.shape[0])
    n_steps = ops.shape[0]
    for i in range(i0, i1):
        # The next design's rows of the paths and valid (not of the joints: rarely asked for).
        nxt = min(i + 1, i1 - 1)
        ahead = (_row(point, nxt, n_steps), _row(dpoint, nxt, n_steps), _row(leg, nxt, n_steps),
                 _row(dleg, nxt, n_steps), _row(valid, nxt, n_steps))
        _place(i, ops, vals, ct, st, links, x, y, dx, dy, d2row, mmin, cmin, cmax, neg, deriv, ahead)
        _emit(i, x, y, dx, dy, tracked, sinks, acc, want_joints, want_leg, stage, deriv,
              pos, dpos, point, dpoint, leg, dleg, valid)


@njit(**_JIT)
def _flat(a, n):
    """A ``(pop, n, 2)`` output as ``(pop, 2 n)``."""
    return a.reshape(a.shape[0], 2 * n)


@njit(**_JIT)
def _run_serial(ops, vals, ct, st, tracked, sinks, links, want_joints, want_leg, stage, deriv,
                pos, dpos, point, dpoint, leg, dleg, valid, mmin, cmin, cmax, neg):
    n = ct.shape[0]
    _designs(0, vals.shape[0], ops, vals, ct, st, tracked, sinks, links, want_joints, want_leg, stage, deriv,
             pos, dpos, _flat(point, n), _flat(dpoint, n), _flat(leg, n), _flat(dleg, n), valid, mmin, cmin, cmax,
             neg)


@njit(**_JIT, parallel=True)
def _run_parallel(ops, vals, ct, st, tracked, sinks, links, want_joints, want_leg, stage, deriv,
                  pos, dpos, point, dpoint, leg, dleg, valid, mmin, cmin, cmax, neg):
    pop = vals.shape[0]
    n = ct.shape[0]
    point, dpoint, leg, dleg = _flat(point, n), _flat(dpoint, n), _flat(leg, n), _flat(dleg, n)
    for c in prange((pop + _CHUNK - 1) // _CHUNK):
        _designs(c * _CHUNK, min(pop, (c + 1) * _CHUNK), ops, vals, ct, st, tracked, sinks, links, want_joints,
                 want_leg, stage, deriv, pos, dpos, point, dpoint, leg, dleg, valid, mmin, cmin, cmax, neg)


class Program(NamedTuple):
    """A checked program ready for the kernels (see ``prepare``)."""

    ops: NDArray[np.int64]
    tracked: int
    sinks: NDArray[np.int64]
    links: NDArray[np.int64]


class Outputs(NamedTuple):
    """Everything ``solve`` gets from the kernel (shapes: see ``run``); leg, dleg None unless asked;
    dpos, dpoint, dleg None without derivatives."""

    pos: F64 | None
    dpos: F64 | None
    point: F64
    dpoint: F64 | None
    leg: F64 | None
    dleg: F64 | None
    valid: NDArray[np.bool_]
    mmin: F64
    cmin: F64
    cmax: F64
    neg: F64


# Blocks of paths of ``solve_all``, reused from call to call once nothing refers to them
# (``core.kinematics.blocks``: a kept block's pages are mapped already; a new one's are faulted in when first
# written, ~0.6 us per design at pop 10 000, a third of the solve).
_PATHS = Pool()


_PREPARED: dict[tuple[bytes, tuple[int, ...], int], Program] = {}
_ANGLES: dict[tuple[int, bytes], tuple[F64, F64]] = {}


def prepare(ops: NDArray[np.int64], tracked: int) -> Program:
    """Check a program and derive the kernel's tables (memoized: a few programs per process).

    Raises:
        ValueError: for a malformed program (a step using a later or missing point).
    """
    ops = np.ascontiguousarray(ops, dtype=np.int64)
    tracked = int(tracked)
    key = (ops.tobytes(), ops.shape, tracked)
    prog = _PREPARED.get(key)
    if prog is None:
        _check_program(ops, tracked)
        ops = ops.copy()
        ops.setflags(write=False)
        prog = Program(ops, tracked, _sinks(ops, tracked), _link_lengths(ops))
        if len(_PREPARED) < 256:
            _PREPARED[key] = prog
    return prog


def angles(theta: F64) -> tuple[F64, F64]:
    """cos and sin of the sample angles (memoized for the usual uniform grids)."""
    key = (theta.shape[0], theta.tobytes())
    cs = _ANGLES.get(key)
    if cs is None:
        cs = (np.cos(theta), np.sin(theta))
        if len(_ANGLES) < 64:
            _ANGLES[key] = cs
    return cs


def solve_all(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, want_joints: bool, parallel: bool,
    stage: tuple[float, float, float, float] | None = None, derivatives: bool = True,
) -> Outputs:
    """``run``, plus the tracked point in the leg frame when ``stage = (kx, ky, ox, oy)``
    (``OutputStage.kernel_args()``) is given
    (``OutputStage.apply`` and ``apply_derivative``, in the same pass). Without ``derivatives``
    no derivative is computed (about half the work; the same positions up to rounding)."""
    vals = np.ascontiguousarray(vals, dtype=np.float64)
    theta = np.ascontiguousarray(theta, dtype=np.float64)
    prog = prepare(ops, tracked)
    n_steps = prog.ops.shape[0]
    if vals.ndim != 3 or vals.shape[1:] != (n_steps, 3):
        raise ValueError(f"ops {prog.ops.shape} and vals {vals.shape} do not match")
    pop = vals.shape[0]
    n = theta.shape[0]
    ct, st = angles(theta)
    shape = (pop, n, n_steps, 2) if want_joints else (0, 0, 0, 2)
    pos, dpos = np.empty(shape), np.empty(shape if derivatives else (0, 0, 0, 2))
    want_leg = stage is not None
    # One block for the paths, reused from call to call once nothing refers to it (``_PATHS``).
    n_paths = (2 if want_leg else 1) * (2 if derivatives else 1)
    block = _PATHS.take(n_paths * pop * n * 2).reshape(n_paths, pop, n, 2)
    point = block[0]
    dpoint = block[1] if derivatives else point[:0]
    leg = block[n_paths // 2] if want_leg else point[:0]
    dleg = block[3] if want_leg and derivatives else point[:0]
    valid = np.empty((pop, n), dtype=np.bool_)
    mmin, cmin, cmax = np.empty((pop, n_steps)), np.empty((pop, n_steps)), np.empty((pop, n_steps))
    neg = np.empty(pop)
    k_o = (1.0, 1.0, 0.0, 0.0) if stage is None else tuple(float(v) for v in stage)
    if len(k_o) != 4:
        raise ValueError(f"stage is (kx, ky, ox, oy), got {stage}")
    kernel = _run_parallel if parallel else _run_serial
    kernel(prog.ops, vals, ct, st, prog.tracked, prog.sinks, prog.links, bool(want_joints), want_leg, k_o,
           bool(derivatives), pos, dpos, point, dpoint, leg, dleg, valid, mmin, cmin, cmax, neg)
    d = bool(derivatives)
    return Outputs(
        pos if want_joints else None, dpos if want_joints and d else None, point, dpoint if d else None,
        leg if want_leg else None, dleg if want_leg and d else None, valid, mmin, cmin, cmax, neg,
    )


def run(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, want_joints: bool, parallel: bool,
    derivatives: bool = True,
) -> tuple[F64 | None, F64 | None, F64, F64 | None, NDArray[np.bool_], F64, F64, F64, F64]:
    """Solve a population; the same outputs as ``core.kinematics.reference.reduce``.

    Never raises for non-finite operands: NaN propagates to every point built on it. Raises
    ValueError only for a malformed program (a step using a later or missing point).

    Args:
        ops: ``(n_steps, 4)`` compiled step rows ``[kind, a, b, side]`` (see ``Program``).
        vals: ``(pop, n_steps, 3)`` operand values (mm, rad); rows may be NaN. Not mutated.
        theta: ``(n_samples,)`` input crank angles (rad).
        tracked: index of the tracked point.
        want_joints: also return every joint (else None for pos and dpos, and no memory for them).
        parallel: run over designs on all threads.
        derivatives: also compute dpos and dpoint (else None for them; the same positions).

    Returns:
        pos, dpos: ``(pop, n_samples, n_steps, 2)`` joint positions (mm) and d/dtheta (mm/rad), or None.
        point, dpoint: ``(pop, n_samples, 2)`` the tracked point and its d/dtheta (or None).
        valid: ``(pop, n_samples)`` True where every joint is finite.
        mmin: ``(pop, n_steps)`` min over samples of each dyad's margin ``min(d - |l1-l2|, l1+l2-d)``
            ignoring NaN (mm); +inf for other steps and where no sample has a value.
        cmin, cmax: ``(pop, n_steps)`` min and max over samples of the cosine of each dyad's
            transmission angle ignoring NaN; +inf / -inf where none.
        neg: ``(pop,)`` total amount by which dyad lengths are negative (mm).
    """
    o = solve_all(ops, vals, theta, tracked, want_joints, parallel, derivatives=derivatives)
    return o.pos, o.dpos, o.point, o.dpoint, o.valid, o.mmin, o.cmin, o.cmax, o.neg


def _sinks(ops: NDArray[np.int64], tracked: int) -> NDArray[np.int64]:
    """Indices of the points, other than the tracked one, that no step uses as an input."""
    used = np.zeros(ops.shape[0], dtype=bool)
    for kind, a, b, _ in ops:
        if a >= 0:
            used[a] = True
        if kind in (DYAD, ATTACH):
            used[b] = True
    used[tracked] = True  # checked apart
    return np.flatnonzero(~used).astype(np.int64)


def _link_lengths(ops: NDArray[np.int64]) -> NDArray[np.int64]:
    """``(n_steps, 2)`` for each attachment whose P and Q lie on one dyad link, the operand
    ``[step, column]`` holding that link's length; ``[-1, -1]`` otherwise."""
    out = np.full((ops.shape[0], 2), -1, dtype=np.int64)
    for j, (kind, p, q, _) in enumerate(ops):
        if kind != ATTACH:
            continue
        for x, other in ((q, p), (p, q)):
            if ops[x, 0] == DYAD and other in (ops[x, 1], ops[x, 2]):
                # Dyad x: |x - ops[x, 1]| = l1 (column 0), |x - ops[x, 2]| = l2 (column 1).
                out[j] = x, 0 if other == ops[x, 1] else 1
                break
    return out


def _check_program(ops: NDArray[np.int64], tracked: int) -> None:
    """The kernel checks no bounds: reject a malformed program (a bug, not a design) up front."""
    if ops.ndim != 2 or ops.shape[1] != 4:
        raise ValueError(f"malformed program: ops of shape {ops.shape}")
    n_steps = ops.shape[0]
    if not 0 <= tracked < n_steps:
        raise ValueError(f"malformed program: tracked point {tracked} of {n_steps}")
    j = np.arange(n_steps)
    kind, a, b = ops[:, 0], ops[:, 1], ops[:, 2]
    two = (kind == DYAD) | (kind == ATTACH)
    known = (kind == GROUND) | (kind == CRANK) | two
    ok = known & (a < j) & ((a >= 0) | (kind == GROUND)) & (~two | ((b >= 0) & (b < j)))
    if not ok.all():
        raise ValueError(f"malformed program: step {int(np.flatnonzero(~ok)[0])} has an unknown kind or point")
