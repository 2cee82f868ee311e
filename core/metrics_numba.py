"""Fast kernel (numba) of the analysis stack; same results as the numpy reference modules.

One pass per design over its samples computes what ``core.trajectory.feature_points``,
``core.metrics`` (h_s, h_m, h_bar, psi), ``core.gait.walking_trajectory`` and ``core.shape.mse``
compute with whole-array numpy operations; the same rules, in the same order (see those modules
for the definitions). ``tests/test_metrics_kernel_matches_reference.py`` holds them equal.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

F64 = NDArray[np.float64]

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

NO_ROOT_VIOLATION = 1.0
ROOT_ITERATIONS = 6

# Output columns of the scalar block ``S`` (pop, N_SCALARS).
H_S, H_M, H_BAR, PSI2, PSI4, MSE, WIDTH, Y_MIN, ROOT_VIOL, N_ROOTS, TURNING, VALID, STEP, ADVANCE = range(14)
N_SCALARS = 14


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
def _herm(P, D, q, out):
    """Periodic cubic Hermite at fractional index q: out = (x, y, dx/dtheta, dy/dtheta)."""
    n = P.shape[0]
    h = 2.0 * np.pi / n
    fl = np.floor(q)
    u = q - fl
    i0 = _wrap(int(fl), n)
    i1 = _wrap(i0 + 1, n)
    u2 = u * u
    u3 = u2 * u
    a0 = 2 * u3 - 3 * u2 + 1
    a1 = u3 - 2 * u2 + u
    a2 = -2 * u3 + 3 * u2
    a3 = u3 - u2
    b0 = 6 * u2 - 6 * u
    b1 = 3 * u2 - 4 * u + 1
    b2 = -6 * u2 + 6 * u
    b3 = 3 * u2 - 2 * u
    for c in range(2):
        out[c] = a0 * P[i0, c] + a1 * D[i0, c] * h + a2 * P[i1, c] + a3 * D[i1, c] * h
        out[2 + c] = (b0 * P[i0, c] + b1 * D[i0, c] * h + b2 * P[i1, c] + b3 * D[i1, c] * h) / h


@njit(**_JIT)
def _weights(q):
    """Hermite position weights (p0, h m0, p1, h m1) at the fractional part of q."""
    u = q - np.floor(q)
    u2 = u * u
    u3 = u2 * u
    return (2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2)


@njit(**_JIT)
def _herm_w(P, D, i0, i1, w, h):
    """Position between samples i0 and i1 with precomputed weights (see ``_weights``)."""
    x = w[0] * P[i0, 0] + w[1] * D[i0, 0] * h + w[2] * P[i1, 0] + w[3] * D[i1, 0] * h
    y = w[0] * P[i0, 1] + w[1] * D[i0, 1] * h + w[2] * P[i1, 1] + w[3] * D[i1, 1] * h
    return x, y


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
def _window_extreme(y, start, length, largest):
    n = y.shape[0]
    best_i = -1
    for i in range(n):
        rel = _rel(i, start, n)
        if rel > 0.0 and rel < length:
            if best_i < 0 or (largest and y[i] > y[best_i]) or ((not largest) and y[i] < y[best_i]):
                best_i = i
    if best_i < 0:
        return -np.inf if largest else np.inf
    im, ip = _wrap(best_i - 1, n), _wrap(best_i + 1, n)
    rm, rp = _rel(im, start, n), _rel(ip, start, n)
    if rm > 0.0 and rm < length and rp > 0.0 and rp < length:
        a, b, c = y[im], y[best_i], y[ip]
        den = a - 2.0 * b + c
        d = 0.5 * (a - c) / den if den != 0.0 else 0.0
        d = min(max(d, -0.5), 0.5)
        return b - 0.25 * (a - c) * d
    return y[best_i]


@njit(**_JIT)
def _union_psi(lo, hi, cnt, offsets, phases, advance, a):
    """psi from the swing arc's blocked intervals (first cnt entries) for one layout."""
    period = 2.0 * abs(advance)
    if not period > 0.0:
        return np.nan
    n_legs = offsets.shape[0]
    m = 2 * n_legs * cnt
    L = np.empty(m)
    H = np.empty(m)
    k = 0
    for leg in range(n_legs):
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
    order = np.argsort(L[:k])
    covered = 0.0
    reach = -np.inf
    for j in range(k):
        i = order[j]
        g = H[i] - max(L[i], reach)
        if g > 0.0:
            covered += g
        if H[i] > reach:
            reach = H[i]
    return 1.0 - min(covered, period) / period


