"""The construction steps of the numba kernel: ground, crank, dyad and attachment, one sample row at a time.

Each step writes the rows of one joint (positions and, with ``deriv``, d/dtheta) for every crank sample;
``core.kinematics.kernel`` runs them in a design's step order. Also here: the bit tricks and the write
prefetch those loops use. Compiled without reference counting (``_NO_RC``): they allocate nothing.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba import njit, types
from numba.extending import intrinsic

_U64_MAX = np.uint64(0xFFFFFFFFFFFFFFFF)
_INF_BITS = np.uint64(0x7FF0000000000000)

# error_model="numpy": x / 0 gives inf or NaN as in numpy instead of raising (and allows SIMD).
# No fastmath, not even "contract": LLVM may fuse a multiply and an add or not, and it decided
# differently for the code it runs after compiling and the code it writes to the disk cache, so a
# process that compiled the kernel and one that loaded it got results 1e-13 apart (and optimizer
# runs that drifted apart). Without it the kernel is ~2-5 % slower and the same in every process.
_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# For functions that allocate nothing: no reference counting of their array arguments (numba's
# atomic incref / decref of every array on every call cost ~30 ns per construction step).
_NO_RC = {**_JIT, "_nrt": False}


@intrinsic
def _bits(typingctx, v):
    """The IEEE-754 bits of a float64, as a uint64 (a register move)."""
    if v != types.float64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.uint64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, v):
    """The float64 with the given IEEE-754 bits."""
    if v != types.uint64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.uint64), codegen


@intrinsic
def _prefetch_w(typingctx, addr):
    """Prefetch the cache line at an address (an integer) for writing; never faults."""
    if not isinstance(addr, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        i32 = ir.IntType(32)
        ptr = builder.inttoptr(args[0], ir.PointerType(ir.IntType(8)))
        fnty = ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32])
        fn = builder.module.declare_intrinsic("llvm.prefetch", [ptr.type], fnty)
        # rw = 1 (write), locality = 3 (keep in all levels), data cache.
        builder.call(fn, [ptr, ir.Constant(i32, 1), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(addr), codegen


@njit(**_NO_RC)
def _prefetch_part(lines, part):
    """Prefetch for writing part ``part`` of the cache lines ``lines = (address of the first,
    count, count per part)``."""
    first, count, per = lines
    for line in range(part * per, min(count, (part + 1) * per)):
        _prefetch_w(first + (line << 6))


@njit(**_NO_RC)
def _lines(address, n_bytes, parts):
    """The cache lines of the bytes [address, address + n_bytes) for ``_prefetch_part``, in parts."""
    first = address & ~63
    count = (((address + n_bytes + 63) & ~63) - first) >> 6
    return first, count, (count + parts - 1) // parts


@njit(**_NO_RC)
def _row(a, i, parts):
    """``_lines`` of row i of a 2-D C-contiguous array (none if it has no rows)."""
    if a.shape[0] == 0:
        return 0, 0, 1
    n_bytes = a.shape[1] * a.itemsize
    return _lines(np.int64(a.ctypes.data) + i * n_bytes, n_bytes, parts)


@njit(**_NO_RC)
def _pos_part(v: float) -> float:
    """``np.maximum(0, v)``: NaN propagates."""
    if v > 0.0 or v != v:
        return v
    return 0.0


@njit(**_NO_RC)
def _ground(x, y, j, a, u, v, c, s):
    """Place X = O + R(angle) (u, v), given c, s = cos, sin(angle); constant over the cycle, so
    its derivative rows stay 0."""
    gx = c * u - s * v
    gy = s * u + c * v
    if a >= 0:
        for k in range(x.shape[1]):
            x[j, k] = gx + x[a, k]
            y[j, k] = gy + y[a, k]
    else:
        for k in range(x.shape[1]):
            x[j, k] = gx + 0.0
            y[j, k] = gy + 0.0


@njit(**_NO_RC)
def _crank(x, y, dx, dy, j, a, u, v, cp, sp, ct, st, deriv):
    """Place X = O + R(phase + theta) (u, v), given cp, sp = cos, sin(phase)."""
    # R(phase + theta) (u, v) = R(theta) R(phase) (u, v): rotate by the phase once per design.
    ru = cp * u - sp * v
    rv = sp * u + cp * v
    if not deriv:
        for k in range(x.shape[1]):
            c, s = ct[k], st[k]
            x[j, k] = x[a, k] + (c * ru - s * rv)
            y[j, k] = y[a, k] + (s * ru + c * rv)
        return
    for k in range(x.shape[1]):
        c, s = ct[k], st[k]
        rx = c * ru - s * rv
        ry = s * ru + c * rv
        x[j, k] = x[a, k] + rx
        y[j, k] = y[a, k] + ry
        dx[j, k] = -ry
        dy[j, k] = rx


@njit(**_NO_RC, inline="always")
def _dyad_chord(x, y, a, b, k, sgn, k1, four_l1sq):
    """At sample k: P, w = Q - P, d2 = |w|^2, t and side H (see ``_dyad``)."""
    p_x, p_y = x[a, k], y[a, k]
    wx = x[b, k] - p_x
    wy = y[b, k] - p_y
    d2 = wx * wx + wy * wy
    t = k1 + d2
    return p_x, p_y, wx, wy, d2, t, sgn * np.sqrt(four_l1sq * d2 - t * t)


@njit(**_NO_RC, inline="always")
def _dyad_at(x, y, dx, dy, j, a, b, k, sgn, k1, four_l1sq):
    """Place X at sample k (see ``_dyad``); returns |PQ|^2."""
    p_x, p_y, wx, wy, d2, t, sh = _dyad_chord(x, y, a, b, k, sgn, k1, four_l1sq)
    # At an exact fold (H = 0) X is still placed; only its derivative is infinite.
    shs = sh if sh != 0.0 else 1.0
    q = 1.0 / (d2 * shs)
    half_inv_d2 = 0.5 * shs * q
    inv_det = 2.0 * d2 * q if sh != 0.0 else np.inf
    a1x = (t * wx - sh * wy) * half_inv_d2
    a1y = (t * wy + sh * wx) * half_inv_d2
    # X turns about P with omega = (X - Q) . (dQ - dP) / det[X - P, X - Q] (the reference's 2 x 2
    # system solved for the link's rotation): dX = dP + omega rot90(X - P).
    dpx, dpy = dx[a, k], dy[a, k]
    omega = ((a1x - wx) * (dx[b, k] - dpx) + (a1y - wy) * (dy[b, k] - dpy)) * inv_det
    x[j, k] = p_x + a1x
    y[j, k] = p_y + a1y
    dx[j, k] = dpx - omega * a1y
    dy[j, k] = dpy + omega * a1x
    return d2


@njit(**_NO_RC, inline="always")
def _dyad_pos_at(x, y, j, a, b, k, sgn, k1, four_l1sq):
    """Place X at sample k without its derivative (see ``_dyad``); returns |PQ|^2."""
    p_x, p_y, wx, wy, d2, t, sh = _dyad_chord(x, y, a, b, k, sgn, k1, four_l1sq)
    half_inv_d2 = 0.5 / d2
    x[j, k] = p_x + (t * wx - sh * wy) * half_inv_d2
    y[j, k] = p_y + (t * wy + sh * wx) * half_inv_d2
    return d2


@njit(**_NO_RC)
def _dyad(x, y, dx, dy, d2row, j, a, b, side, l1, l2, deriv):
    """Place X with |PX| = l1, |QX| = l2; return the cycle's min margin and min, max cos(mu).

    With w = Q - P, d2 = |w|^2, t = l1^2 - l2^2 + d2 (= 2 d along) and H = sqrt(4 l1^2 d2 - t^2)
    (= 2 d h): X - P = (t w + side H rot90(w)) / (2 d2), and det[X - P, X - Q] = side H / 2.
    One sqrt and one divide per sample: q = 1 / (d2 side H) gives both 1 / (2 d2) and 2 / (side H)
    (without the derivative, 1 / (2 d2) is the divide).

    The margin and cos(mu) are monotone in d2, and so is their rounding: their extremes over the
    cycle (ignoring NaN samples) are the reference's per-sample formulas at the smallest and
    largest d2, found by integer min reductions that vectorize in the loop. As unsigned integers
    the bits of d2 >= +0 order like its values and every NaN (either sign) sorts above +inf;
    ``inf_bits - bits`` maps [0, inf] onto [inf_bits, 0] and every NaN above inf_bits again.
    """
    k1 = l1 * l1 - l2 * l2
    four_l1sq = 4.0 * (l1 * l1)
    sgn = float(side)
    dl = abs(l1 - l2)
    sl = l1 + l2
    s12 = l1 * l1 + l2 * l2
    den = 2.0 * l1 * l2
    n = x.shape[1]
    if not (np.isfinite(dl) and np.isfinite(sl) and np.isfinite(s12) and np.isfinite(den) and den != 0.0):
        # Odd lengths: the reference's per-sample formulas, literally.
        for k in range(n):
            if deriv:
                d2row[k] = _dyad_at(x, y, dx, dy, j, a, b, k, sgn, k1, four_l1sq)
            else:
                d2row[k] = _dyad_pos_at(x, y, j, a, b, k, sgn, k1, four_l1sq)
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
    lo_bits = _U64_MAX
    hi_gap = _U64_MAX
    if deriv:
        for k in range(n):
            v = _bits(_dyad_at(x, y, dx, dy, j, a, b, k, sgn, k1, four_l1sq))
            lo_bits = min(lo_bits, v)
            hi_gap = min(hi_gap, _INF_BITS - v)
    else:
        for k in range(n):
            v = _bits(_dyad_pos_at(x, y, j, a, b, k, sgn, k1, four_l1sq))
            lo_bits = min(lo_bits, v)
            hi_gap = min(hi_gap, _INF_BITS - v)
    if lo_bits > _INF_BITS:  # every sample NaN
        return np.inf, np.inf, -np.inf
    lo, hi = _from_bits(lo_bits), _from_bits(_INF_BITS - hi_gap)
    m_lo = np.sqrt(lo) - dl
    m_hi = sl - np.sqrt(hi)
    c_lo = (s12 - lo) / den
    c_hi = (s12 - hi) / den
    return min(m_lo, m_hi), min(c_lo, c_hi), max(c_lo, c_hi)


@njit(**_NO_RC)
def _attach(x, y, dx, dy, j, a, b, u, v, known, length, deriv):
    """Place X = P + u e + v rot90(e), e = (Q - P) / |Q - P|.

    known: |Q - P| is a dyad length (P, Q on one dyad link), so use ``length`` instead of
    measuring it: the same value up to rounding, and no sqrt or divide per sample.
    """
    # Without ``deriv``: the same positions and no derivative rows.
    if known and not deriv:
        inv = 1.0 / length
        uu, vv = u * inv, v * inv
        for k in range(x.shape[1]):
            p_x, p_y = x[a, k], y[a, k]
            wx = x[b, k] - p_x
            wy = y[b, k] - p_y
            x[j, k] = p_x + (uu * wx - vv * wy)
            y[j, k] = p_y + (uu * wy + vv * wx)
    elif not deriv:
        for k in range(x.shape[1]):
            p_x, p_y = x[a, k], y[a, k]
            wx = x[b, k] - p_x
            wy = y[b, k] - p_y
            inv_len = 1.0 / np.sqrt(wx * wx + wy * wy)
            ex = wx * inv_len
            ey = wy * inv_len
            x[j, k] = p_x + u * ex - v * ey
            y[j, k] = p_y + u * ey + v * ex
    elif known:
        inv = 1.0 / length
        # P and Q lie on one rigid link: with U, V = (u, v) / |w|, X - P = U w + V rot90(w), and
        # X turns with the link at omega = cross(w, dw) / |w|^2: dX = dP + omega rot90(X - P).
        uu, vv, inv2 = u * inv, v * inv, inv * inv
        for k in range(x.shape[1]):
            p_x, p_y = x[a, k], y[a, k]
            wx = x[b, k] - p_x
            wy = y[b, k] - p_y
            ax = uu * wx - vv * wy
            ay = uu * wy + vv * wx
            omega = (wx * (dy[b, k] - dy[a, k]) - wy * (dx[b, k] - dx[a, k])) * inv2
            x[j, k] = p_x + ax
            y[j, k] = p_y + ay
            dx[j, k] = dx[a, k] - omega * ay
            dy[j, k] = dy[a, k] + omega * ax
    else:
        for k in range(x.shape[1]):
            p_x, p_y, dp_x, dp_y = x[a, k], y[a, k], dx[a, k], dy[a, k]
            wx = x[b, k] - p_x
            wy = y[b, k] - p_y
            inv_len = 1.0 / np.sqrt(wx * wx + wy * wy)
            ex = wx * inv_len
            ey = wy * inv_len
            dwx = dx[b, k] - dp_x
            dwy = dy[b, k] - dp_y
            t = ex * dwx + ey * dwy
            dex = (dwx - ex * t) * inv_len
            dey = (dwy - ey * t) * inv_len
            x[j, k] = p_x + u * ex - v * ey
            y[j, k] = p_y + u * ey + v * ex
            dx[j, k] = dp_x + u * dex - v * dey
            dy[j, k] = dp_y + u * dey + v * dex
