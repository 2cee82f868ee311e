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

from core.kinematics import kernel as SK

F64 = NDArray[np.float64]

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

NO_ROOT_VIOLATION = 1.0
ROOT_ITERATIONS = 6

# Output columns of the scalar block ``S`` (pop, N_SCALARS).
H_S, H_M, H_BAR, PSI2, PSI4, MSE, WIDTH, Y_MIN, ROOT_VIOL, N_ROOTS, TURNING, VALID, STEP, ADVANCE = range(14)
N_SCALARS = 14

# Designs per parallel task (scratch is allocated per task).
_CHUNK = 32
# Pieces of the psi union sorted by insertion below this count (else argsort).
_SMALL_SORT = 48


@njit(**_JIT)
def _rel(i, q, n):
    """``(i - q) mod n`` for i, q in [0, n) (what numpy's % gives there)."""
    r = i - q
    return r + n if r < 0.0 else r


@njit(**_JIT)
def _wrap(i, n):
    """``i mod n`` for an index within a few periods (no integer division in the hot loops)."""
    while i >= n:
        i -= n
    while i < 0:
        i += n
    return i


@njit(**_JIT)
def _herm(px, py, dx, dy, q):
    """Periodic cubic Hermite at fractional index q: (x, y, dx/dtheta, dy/dtheta)."""
    n = px.shape[0]
    h = 2.0 * np.pi / n
    fl = np.floor(q)
    u = q - fl
    i0 = _wrap(int(fl), n)
    i1 = _wrap(i0 + 1, n)
    u2 = u * u
    u3 = u * u * u
    a0 = 2 * u3 - 3 * u2 + 1
    a1 = u3 - 2 * u2 + u
    a2 = -2 * u3 + 3 * u2
    a3 = u3 - u2
    b0 = 6 * u2 - 6 * u
    b1 = 3 * u2 - 4 * u + 1
    b2 = -6 * u2 + 6 * u
    b3 = 3 * u2 - 2 * u
    mx0, mx1, my0, my1 = dx[i0] * h, dx[i1] * h, dy[i0] * h, dy[i1] * h
    x = a0 * px[i0] + a1 * mx0 + a2 * px[i1] + a3 * mx1
    y = a0 * py[i0] + a1 * my0 + a2 * py[i1] + a3 * my1
    vx = (b0 * px[i0] + b1 * mx0 + b2 * px[i1] + b3 * mx1) / h
    vy = (b0 * py[i0] + b1 * my0 + b2 * py[i1] + b3 * my1) / h
    return x, y, vx, vy


@njit(**_JIT)
def _parab(v, i):
    n = v.shape[0]
    a = v[_wrap(i - 1, n)]
    b = v[i]
    c = v[_wrap(i + 1, n)]
    den = a - 2.0 * b + c
    d = 0.5 * (a - c) / den if den != 0.0 else 0.0
    return min(max(d, -0.5), 0.5)


@njit(**_JIT)
def _vertex(y, i, start, length):
    """``core.analysis.metrics._window_extreme``'s value at sample i: the parabola's vertex if both
    neighbours lie in the window, else the sample."""
    n = y.shape[0]
    im, ip = _wrap(i - 1, n), _wrap(i + 1, n)
    rm, rp = _rel(im, start, n), _rel(ip, start, n)
    if rm > 0.0 and rm < length and rp > 0.0 and rp < length:
        a, b, c = y[im], y[i], y[ip]
        den = a - 2.0 * b + c
        d = 0.5 * (a - c) / den if den != 0.0 else 0.0
        d = min(max(d, -0.5), 0.5)
        return b - 0.25 * (a - c) * d
    return y[i]


