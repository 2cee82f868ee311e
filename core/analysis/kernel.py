"""Fast kernel (numba) of the analysis stack; same results as the numpy reference modules.

One pass per design over its samples computes what ``core.analysis.features.feature_points``,
``core.analysis.metrics`` (h_s, h_m, h_bar, psi), ``core.analysis.gait.walking_trajectory``
and ``core.analysis.shape.mse``
compute with whole-array numpy operations; the same rules, in the same order (see those modules
for the definitions). ``tests/test_metrics_kernel_matches_reference.py`` holds them equal.

Two entries: ``run`` analyses given paths; ``run_designs`` solves each design with the solver
kernel (``core.kinematics.kernel``) and analyses its path at once, from rows still in cache: no
``(pop, n_samples, 2)`` array is ever allocated (the optimizer's path, through
``core.analysis.evaluate.evaluate``). Scratch arrays are allocated once per chunk of designs.

Where the arithmetic differs from the reference (agreement ~1e-13, tested to 1e-9): sums are
sequential, and psi merges the touching blocked pieces of the swing arc before the union over
legs (the same set, so the same length up to rounding; no sort of hundreds of pieces).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from core.analysis.path_kernel import (  # noqa: F401  (re-exported: the column names)
    _CHUNK,
    _JIT,
    ADVANCE,
    H_BAR,
    H_M,
    H_S,
    MSE,
    N_ROOTS,
    N_SCALARS,
    PSI2,
    PSI4,
    ROOT_VIOL,
    STEP,
    TURNING,
    VALID,
    WIDTH,
    Y_MIN,
    _analyse,
    work,
)
from core.kinematics import kernel as SK
from core.kinematics import steps as SK_STEPS

F64 = NDArray[np.float64]

@njit(**_JIT)
def _rows(p0, p1, leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    """Designs p0 .. p1 - 1 of given paths (rows copied to scratch, x and y apart)."""
    n = leg.shape[1]
    W = work(n, max(offs2.shape[0], offs4.shape[0]))
    px, py, dpx, dpy, qx, qy = W[10], W[11], W[12], W[13], W[14], W[15]
    for p in range(p0, p1):
        for i in range(n):
            px[i] = leg[p, i, 0]
            py[i] = leg[p, i, 1]
            dpx[i] = dleg[p, i, 0]
            dpy[i] = dleg[p, i, 1]
            qx[i] = point[p, i, 0]
            qy[i] = point[p, i, 1]
        _analyse(p, px, py, dpx, dpy, qx, qy, target, period, a, b, offs2, ph2, offs4, ph4, W, index, pts, tans, S)


@njit(**_JIT, parallel=True)
def _run_parallel(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    pop = leg.shape[0]
    for c in prange((pop + _CHUNK - 1) // _CHUNK):
        _rows(c * _CHUNK, min(pop, (c + 1) * _CHUNK), leg, dleg, point, target, period, a, b, offs2, ph2, offs4,
              ph4, index, pts, tans, S)


@njit(**_JIT)
def _run_serial(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    _rows(0, leg.shape[0], leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S)


def run(
    leg: F64, dleg: F64, point: F64, target: F64, period: float, a: float, b: float,
    offs2: F64, ph2: F64, offs4: F64, ph4: F64, index: F64, pts: F64, tans: F64, S: F64,
) -> None:
    """Fill ``index (pop, 8)``, ``pts``/``tans (pop, 8, 2)`` and ``S (pop, N_SCALARS)`` for every design.

    Rows with a non-finite leg, dleg or point sample are left NaN (``VALID`` = 0). Designs run in
    parallel from ``core.kinematics.solver.PARALLEL_MIN_POP`` on, like the solver.
    """
    from core.kinematics.solver import PARALLEL_MIN_POP

    kernel = _run_parallel if leg.shape[0] >= PARALLEL_MIN_POP else _run_serial
    kernel(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S)


def _fused_designs(solver_digest: str):  # type: ignore[no-untyped-def]
    @njit(**_JIT)
    def designs(i0, i1, ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b, offs2, ph2,
                offs4, ph4, mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S):
        """Solve and analyse designs i0 .. i1 - 1 with one set of scratch rows."""
        if len(solver_digest) == 0:  # keeps the digest in the cache key
            return
        n = ct.shape[0]
        x, y, dx, dy, d2row, acc = SK.scratch(ops.shape[0], n)
        W = work(n, max(offs2.shape[0], offs4.shape[0]))
        lx, ly, ldx, ldy = W[10], W[11], W[12], W[13]
        kx, ky = stage[0], stage[1]
        cx, cy = (1.0 - kx) * stage[2], (1.0 - ky) * stage[3]
        for i in range(i0, i1):
            SK.place(i, ops, vals, ct, st, links, x, y, dx, dy, d2row, mmin, cmin, cmax, neg, True)
            SK.all_finite(x, y, tracked, sinks, acc)
            bad = False
            for k in range(n):
                bad |= acc[k] != 0.0
            broken[i] = bad
            for j in range(ops.shape[0]):  # each joint's lowest y (design frame; NaN samples skipped)
                m = np.inf
                for k in range(n):
                    if y[j, k] < m:
                        m = y[j, k]
                ylow[i, j] = m
            # OutputStage.apply / apply_derivative, operation for operation (no fused multiply-add).
            for k in range(n):
                lx[k] = x[tracked, k] * kx + cx
                ly[k] = y[tracked, k] * ky + cy
                ldx[k] = dx[tracked, k] * kx
                ldy[k] = dy[tracked, k] * ky
            _analyse(i, lx, ly, ldx, ldy, x[tracked], y[tracked], target, period, a, b, offs2, ph2, offs4, ph4, W,
                     index, pts, tans, S)

    return designs


def _fused_runs(solver_digest: str):  # type: ignore[no-untyped-def]
    # _fused_chunk is a global here: a dispatcher as a closure variable would change the cache key per process.
    @njit(**_JIT)
    def serial(ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b, offs2, ph2, offs4, ph4,
               mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S):
        if len(solver_digest) == 0:
            return
        _fused_chunk(0, vals.shape[0], ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b,
                     offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S)

    @njit(**_JIT, parallel=True)
    def parallel(ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b, offs2, ph2, offs4, ph4,
                 mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S):
        if len(solver_digest) == 0:
            return
        pop = vals.shape[0]
        for c in prange((pop + _CHUNK - 1) // _CHUNK):
            _fused_chunk(c * _CHUNK, min(pop, (c + 1) * _CHUNK), ops, vals, ct, st, tracked, sinks, links, stage,
                         target, period, a, b, offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken, ylow, index,
                         pts, tans, S)

    return serial, parallel


# The fused kernels call the solver kernel, whose source numba's cache does not watch: their
# cache keys carry a digest of it (kernel and steps) (a closure variable), so editing the solver recompiles them.
_SOLVER_DIGEST = hashlib.sha1(b"".join(Path(str(m.__file__)).read_bytes() for m in (SK, SK_STEPS))).hexdigest()
_fused_chunk = _fused_designs(_SOLVER_DIGEST)
_fused_serial, _fused_parallel = _fused_runs(_SOLVER_DIGEST)


def run_designs(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, stage: tuple[float, float, float, float],
    target: F64, period: float, a: float, b: float, offs2: F64, ph2: F64, offs4: F64, ph4: F64, parallel: bool,
) -> tuple[F64, F64, F64, F64, NDArray[np.bool_], F64, F64, F64, F64, F64]:
    """Solve every design (``core.kinematics.kernel``) and analyse its path in the same pass.

    The results of ``solver_numba.solve_all(..., stage=stage)`` followed by ``run`` on its point,
    leg and dleg, without those ``(pop, n_samples, 2)`` arrays.

    Returns:
        mmin, cmin, cmax ``(pop, n_steps)`` and neg ``(pop,)`` as ``solver_numba.run``; broken ``(pop,)``
        True where some sample has a non-finite joint (``~valid.any(1)``); ylow ``(pop, n_steps)`` each joint's
        lowest y over the samples (design frame, mm; +inf where it is never placed); index, pts, tans, S as
        ``run`` fills them.
    """
    vals = np.ascontiguousarray(vals, dtype=np.float64)
    theta = np.ascontiguousarray(theta, dtype=np.float64)
    prog = SK.prepare(ops, tracked)
    n_steps = prog.ops.shape[0]
    if vals.ndim != 3 or vals.shape[1:] != (n_steps, 3):
        raise ValueError(f"ops {prog.ops.shape} and vals {vals.shape} do not match")
    pop = vals.shape[0]
    ct, st = SK.angles(theta)
    mmin, cmin, cmax = np.empty((pop, n_steps)), np.empty((pop, n_steps)), np.empty((pop, n_steps))
    neg = np.empty(pop)
    broken = np.empty(pop, dtype=np.bool_)
    ylow = np.empty((pop, n_steps))
    index = np.empty((pop, 8))
    pts = np.empty((pop, 8, 2))
    tans = np.empty((pop, 8, 2))
    S = np.empty((pop, N_SCALARS))
    kernel = _fused_parallel if parallel else _fused_serial
    kernel(prog.ops, vals, ct, st, prog.tracked, prog.sinks, prog.links,
           tuple(float(v) for v in stage), np.ascontiguousarray(target, dtype=np.float64),
           float(period), float(a), float(b), offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken,
           ylow, index, pts, tans, S)
    return mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S