@njit(**_JIT)
def _one(P, D, Q, T, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    n = P.shape[0]
    px, py, dy = P[:, 0], P[:, 1], D[:, 1]
    half_n = n / 2.0
    h = 2.0 * np.pi / n
    tmp = np.empty(4)
    # design-frame width, y_min, mse
    xmin, xmax, ymin, acc = np.inf, -np.inf, np.inf, 0.0
    for i in range(n):
        xmin = min(xmin, Q[i, 0])
        xmax = max(xmax, Q[i, 0])
        ymin = min(ymin, Q[i, 1])
        ex, ey = Q[i, 0] - T[i, 0], Q[i, 1] - T[i, 1]
        acc += np.sqrt(ex * ex + ey * ey)
    S[WIDTH] = xmax - xmin
    S[Y_MIN] = ymin
    S[MSE] = acc / n
    # y(t + T/2) and its derivative
    ys = np.empty(n)
    dys = np.empty(n)
    if n % 2 == 0:
        for i in range(n):
            j = _wrap(i + n // 2, n)
            ys[i] = py[j]
            dys[i] = dy[j]
    else:
        for i in range(n):
            _herm(P, D, i + half_n, tmp)
            ys[i] = tmp[1]
            dys[i] = tmp[3]
    f = py - ys
    df = dy - dys
    # landing roots
    half = n // 2
    csum = np.empty(n + half + 2)
    csum[0] = 0.0
    for i in range(n + half + 1):
        csum[i + 1] = csum[i] + py[_wrap(i, n)]
    n_roots = 0
    best_score = np.inf
    best_i = 0
    best_u = 0.0
    for i in range(n):
        i1 = _wrap(i + 1, n)
        if (f[i] >= 0.0) == (f[i1] >= 0.0):
            continue
        n_roots += 1
        f0, f1 = f[i], f[i1]
        m0, m1 = df[i] * h, df[i1] * h
        u = f0 / (f0 - f1)
        lo, hi = 0.0, 1.0
        s0 = f0 >= 0.0
        for _ in range(ROOT_ITERATIONS):
            u2 = u * u
            u3 = u2 * u
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
        peak = np.zeros(n)
        c = 0
        for i in range(n):
            if (f[i] >= 0.0) != (f[_wrap(i + 1, n)] >= 0.0):
                c += 1
            lab = c % n_roots
            peak[lab] = max(peak[lab], abs(f[i]))
        peak = np.sort(peak)
        viol = 0.5 * (peak.sum() - peak[-1] - peak[-2])
    S[N_ROOTS] = n_roots
    S[ROOT_VIOL] = viol
    q1 = (best_i + best_u) % n
    q2 = (q1 + half_n) % n
    # extremes of the whole cycle
    i3, i4, i5 = 0, 0, 0
    for i in range(n):
        if py[i] < py[i3]:
            i3 = i
        if px[i] < px[i4]:
            i4 = i
        if px[i] > px[i5]:
            i5 = i
    q3 = i3 + _parab(py, i3)
    q4 = i4 + _parab(px, i4)
    q5 = i5 + _parab(px, i5)
    # swing peaks
    ia, ib, isw = -1, -1, -1
    for i in range(n):
        rel = _rel(i, q2, n)
        if not (rel > 0.0 and rel < half_n):
            continue
        if isw < 0 or py[i] > py[isw]:
            isw = i
        if py[i] > py[_wrap(i - 1, n)] and py[i] >= py[_wrap(i + 1, n)]:
            if ia < 0 or py[i] > py[ia]:
                ib = ia
                ia = i
            elif ib < 0 or py[i] > py[ib]:
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
    i6 = -1
    for i in range(n):
        rel = _rel(i, q2, n)
        if rel >= r7 and rel <= r8 and (i6 < 0 or py[i] < py[i6]):
            i6 = i
    if i6 < 0:
        i6 = 0
    q6 = q7 if i6 == i7 else i6 + _parab(py, i6)
    qs = (q1, q2, q3, q4, q5, q6, q7, q8)
    for k in range(8):
        q = qs[k] % n
        index[k] = q
        _herm(P, D, q, tmp)
        pts[k, 0] = tmp[0]
        pts[k, 1] = tmp[1]
        tans[k, 0] = tmp[2]
        tans[k, 1] = tmp[3]
    # turning number of the polygon
    turns = 0
    sx, sy = px[0] - px[n - 1], py[0] - py[n - 1]
    for i in range(n):
        j = _wrap(i + 1, n)
        tx, ty = px[j] - px[i], py[j] - py[i]
        cr = sx * ty - sy * tx
        if sy < 0.0 and ty >= 0.0 and cr > 0.0:
            turns += 1
        elif sy >= 0.0 and ty < 0.0 and cr < 0.0:
            turns -= 1
        sx, sy = tx, ty
    S[TURNING] = turns
    # stance fluctuation
    e1, e2 = pts[0, 1], pts[1, 1]
    hi = max(_window_extreme(py, index[0], half_n, True), max(e1, e2))
    lo = min(_window_extreme(py, index[0], half_n, False), min(e1, e2))
    S[H_S] = hi - lo
    # walking trajectory (swing arc) and its heights
    m = n // 2 + 1
    wx = np.empty(m)
    wh = np.empty(m)
    c1x, c2x = pts[0, 0], pts[1, 0]
    if n % 2 == 0:
        # the swing samples sit one sample apart: the Hermite weights are the same for all of them
        w2 = _weights(index[1])
        w1 = _weights(index[0])
        i2, i1 = int(np.floor(index[1])), int(np.floor(index[0]))
        for j in range(m):
            x2, y2 = _herm_w(P, D, _wrap(i2 + j, n), _wrap(i2 + j + 1, n), w2, h)
            x1, y1 = _herm_w(P, D, _wrap(i1 + j, n), _wrap(i1 + j + 1, n), w1, h)
            wx[j] = x2 - x1 + c1x
            wh[j] = y2 - y1
    else:
        tmp2 = np.empty(4)
        for j in range(m):
            s = j * (half_n / (m - 1))
            _herm(P, D, index[1] + s, tmp)
            _herm(P, D, index[0] + s, tmp2)
            wx[j] = tmp[0] - tmp2[0] + c1x
            wh[j] = tmp[1] - tmp2[1]
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
    # blocked intervals below height b
    lo_i = np.empty(m - 1)
    hi_i = np.empty(m - 1)
    cnt = 0
    for j in range(m - 1):
        x0, x1, h0, h1 = wx[j], wx[j + 1], wh[j], wh[j + 1]
        dh = h1 - h0
        if dh == 0.0:
            if h0 > b:
                continue
            ulo, uhi = 0.0, 1.0
        else:
            u = (b - h0) / dh
            if dh > 0.0:
                ulo, uhi = 0.0, min(u, 1.0)
            else:
                ulo, uhi = max(u, 0.0), 1.0
            if ulo > uhi:
                continue
        xa = x0 + ulo * (x1 - x0)
        xb = x0 + uhi * (x1 - x0)
        lo_i[cnt] = min(xa, xb)
        hi_i[cnt] = max(xa, xb)
        cnt += 1
    S[PSI2] = _union_psi(lo_i, hi_i, cnt, offs2, ph2, advance, a)
    S[PSI4] = _union_psi(lo_i, hi_i, cnt, offs4, ph4, advance, a)


@njit(**_JIT)
def _row(p, leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    """Design p: NaN outputs (``VALID`` = 0) if any leg, dleg or point sample is non-finite."""
    n = leg.shape[1]
    ok = True
    for i in range(n):
        for c in range(2):
            if not (np.isfinite(leg[p, i, c]) and np.isfinite(dleg[p, i, c]) and np.isfinite(point[p, i, c])):
                ok = False
    if not ok:
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
        return
    S[p, VALID] = 1.0
    _one(leg[p], dleg[p], point[p], target, period, a, b, offs2, ph2, offs4, ph4, index[p], pts[p], tans[p], S[p])


@njit(**_JIT, parallel=True)
def _run_parallel(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    for p in prange(leg.shape[0]):
        _row(p, leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S)


@njit(**_JIT)
def _run_serial(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S):
    for p in range(leg.shape[0]):
        _row(p, leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S)


def run(
    leg: F64, dleg: F64, point: F64, target: F64, period: float, a: float, b: float,
    offs2: F64, ph2: F64, offs4: F64, ph4: F64, index: F64, pts: F64, tans: F64, S: F64,
) -> None:
    """Fill ``index (pop, 8)``, ``pts``/``tans (pop, 8, 2)`` and ``S (pop, N_SCALARS)`` for every design.

    Rows with a non-finite leg, dleg or point sample are left NaN (``VALID`` = 0). Designs run in
    parallel from ``core.kinematics.PARALLEL_MIN_POP`` on, like the solver.
    """
    from core.kinematics import PARALLEL_MIN_POP

    kernel = _run_parallel if leg.shape[0] >= PARALLEL_MIN_POP else _run_serial
    kernel(leg, dleg, point, target, period, a, b, offs2, ph2, offs4, ph4, index, pts, tans, S)