@njit(**_JIT)
def _union_psi(lo, hi, cnt, offsets, phases, advance, a, L, H):
    """psi from the swing arc's blocked intervals (first cnt entries) for one layout."""
    period = 2.0 * abs(advance)
    if not period > 0.0:
        return np.nan
    k = 0
    for leg in range(offsets.shape[0]):
        sh = offsets[leg] + 2.0 * phases[leg] * advance
        for j in range(cnt):
            l0 = lo[j] + sh - a
            h0 = hi[j] + sh
            base = np.floor(l0 / period) * period
            l1 = l0 - base
            h1 = h0 - base
            if h1 - l1 >= period:
                return 0.0
            L[k] = l1
            H[k] = min(h1, period)
            k += 1
            if h1 > period:
                L[k] = 0.0
                H[k] = min(h1 - period, period)
                k += 1
    if k <= _SMALL_SORT:
        for j in range(1, k):  # insertion sort of (L, H) by L
            lj, hj = L[j], H[j]
            r = j - 1
            while r >= 0 and L[r] > lj:
                L[r + 1] = L[r]
                H[r + 1] = H[r]
                r -= 1
            L[r + 1] = lj
            H[r + 1] = hj
    else:
        order = np.argsort(L[:k])
        Ls, Hs = L[:k][order], H[:k][order]
        L[:k] = Ls
        H[:k] = Hs
    covered = 0.0
    reach = -np.inf
    for j in range(k):
        g = H[j] - max(L[j], reach)
        if g > 0.0:
            covered += g
        if H[j] > reach:
            reach = H[j]
    return 1.0 - min(covered, period) / period


@njit(**_JIT)
def work(n, n_legs):
    """Per-task scratch for ``_one``: ten float rows (see there) sized for n samples."""
    half = n // 2
    m = half + 1
    return (np.empty(n), np.empty(n), np.empty(n + half + 2), np.empty(n), np.empty(m), np.empty(m),
            np.empty(m), np.empty(m), np.empty(2 * n_legs * m + 2), np.empty(2 * n_legs * m + 2),
            np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n))


