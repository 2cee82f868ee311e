"""The numba analysis of one design's path: feature points, h_s, h_m, h_bar, psi, MSE (``core.analysis.kernel``
runs it over populations; the numpy reference modules define what it computes).

``_analyse`` takes one design's tracked point and its d/dtheta over the crank samples and writes the
design's row of the scalar block ``S`` (columns below), its feature-point indices and tangents.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from core.analysis.features import LOBE_TOL, NO_ROOT_VIOLATION
from core.analysis.path_math import _herm, _herm_w, _parab, _rel, _union_psi, _vertex, _weights, _wrap

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

ROOT_ITERATIONS = 6

# Output columns of the scalar block ``S`` (pop, N_SCALARS).
H_S, H_M, H_BAR, PSI2, PSI4, MSE, WIDTH, Y_MIN, ROOT_VIOL, N_ROOTS, TURNING, VALID, STEP, ADVANCE = range(14)
N_SCALARS = 14

# Designs per parallel task (scratch is allocated per task).
_CHUNK = 32


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
        for k in range(n_roots):
            peak[k] = 0.0
        cnt = 0
        for i in range(n):
            lab = cnt % n_roots  # sample i's lobe: a crossing at i is between i and i + 1
            peak[lab] = max(peak[lab], abs(f[i]))
            if (f[i] >= 0.0) != (f[_wrap(i + 1, n)] >= 0.0):
                cnt += 1
        # Every lobe but the two largest (found in one pass; no sort, and no sum-then-subtract round-off).
        k1, k2 = 0, 1
        if peak[1] > peak[0]:
            k1, k2 = 1, 0
        for k in range(2, n_roots):
            if peak[k] > peak[k1]:
                k1, k2 = k, k1
            elif peak[k] > peak[k2]:
                k2 = k
        for k in range(n_roots):
            if k != k1 and k != k2:
                viol += 0.5 * max(peak[k] - LOBE_TOL, 0.0)
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
