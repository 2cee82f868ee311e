"""Fast interpreter of a compiled mechanism (numba); the results of ``core.solver_numpy``.

One generic interpreter of the step program (never one kernel per topology). Per design the
steps run in the outer loop and the samples in the inner loop, on contiguous per-point rows
``x, y, dx, dy`` of shape ``(n_steps, n_samples)``: every inner loop is a branch-free
elementwise pass that LLVM turns into SIMD code. The kind of a step is decided outside it.

Where it differs from the reference's arithmetic, for speed (agreement ~1e-12, tested to 1e-9):
a dyad takes one sqrt and one divide per sample (see ``_dyad``); an attachment on a dyad link
uses the link's length instead of measuring it; a crank rotates precomputed cos/sin of theta.
The cycle statistics of a dyad (margin, cosine of the transmission angle) are the reference's
formulas evaluated at the extreme |PQ|^2 of the cycle. With ``want_joints=False`` (the
optimizer's path) nothing of size ``pop * n_samples * n_steps`` is allocated. Coordinates are
assumed below ~1e75 mm (beyond, products in ``_dyad`` overflow).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from core.mechanisms.model import ATTACH, CRANK, DYAD, GROUND

F64 = NDArray[np.float64]

# Designs per parallel task: scratch rows are allocated once per chunk, not per design.
_CHUNK = 64

_I64_MAX = np.int64(0x7FFFFFFFFFFFFFFF)
_INF_BITS = np.int64(0x7FF0000000000000)

# error_model="numpy": x / 0 gives inf or NaN as in numpy instead of raising (and allows SIMD).
# fastmath "contract" only: fused multiply-adds; no flag that assumes away NaN or inf.
_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "fastmath": {"contract"}}


@njit(**_JIT)
def _pos_part(v: float) -> float:
    """``np.maximum(0, v)``: NaN propagates."""
    if v > 0.0 or v != v:
        return v
    return 0.0


@njit(**_JIT)
def _ground(x, y, j, a, u, v, c, s):
    """Place X = O + R(angle) (u, v), given c, s = cos, sin(angle); constant over the cycle, so
    its derivative rows stay 0."""
    gx = c * u - s * v
    gy = s * u + c * v
    xj, yj = x[j], y[j]
    n = xj.shape[0]
    if a >= 0:
        xa, ya = x[a], y[a]
        for k in range(n):
            xj[k] = gx + xa[k]
            yj[k] = gy + ya[k]
    else:
        for k in range(n):
            xj[k] = gx + 0.0
            yj[k] = gy + 0.0


@njit(**_JIT)
def _crank(x, y, dx, dy, j, a, u, v, cp, sp, ct, st):
    """Place X = O + R(phase + theta) (u, v), given cp, sp = cos, sin(phase)."""
    # R(phase + theta) (u, v) = R(theta) R(phase) (u, v): rotate by the phase once per design.
    ru = cp * u - sp * v
    rv = sp * u + cp * v
    xj, yj, dxj, dyj = x[j], y[j], dx[j], dy[j]
    xa, ya = x[a], y[a]
    for k in range(xj.shape[0]):
        c, s = ct[k], st[k]
        rx = c * ru - s * rv
        ry = s * ru + c * rv
        xj[k] = xa[k] + rx
        yj[k] = ya[k] + ry
        dxj[k] = -ry
        dyj[k] = rx


@njit(**_JIT)
def _dyad(x, y, dx, dy, d2row, j, a, b, side, l1, l2):
    """Place X with |PX| = l1, |QX| = l2; store |PQ|^2 per sample in d2row for the cycle statistics.

    With w = Q - P, d2 = |w|^2, t = l1^2 - l2^2 + d2 (= 2 d along) and H = sqrt(4 l1^2 d2 - t^2)
    (= 2 d h): X - P = (t w + side H rot90(w)) / (2 d2), and det[X - P, X - Q] = side H / 2.
    One sqrt and one divide per sample: q = 1 / (d2 side H) gives both 1 / (2 d2) and 2 / (side H).
    """
    k1 = l1 * l1 - l2 * l2
    four_l1sq = 4.0 * (l1 * l1)
    sgn = float(side)
    xj, yj, dxj, dyj = x[j], y[j], dx[j], dy[j]
    px, py, dpx, dpy = x[a], y[a], dx[a], dy[a]
    qx, qy, dqx, dqy = x[b], y[b], dx[b], dy[b]
    for k in range(xj.shape[0]):
        p_x, p_y = px[k], py[k]
        wx = qx[k] - p_x
        wy = qy[k] - p_y
        d2 = wx * wx + wy * wy
        t = k1 + d2
        sh = sgn * np.sqrt(four_l1sq * d2 - t * t)
        # At an exact fold (H = 0) X is still placed; only its derivative is infinite.
        shs = sh if sh != 0.0 else 1.0
        q = 1.0 / (d2 * shs)
        half_inv_d2 = 0.5 * shs * q
        inv_det = 2.0 * d2 * q if sh != 0.0 else np.inf
        a1x = (t * wx - sh * wy) * half_inv_d2
        a1y = (t * wy + sh * wx) * half_inv_d2
        a2x = a1x - wx
        a2y = a1y - wy
        r1 = a1x * dpx[k] + a1y * dpy[k]
        r2 = a2x * dqx[k] + a2y * dqy[k]
        ox = p_x + a1x
        oy = p_y + a1y
        xj[k] = ox
        yj[k] = oy
        dxj[k] = (r1 * a2y - r2 * a1y) * inv_det
        dyj[k] = (a1x * r2 - a2x * r1) * inv_det
        d2row[k] = d2


@njit(**_JIT)
def _dyad_stats(d2row, l1, l2):
    """Min over samples of the dyad margin, min and max of cos(mu), each ignoring NaN samples.

    Both are monotone in d2 = |PQ|^2, and so is their rounding: their extremes over the cycle
    are the reference's per-sample formulas at the smallest and largest d2 (two evaluations
    instead of one per sample).
    """
    dl = abs(l1 - l2)
    sl = l1 + l2
    s12 = l1 * l1 + l2 * l2
    den = 2.0 * l1 * l2
    n = d2row.shape[0]
    if not (np.isfinite(dl) and np.isfinite(sl) and np.isfinite(s12) and np.isfinite(den) and den != 0.0):
        # Odd lengths: the reference's per-sample formulas, literally.
        mmin, cmin, cmax = np.inf, np.inf, -np.inf
        for k in range(n):
            d2 = d2row[k]
            d = np.sqrt(d2)
            m1 = d - dl
            m2 = sl - d
            if m1 == m1 and m2 == m2:
                m = m1 if m1 < m2 else m2
                mmin = m if m < mmin else mmin
            c = (s12 - d2) / den
            cmin = c if c < cmin else cmin
            cmax = c if c > cmax else cmax
        return mmin, cmin, cmax
    # d2 >= 0, so its bits (sign cleared, as NaN's sign varies) order like its values and
    # every NaN sorts above +inf: integer min/max reductions vectorize, float ones do not.
    bits = d2row.view(np.int64)
    lo_bits = _I64_MAX
    hi_bits = np.int64(-1)
    for k in range(n):
        v = bits[k] & _I64_MAX
        lo_bits = min(lo_bits, v)
        hi_bits = max(hi_bits, v if v <= _INF_BITS else np.int64(-1))
    if lo_bits > _INF_BITS:  # every sample NaN
        return np.inf, np.inf, -np.inf
    # Back to floats through the row (no scalar bitcast in numba); the row is spent.
    bits[0] = lo_bits
    bits[1] = hi_bits
    lo, hi = d2row[0], d2row[1]
    m_lo = np.sqrt(lo) - dl
    m_hi = sl - np.sqrt(hi)
    c_lo = (s12 - lo) / den
    c_hi = (s12 - hi) / den
    return min(m_lo, m_hi), min(c_lo, c_hi), max(c_lo, c_hi)


@njit(**_JIT)
def _attach(x, y, dx, dy, j, a, b, u, v, known, length):
    """Place X = P + u e + v rot90(e), e = (Q - P) / |Q - P|.

    known: |Q - P| is a dyad length (P, Q on one dyad link), so use ``length`` instead of
    measuring it: the same value up to rounding, and no sqrt or divide per sample.
    """
    if known:
        _attach_rows(x, y, dx, dy, j, a, b, u, v, 1.0 / length)
    else:
        _attach_rows(x, y, dx, dy, j, a, b, u, v, np.nan)


@njit(**_JIT)
def _attach_rows(x, y, dx, dy, j, a, b, u, v, inv_length):
    xj, yj, dxj, dyj = x[j], y[j], dx[j], dy[j]
    px, py, dpx, dpy = x[a], y[a], dx[a], dy[a]
    qx, qy, dqx, dqy = x[b], y[b], dx[b], dy[b]
    measure = inv_length != inv_length
    for k in range(xj.shape[0]):
        p_x, p_y, dp_x, dp_y = px[k], py[k], dpx[k], dpy[k]
        wx = qx[k] - p_x
        wy = qy[k] - p_y
        inv_len = 1.0 / np.sqrt(wx * wx + wy * wy) if measure else inv_length
        ex = wx * inv_len
        ey = wy * inv_len
        dwx = dqx[k] - dp_x
        dwy = dqy[k] - dp_y
        t = ex * dwx + ey * dwy
        dex = (dwx - ex * t) * inv_len
        dey = (dwy - ey * t) * inv_len
        ox = p_x + u * ex - v * ey
        oy = p_y + u * ey + v * ex
        xj[k] = ox
        yj[k] = oy
        dxj[k] = dp_x + u * dex - v * dey
        dyj[k] = dp_y + u * dey + v * dex


@njit(**_JIT)
def _scratch(n_steps, n):
    """Scratch rows: x, y, dx, dy ``(n_steps, n)``; d2 and finiteness accumulators ``(n,)``.

    Derivative rows start at 0: ground steps never write theirs.
    """
    return (np.empty((n_steps, n)), np.empty((n_steps, n)), np.zeros((n_steps, n)), np.zeros((n_steps, n)),
            np.empty(n), np.empty(n))


@njit(**_JIT)
def _designs(i0, i1, ops, vals, ct, st, tracked, sinks, links, want_joints,
             pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg):
    """Solve designs i0 .. i1 - 1 into their rows of the outputs, with one set of scratch rows."""
    n_steps = ops.shape[0]
    n = ct.shape[0]
    x, y, dx, dy, d2row, acc = _scratch(n_steps, n)
    for i in range(i0, i1):
        _design(i, ops, vals, ct, st, tracked, sinks, links, want_joints, x, y, dx, dy, d2row, acc,
                pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg)


@njit(**_JIT)
def _design(i, ops, vals, ct, st, tracked, sinks, links, want_joints, x, y, dx, dy, d2row, acc,
            pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg):
    """Solve design i into row i of the outputs, using the scratch rows given."""
    n_steps = ops.shape[0]
    n = ct.shape[0]
    total_neg = 0.0
    # Steps often share an angle (one crank phase, one frame angle): cache the last cos, sin.
    last, c, s = 0.0, 1.0, 0.0
    for j in range(n_steps):
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
                _crank(x, y, dx, dy, j, a, v0, v1, c, s, ct, st)
        elif kind == DYAD:
            total_neg += _pos_part(-v0) + _pos_part(-v1)
            _dyad(x, y, dx, dy, d2row, j, a, b, side, v0, v1)
            mmin[i, j], cmin[i, j], cmax[i, j] = _dyad_stats(d2row, v0, v1)
        else:  # ATTACH (run() rejects unknown kinds)
            ls, lc = links[j, 0], links[j, 1]
            _attach(x, y, dx, dy, j, a, b, v0, v1, ls >= 0, abs(vals[i, ls, lc]) if ls >= 0 else 1.0)
    neg[i] = total_neg
    # Every step turns a non-finite input point into a non-finite output point, so a sample
    # has every point finite iff the tracked point and the other sinks (points no later step
    # uses) are finite. x - x is 0 for finite x and NaN for inf and NaN.
    for k in range(n):
        acc[k] = 0.0
    for sink in sinks:
        xs, ys = x[sink], y[sink]
        for k in range(n):
            acc[k] += (xs[k] - xs[k]) + (ys[k] - ys[k])
    valid_i = valid[i]
    # Flat views: interleaved stores by index vectorize, [k, 0] / [k, 1] pairs do not.
    pt, dpt = point[i].reshape(-1), dpoint[i].reshape(-1)
    xt, yt, dxt, dyt = x[tracked], y[tracked], dx[tracked], dy[tracked]
    for k in range(n):
        px, py = xt[k], yt[k]
        valid_i[k] = (px - px) + (py - py) + acc[k] == 0.0
        pt[2 * k] = px
        pt[2 * k + 1] = py
    for k in range(n):
        dpt[2 * k] = dxt[k]
        dpt[2 * k + 1] = dyt[k]
    if want_joints:
        for k in range(n):
            for j in range(n_steps):
                pos[i, k, j, 0] = x[j, k]
                pos[i, k, j, 1] = y[j, k]
                dpos[i, k, j, 0] = dx[j, k]
                dpos[i, k, j, 1] = dy[j, k]


@njit(**_JIT)
def _run_serial(ops, vals, ct, st, tracked, sinks, links, want_joints,
                pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg):
    _designs(0, vals.shape[0], ops, vals, ct, st, tracked, sinks, links, want_joints,
             pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg)


@njit(**_JIT, parallel=True)
def _run_parallel(ops, vals, ct, st, tracked, sinks, links, want_joints,
                  pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg):
    pop = vals.shape[0]
    for c in prange((pop + _CHUNK - 1) // _CHUNK):
        _designs(c * _CHUNK, min(pop, (c + 1) * _CHUNK), ops, vals, ct, st, tracked, sinks, links, want_joints,
                 pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg)


def run(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, want_joints: bool, parallel: bool
) -> tuple[F64 | None, F64 | None, F64, F64, NDArray[np.bool_], F64, F64, F64, F64]:
    """Solve a population; the same outputs as ``core.kinematics.reduce_reference``.

    Never raises for non-finite operands: NaN propagates to every point built on it. Raises
    ValueError only for a malformed program (a step using a later or missing point).

    Args:
        ops: ``(n_steps, 4)`` compiled step rows ``[kind, a, b, side]`` (see ``Program``).
        vals: ``(pop, n_steps, 3)`` operand values (mm, rad); rows may be NaN. Not mutated.
        theta: ``(n_samples,)`` input crank angles (rad).
        tracked: index of the tracked point.
        want_joints: also return every joint (else None for pos and dpos, and no memory for them).
        parallel: run over designs on all threads.

    Returns:
        pos, dpos: ``(pop, n_samples, n_steps, 2)`` joint positions (mm) and d/dtheta (mm/rad), or None.
        point, dpoint: ``(pop, n_samples, 2)`` the tracked point and its d/dtheta.
        valid: ``(pop, n_samples)`` True where every joint is finite.
        mmin: ``(pop, n_steps)`` min over samples of each dyad's margin ``min(d - |l1-l2|, l1+l2-d)``
            ignoring NaN (mm); +inf for other steps and where no sample has a value.
        cmin, cmax: ``(pop, n_steps)`` min and max over samples of the cosine of each dyad's
            transmission angle ignoring NaN; +inf / -inf where none.
        neg: ``(pop,)`` total amount by which dyad lengths are negative (mm).
    """
    ops = np.ascontiguousarray(ops, dtype=np.int64)
    vals = np.ascontiguousarray(vals, dtype=np.float64)
    theta = np.ascontiguousarray(theta, dtype=np.float64)
    tracked = int(tracked)
    _check_program(ops, vals, tracked)
    pop, n_steps = vals.shape[:2]
    n = theta.shape[0]
    ct, st = np.cos(theta), np.sin(theta)
    shape = (pop, n, n_steps, 2) if want_joints else (0, 0, 0, 2)
    pos, dpos = np.empty(shape), np.empty(shape)
    point, dpoint = np.empty((pop, n, 2)), np.empty((pop, n, 2))
    valid = np.empty((pop, n), dtype=np.bool_)
    mmin, cmin, cmax = np.empty((pop, n_steps)), np.empty((pop, n_steps)), np.empty((pop, n_steps))
    neg = np.empty(pop)
    kernel = _run_parallel if parallel else _run_serial
    kernel(ops, vals, ct, st, tracked, _sinks(ops, tracked), _link_lengths(ops), bool(want_joints),
           pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg)
    if not want_joints:
        return None, None, point, dpoint, valid, mmin, cmin, cmax, neg
    return pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg


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


def _check_program(ops: NDArray[np.int64], vals: F64, tracked: int) -> None:
    """The kernel checks no bounds: reject a malformed program (a bug, not a design) up front."""
    n_steps = ops.shape[0]
    if ops.ndim != 2 or ops.shape[1] != 4 or vals.ndim != 3 or vals.shape[1:] != (n_steps, 3):
        raise ValueError(f"ops {ops.shape} and vals {vals.shape} do not match")
    if not 0 <= tracked < n_steps:
        raise ValueError(f"malformed program: tracked point {tracked} of {n_steps}")
    j = np.arange(n_steps)
    kind, a, b = ops[:, 0], ops[:, 1], ops[:, 2]
    two = (kind == DYAD) | (kind == ATTACH)
    known = (kind == GROUND) | (kind == CRANK) | two
    ok = known & (a < j) & ((a >= 0) | (kind == GROUND)) & (~two | ((b >= 0) & (b < j)))
    if not ok.all():
        raise ValueError(f"malformed program: step {int(np.flatnonzero(~ok)[0])} has an unknown kind or point")