@njit(**_JIT)
def _one(px, py, dpx, dpy, qx, qy, T, period, a, b, offs2, ph2, offs4, ph4, W, index, pts, tans, S):
    """Every metric of one finite path: leg frame ``px, py`` and d/dtheta ``dpx, dpy``, design
    frame ``qx, qy``; results into this design's rows index (8,), pts, tans (8, 2), S."""
    f, df, csum, peak, wx, wh, lo_i, hi_i, L, H = W[0], W[1], W[2], W[3], W[4], W[5], W[6], W[7], W[8], W[9]
    n = px.shape[0]
    half_n = n / 2.0
    half = n // 2
    h = 2.0 * np.pi / n
    # One pass for the sequential reductions, so their dependency chains overlap: design-frame
    # width, y_min and mse; prefix sums of y (landing scores); extremes; turning number.
    xmin, xmax, ymin, acc = np.inf, -np.inf, np.inf, 0.0
    c = 0.0
    csum[0] = 0.0
    i3, i4, i5 = 0, 0, 0
    turns = 0
    sx, sy = px[0] - px[n - 1], py[0] - py[n - 1]
    for i in range(n):
        xq, yq = qx[i], qy[i]
        xmin = min(xmin, xq)
        xmax = max(xmax, xq)
        ymin = min(ymin, yq)
        ex, ey = xq - T[i, 0], yq - T[i, 1]
        acc += np.sqrt(ex * ex + ey * ey)
        yi = py[i]
        c += yi
        csum[i + 1] = c
        if yi < py[i3]:
            i3 = i
        if px[i] < px[i4]:
            i4 = i
        if px[i] > px[i5]:
            i5 = i
        j = i + 1 if i + 1 < n else 0
        tx, ty = px[j] - px[i], py[j] - yi
        cr = sx * ty - sy * tx
        if sy < 0.0 and ty >= 0.0 and cr > 0.0:
            turns += 1
        elif sy >= 0.0 and ty < 0.0 and cr < 0.0:
            turns -= 1
        sx, sy = tx, ty
    for i in range(n, n + half + 1):
        c += py[i - n]
        csum[i + 1] = c
    S[WIDTH] = xmax - xmin
    S[Y_MIN] = ymin
    S[MSE] = acc / n
    S[TURNING] = turns
    # f = y(t) - y(t + T/2) and its derivative
    if n % 2 == 0:
        for i in range(half):
            f[i] = py[i] - py[i + half]
            df[i] = dpy[i] - dpy[i + half]
        for i in range(half, n):
            f[i] = py[i] - py[i - half]
            df[i] = dpy[i] - dpy[i - half]
    else:
        for i in range(n):
            _, ys, _, dys = _herm(px, py, dpx, dpy, i + half_n)
            f[i] = py[i] - ys
            df[i] = dpy[i] - dys
    # landing roots
    n_roots = 0
    best_score = np.inf
    best_i = 0
    best_u = 0.0
    for i in range(n):
        i1 = i + 1 if i + 1 < n else 0
        f0, f1 = f[i], f[i1]
        if (f0 >= 0.0) == (f1 >= 0.0):
            continue
        n_roots += 1
        m0, m1 = df[i] * h, df[i1] * h
        u = f0 / (f0 - f1)
        lo, hi = 0.0, 1.0
        s0 = f0 >= 0.0
        for _ in range(ROOT_ITERATIONS):
            u2 = u * u
            u3 = u * u * u
            val = (2 * u3 - 3 * u2 + 1) * f0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * f1 + (u3 - u2) * m1
            der = (6 * u2 - 6 * u) * f0 + (3 * u2 - 4 * u + 1) * m0 + (-6 * u2 + 6 * u) * f1 + (3 * u2 - 2 * u) * m1
            if val == 0.0:
                break
            if (val >= 0.0) == s0:
                lo = u
            else:
                hi = u
            nxt = u - val / der if der != 0.0 else -1.0  # -1: outside, bisect
            u = nxt if (nxt >= lo and nxt <= hi) else 0.5 * (lo + hi)
        score = (csum[i + half + 2] - csum[i + 1]) / (half + 1)
        if score < best_score:
            best_score = score
            best_i = i
            best_u = u
    viol = 0.0
    if n_roots == 0:
        viol = NO_ROOT_VIOLATION
    elif n_roots > 2:
        for i in range(n):
            peak[i] = 0.0
        cnt = 0
        for i in range(n):
            if (f[i] >= 0.0) != (f[_wrap(i + 1, n)] >= 0.0):
                cnt += 1
            lab = cnt % n_roots
            peak[lab] = max(peak[lab], abs(f[i]))
        srt = np.sort(peak)
        viol = 0.5 * (srt.sum() - srt[-1] - srt[-2])
    S[N_ROOTS] = n_roots
    S[ROOT_VIOL] = viol
    q1 = (best_i + best_u) % n
    q2 = (q1 + half_n) % n
    q3 = i3 + _parab(py, i3)
    q4 = i4 + _parab(px, i4)
    q5 = i5 + _parab(px, i5)
    # swing peaks
    ia, ib, isw = -1, -1, -1
    for i in range(n):
        rel = _rel(i, q2, n)
        if not (rel > 0.0 and rel < half_n):
            continue
        yi = py[i]
        if isw < 0 or yi > py[isw]:
            isw = i
        if yi > py[i - 1 if i > 0 else n - 1] and yi >= py[i + 1 if i + 1 < n else 0]:
            if ia < 0 or yi > py[ia]:
                ib = ia
                ia = i
            elif ib < 0 or yi > py[ib]:
                ib = i
    if isw < 0:
        isw = 0
    if ia < 0:
        ia = isw
        ib = isw
    elif ib < 0:
        ib = ia
    ra, rb = _rel(ia, q2, n), _rel(ib, q2, n)
    if ra <= rb:
        i7, i8, r7, r8 = ia, ib, ra, rb
    else:
        i7, i8, r7, r8 = ib, ia, rb, ra
    q7 = i7 + _parab(py, i7)
    q8 = i8 + _parab(py, i8)
    # t6: lowest point between t7 and t8; stance window extremes (samples strictly inside
    # (t1, t1 + T/2)) for h_s
    i6 = -1
    q1w = q1 % n
    smax, smin = -1, -1
    for i in range(n):
        yi = py[i]
        rel = _rel(i, q2, n)
        if rel >= r7 and rel <= r8 and (i6 < 0 or yi < py[i6]):
            i6 = i
        rs = _rel(i, q1w, n)
        if rs > 0.0 and rs < half_n:
            if smax < 0 or yi > py[smax]:
                smax = i
            if smin < 0 or yi < py[smin]:
                smin = i
    if i6 < 0:
        i6 = 0
    q6 = q7 if i6 == i7 else i6 + _parab(py, i6)
    qs = (q1, q2, q3, q4, q5, q6, q7, q8)
    for k in range(8):
        q = qs[k] % n
        index[k] = q
        x, y, vx, vy = _herm(px, py, dpx, dpy, q)
        pts[k, 0] = x
        pts[k, 1] = y
        tans[k, 0] = vx
        tans[k, 1] = vy
    # stance fluctuation (core.analysis.metrics.stance_fluctuation)
    e1, e2 = pts[0, 1], pts[1, 1]
    wmax = _vertex(py, smax, index[0], half_n) if smax >= 0 else -np.inf
    wmin = _vertex(py, smin, index[0], half_n) if smin >= 0 else np.inf
    S[H_S] = max(wmax, max(e1, e2)) - min(wmin, min(e1, e2))
    # walking trajectory (swing arc) and its heights
    m = n // 2 + 1
    c1x, c2x = pts[0, 0], pts[1, 0]
    if n % 2 == 0:
        # the swing samples sit one sample apart: the Hermite weights are the same for all of them
        w2 = _weights(index[1])
        w1 = _weights(index[0])
        i2, i1 = int(np.floor(index[1])), int(np.floor(index[0]))
        for j in range(m):
            x2, y2 = _herm_w(px, py, dpx, dpy, _wrap(i2 + j, n), _wrap(i2 + j + 1, n), w2, h)
            x1, y1 = _herm_w(px, py, dpx, dpy, _wrap(i1 + j, n), _wrap(i1 + j + 1, n), w1, h)
            wx[j] = x2 - x1 + c1x
            wh[j] = y2 - y1
    else:
        for j in range(m):
            s = j * (half_n / (m - 1))
            x2, y2, _, _ = _herm(px, py, dpx, dpy, index[1] + s)
            x1, y1, _, _ = _herm(px, py, dpx, dpy, index[0] + s)
            wx[j] = x2 - x1 + c1x
            wh[j] = y2 - y1
    wh[0] = 0.0
    wh[m - 1] = 0.0
    wx[0] = c2x
    wx[m - 1] = 2.0 * c1x - c2x
    S[STEP] = np.hypot(wx[m - 1] - wx[0], 2.0 * pts[0, 1] - pts[1, 1] - pts[1, 1])
    advance = c1x - c2x
    S[ADVANCE] = advance
    hm = -np.inf
    tr = 0.0
    for j in range(m):
        hm = max(hm, wh[j])
        if j > 0:
            tr += wh[j] + wh[j - 1]
    S[H_M] = hm
    S[H_BAR] = tr / (2.0 * (m - 1))
    # blocked intervals below height b, touching pieces merged (see the module docstring)
    cnt = 0
    touching = False
    for j in range(m - 1):
        x0, x1, h0, h1 = wx[j], wx[j + 1], wh[j], wh[j + 1]
        dh = h1 - h0
        if dh == 0.0:
            if h0 > b:
                touching = False
                continue
            ulo, uhi = 0.0, 1.0
        else:
            u = (b - h0) / dh
            if dh > 0.0:
                ulo, uhi = 0.0, min(u, 1.0)
            else:
                ulo, uhi = max(u, 0.0), 1.0
            if ulo > uhi:
                touching = False
                continue
        xa = x0 + ulo * (x1 - x0)
        xb = x0 + uhi * (x1 - x0)
        lo_j, hi_j = min(xa, xb), max(xa, xb)
        if touching and ulo == 0.0:  # shares the arc point wx[j] with the previous piece
            lo_i[cnt - 1] = min(lo_i[cnt - 1], lo_j)
            hi_i[cnt - 1] = max(hi_i[cnt - 1], hi_j)
        else:
            lo_i[cnt] = lo_j
            hi_i[cnt] = hi_j
            cnt += 1
        touching = uhi == 1.0
    S[PSI2] = _union_psi(lo_i, hi_i, cnt, offs2, ph2, advance, a, L, H)
    S[PSI4] = _union_psi(lo_i, hi_i, cnt, offs4, ph4, advance, a, L, H)


