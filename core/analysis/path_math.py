"""Small compiled helpers of the path kernel: periodic indices, Hermite interpolation of a sampled path,
parabolic extremum vertices, and the union of blocked swing-arc pieces behind psi."""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
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