@njit(**_JIT)
def _weights(q):
    """Hermite position weights (p0, h m0, p1, h m1) at the fractional part of q."""
    u = q - np.floor(q)
    u2 = u * u
    u3 = u * u * u
    return (2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2)


@njit(**_JIT)
def _herm_w(px, py, dx, dy, i0, i1, w, h):
    """Position between samples i0 and i1 with precomputed weights (see ``_weights``)."""
    x = w[0] * px[i0] + w[1] * (dx[i0] * h) + w[2] * px[i1] + w[3] * (dx[i1] * h)
    y = w[0] * py[i0] + w[1] * (dy[i0] * h) + w[2] * py[i1] + w[3] * (dy[i1] * h)
    return x, y


@njit(**_JIT)
def _invalid(p, index, pts, tans, S):
    """Row p of a path with a non-finite sample: NaN outputs, ``VALID`` = 0."""
    for k in range(N_SCALARS):
        S[p, k] = np.nan
    S[p, VALID] = 0.0
    S[p, ROOT_VIOL] = np.inf
    S[p, N_ROOTS] = 0.0
    S[p, TURNING] = 0.0
    for k in range(8):
        index[p, k] = np.nan
        for c in range(2):
            pts[p, k, c] = np.nan
            tans[p, k, c] = np.nan


@njit(**_JIT)
def _finite(px, py, dpx, dpy, qx, qy):
    """True iff every sample of the six rows is finite (x - x is 0 for finite x, else NaN)."""
    ok = True
    for i in range(px.shape[0]):
        s = (px[i] - px[i]) + (py[i] - py[i]) + (dpx[i] - dpx[i]) + (dpy[i] - dpy[i])
        ok &= s + (qx[i] - qx[i]) + (qy[i] - qy[i]) == 0.0
    return ok


@njit(**_JIT)
def _analyse(p, px, py, dpx, dpy, qx, qy, target, period, a, b, offs2, ph2, offs4, ph4, W, index, pts, tans, S):
    """Row p from its leg path, d/dtheta and design-frame path: NaN unless every sample is finite."""
    if not _finite(px, py, dpx, dpy, qx, qy):
        _invalid(p, index, pts, tans, S)
        return
    S[p, VALID] = 1.0
    _one(px, py, dpx, dpy, qx, qy, target, period, a, b, offs2, ph2, offs4, ph4, W, index[p], pts[p], tans[p], S[p])


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
                offs4, ph4, mmin, cmin, cmax, neg, broken, index, pts, tans, S):
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
               mmin, cmin, cmax, neg, broken, index, pts, tans, S):
        if len(solver_digest) == 0:
            return
        _fused_chunk(0, vals.shape[0], ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b,
                     offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken, index, pts, tans, S)

    @njit(**_JIT, parallel=True)
    def parallel(ops, vals, ct, st, tracked, sinks, links, stage, target, period, a, b, offs2, ph2, offs4, ph4,
                 mmin, cmin, cmax, neg, broken, index, pts, tans, S):
        if len(solver_digest) == 0:
            return
        pop = vals.shape[0]
        for c in prange((pop + _CHUNK - 1) // _CHUNK):
            _fused_chunk(c * _CHUNK, min(pop, (c + 1) * _CHUNK), ops, vals, ct, st, tracked, sinks, links, stage,
                         target, period, a, b, offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken, index, pts,
                         tans, S)

    return serial, parallel


# The fused kernels call the solver kernel, whose source numba's cache does not watch: their
# cache keys carry a digest of it (a closure variable), so editing the solver recompiles them.
_SOLVER_DIGEST = hashlib.sha1(Path(SK.__file__).read_bytes()).hexdigest()
_fused_chunk = _fused_designs(_SOLVER_DIGEST)
_fused_serial, _fused_parallel = _fused_runs(_SOLVER_DIGEST)


def run_designs(
    ops: NDArray[np.int64], vals: F64, theta: F64, tracked: int, stage: tuple[float, float, float, float],
    target: F64, period: float, a: float, b: float, offs2: F64, ph2: F64, offs4: F64, ph4: F64, parallel: bool,
) -> tuple[F64, F64, NDArray[np.bool_], F64, F64, F64, F64]:
    """Solve every design (``core.kinematics.kernel``) and analyse its path in the same pass.

    The results of ``solver_numba.solve_all(..., stage=stage)`` followed by ``run`` on its point,
    leg and dleg, without those ``(pop, n_samples, 2)`` arrays.

    Returns:
        mmin ``(pop, n_steps)`` and neg ``(pop,)`` as ``solver_numba.run``; broken ``(pop,)``
        True where some sample has a non-finite joint (``~valid.any(1)``); index, pts, tans, S
        as ``run`` fills them.
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
    index = np.empty((pop, 8))
    pts = np.empty((pop, 8, 2))
    tans = np.empty((pop, 8, 2))
    S = np.empty((pop, N_SCALARS))
    kernel = _fused_parallel if parallel else _fused_serial
    kernel(prog.ops, vals, ct, st, prog.tracked, prog.sinks, prog.links,
           tuple(float(v) for v in stage), np.ascontiguousarray(target, dtype=np.float64),
           float(period), float(a), float(b), offs2, ph2, offs4, ph4, mmin, cmin, cmax, neg, broken,
           index, pts, tans, S)
    return mmin, neg, broken, index, pts, tans, S
