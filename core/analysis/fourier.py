"""Fourier descriptors of closed curves and the best similarity transform between two curves.

A curve ``(x, y)`` is the complex signal ``z = x + i y``. Descriptors come from the FFT of the
curve resampled uniformly in arc length; the similarity transform works on the samples as given
(time- or crank-uniform), so its cyclic shift is a crank-phase offset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]

DEFAULT_HARMONICS = 16
DEFAULT_RESAMPLE = 256


def _batch(curve: F64) -> F64:
    c = np.asarray(curve, dtype=np.float64)
    return c[None] if c.ndim == 2 else c


def resample_arclength(curve: F64, n: int = DEFAULT_RESAMPLE) -> F64:
    """Resample closed polylines uniformly in arc length, starting at their first point.

    Args:
        curve: ``(pop, m, 2)`` or ``(m, 2)`` closed curves, no repeated closing point (mm).
        n: output samples.

    Returns:
        ``(pop, n, 2)``; NaN rows where a curve has a NaN or zero length.
    """
    c = np.ascontiguousarray(_batch(curve))
    out = np.empty((c.shape[0], n, 2))
    _resample(c, out)
    return out


@numba.njit(cache=True, nogil=True)
def _resample(c: F64, out: F64) -> None:  # pragma: no cover - compiled
    # One walk along each polyline: output point j sits at arc length j L / n.
    pop, m, n = c.shape[0], c.shape[1], out.shape[1]
    seg = np.empty(m)
    for p in range(pop):
        total = 0.0
        for i in range(m):
            k = i + 1 if i + 1 < m else 0
            dx, dy = c[p, k, 0] - c[p, i, 0], c[p, k, 1] - c[p, i, 1]
            seg[i] = np.sqrt(dx * dx + dy * dy)  # hypot is ~4x slower; no lengths near under/overflow here
            total += seg[i]
        if not (np.isfinite(total) and total > 0.0):
            out[p] = np.nan
            continue
        i, s0 = 0, 0.0  # segment i runs from arc length s0 to s0 + seg[i]
        for j in range(n):
            u = j * (total / n)
            while i < m - 1 and s0 + seg[i] <= u:
                s0 += seg[i]
                i += 1
            k = i + 1 if i + 1 < m else 0
            w = (u - s0) / seg[i] if seg[i] > 0.0 else 0.0
            out[p, j, 0] = c[p, i, 0] + w * (c[p, k, 0] - c[p, i, 0])
            out[p, j, 1] = c[p, i, 1] + w * (c[p, k, 1] - c[p, i, 1])


def harmonic_numbers(n_harmonics: int = DEFAULT_HARMONICS) -> NDArray[np.int64]:
    """``(2K,)`` the harmonic k of each descriptor entry: ``1 ... K, -1 ... -K``."""
    k = np.arange(1, n_harmonics + 1)
    return np.concatenate([k, -k])


def coefficients(curve: F64, n_harmonics: int = DEFAULT_HARMONICS, n_resample: int = DEFAULT_RESAMPLE) -> C128:
    """Raw complex Fourier coefficients ``Z_k`` (``k = 1..K, -1..-K``) of the arc-length-resampled curve.

    ``z(s) = sum_k Z_k exp(2 pi i k s)`` with s the arc-length fraction; ``(pop, 2K)`` (mm).
    """
    r = resample_arclength(curve, n_resample)
    z = r[..., 0] + 1j * r[..., 1]
    Z = np.fft.fft(z, axis=1) / n_resample
    return Z[:, harmonic_numbers(n_harmonics) % n_resample]


def descriptors(curve: F64, n_harmonics: int = DEFAULT_HARMONICS, n_resample: int = DEFAULT_RESAMPLE) -> C128:
    """Normalised Fourier descriptors ``(pop, 2K)`` (harmonics ``1..K, -1..-K``).

    Invariant to translation (Z_0 dropped), scale (unit energy ``sum |Z_k|^2 = 1``), rotation and
    start point: with ``Z_k -> Z_k exp(-i (alpha + k sigma))``, alpha and sigma make Z_1 and Z_-1
    real and positive. That leaves sigma and sigma + pi; the branch whose largest even harmonic has
    a non-negative real part is kept. Orientation (traversal direction) is not normalised.

    Args:
        curve: ``(pop, m, 2)`` or ``(m, 2)`` closed curves (mm).
        n_harmonics: K.
        n_resample: arc-length samples fed to the FFT.
    """
    Z = coefficients(curve, n_harmonics, n_resample)
    _normalise(Z, n_harmonics)
    return Z


@numba.njit(cache=True, nogil=True)
def _normalise(Z: C128, K: int) -> None:  # pragma: no cover - compiled
    # descriptors' normalisation, in place, row by row (entries k = 1..K, -1..-K); a row with a NaN stays NaN.
    for p in range(Z.shape[0]):
        e = 0.0
        for j in range(2 * K):
            e += Z[p, j].real * Z[p, j].real + Z[p, j].imag * Z[p, j].imag
        e = np.sqrt(e)
        if not e > 0.0:  # NaN, or a path that does not move: no shape
            Z[p, :] = np.nan
            continue
        for j in range(2 * K):
            Z[p, j] = Z[p, j] / e
        a1, am1 = np.angle(Z[p, 0]), np.angle(Z[p, K])
        sigma, alpha = 0.5 * (a1 - am1), 0.5 * (a1 + am1)
        # exp(-i (alpha + k sigma)) = exp(-i alpha) exp(-i sigma)^k: one exp per row, the powers by products.
        ea, es, pw = np.exp(-1j * alpha), np.exp(-1j * sigma), 1.0 + 0.0j
        for j in range(K):
            pw = pw * es
            Z[p, j] = Z[p, j] * (ea * pw)
            Z[p, K + j] = Z[p, K + j] * (ea * np.conj(pw))
        # The largest even harmonic (first of equals, k = 2, 4, ..., then -2, -4, ...) decides the branch.
        best, at = -1.0, -1
        for j in range(2 * K):
            k = j + 1 if j < K else K - j - 1
            if k % 2 == 0:
                m = np.abs(Z[p, j])
                if m > best:
                    best, at = m, j
        if at >= 0 and Z[p, at].real < 0.0:
            for j in range(2 * K):
                k = j + 1 if j < K else K - j - 1
                if k % 2 == 0:
                    Z[p, j] = -Z[p, j]


def descriptor_distance(a: C128, b: C128, n_grid: int = 1024) -> F64:
    """Distance between descriptor sets, minimised over rotation and start point.

    ``min over alpha, sigma`` of ``|a - b exp(i (alpha + k sigma))|``: for each sigma the best alpha
    is closed-form, leaving ``|a|^2 + |b|^2 - 2 max_sigma |C(sigma)|`` with the trigonometric
    polynomial ``C(sigma) = sum_k conj(a_k) b_k exp(i k sigma)``, maximised on a grid (by FFT) then
    by three Newton steps. So the value does not depend on the normalisation branch.

    Args:
        a, b: ``(pop, 2K)`` or ``(2K,)`` descriptors from ``descriptors`` (same K).
        n_grid: grid points in sigma (>= 4K).

    Returns:
        ``(pop,)`` >= 0; NaN where either side is NaN.
    """
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    a, b = np.broadcast_arrays(a, b)
    kk = harmonic_numbers(a.shape[1] // 2)
    w = np.conj(a) * b
    grid = np.zeros((w.shape[0], n_grid), complex)
    grid[:, kk % n_grid] = w
    C = np.fft.ifft(grid, axis=1)  # C(2 pi j / n_grid) / n_grid
    out = np.empty(len(w))
    # Writeable C arrays whatever came in: broadcast views are read-only, another kernel signature (the studio's
    # warm-up compiles one; a one-design evaluation then compiled a second).
    a, b = (np.require(v, np.complex128, ("C", "W")) for v in (a, b))
    _closest(a, b, np.require(w, np.complex128, ("C", "W")), kk.astype(np.float64), C, out)
    return out


@numba.njit(cache=True, nogil=True)
def _powers(sig: float, e: C128) -> None:  # pragma: no cover - compiled
    # e = exp(i k sig) for the harmonics k = 1..K, -1..-K (harmonic_numbers' order), by products of one exp.
    K = len(e) // 2
    z, pw = np.exp(1j * sig), 1.0 + 0.0j
    for j in range(K):
        pw = pw * z
        e[j], e[K + j] = pw, np.conj(pw)


@numba.njit(cache=True, nogil=True)
def _closest(a: C128, b: C128, w: C128, kk: F64, C: C128, out: F64) -> None:  # pragma: no cover - compiled
    # descriptor_distance per row from C's grid: its largest |C| (first of equals), three Newton steps on
    # |C(sigma)|^2 from there, the better of the two, then |a|^2 + |b|^2 - 2 |C|.
    n_grid, m = C.shape[1], w.shape[1]
    ek = np.empty(m, np.complex128)
    for p in range(w.shape[0]):
        big, at = -1.0, 0
        for j in range(n_grid):
            v = C[p, j]
            e = v.real * v.real + v.imag * v.imag
            if e > big:
                big, at = e, j
        sig = 2.0 * np.pi * at / n_grid
        for _ in range(3):
            c0 = c1 = c2 = 0.0j
            _powers(sig, ek)
            for q in range(m):
                t = w[p, q] * ek[q]
                c0 += t
                c1 += 1j * kk[q] * t
                c2 += -(kk[q] * kk[q]) * t
            g1 = 2.0 * (c0.real * c1.real + c0.imag * c1.imag)
            g2 = 2.0 * (c1.real * c1.real + c1.imag * c1.imag + c0.real * c2.real + c0.imag * c2.imag)
            if g2 < 0.0:
                sig = sig - g1 / g2
        c0 = 0.0j
        _powers(sig, ek)
        for q in range(m):
            c0 += w[p, q] * ek[q]
        best = max(np.abs(c0), np.sqrt(big) * n_grid)
        d2 = 0.0
        for q in range(m):
            d2 += a[p, q].real * a[p, q].real + a[p, q].imag * a[p, q].imag
            d2 += b[p, q].real * b[p, q].real + b[p, q].imag * b[p, q].imag
        d2 -= 2.0 * best
        out[p] = np.sqrt(d2) if d2 > 0.0 else (0.0 if d2 <= 0.0 else np.nan)


@dataclass(frozen=True)
class Similarity:
    """``target_i ~ scale R(rotation) source_(i + shift) + translation`` for a population.

    Attributes:
        scale: ``(pop,)`` > 0.
        rotation: ``(pop,)`` rad, counter-clockwise.
        translation: ``(pop, 2)`` mm.
        shift: ``(pop,)`` cyclic sample shift k (source sample i + k lands on target sample i).
        phase: ``(pop,)`` the same shift as a crank angle ``2 pi k / n`` (rad): adding it to a
            mechanism's crank phase g moves sample i + k to sample i.
        rms: ``(pop,)`` root-mean-square residual distance (mm).
    """

    scale: F64
    rotation: F64
    translation: F64
    shift: NDArray[np.int64]
    phase: F64
    rms: F64


def similarity_transform(source: F64, target: F64) -> Similarity:
    """Least-squares similarity (scale, rotation, translation, cyclic shift) mapping source onto target.

    For each cyclic shift the optimum is closed-form (complex Procrustes); the best shift maximises
    ``|sum_i conj(s~_(i+k)) q~_i|`` over all k at once by FFT cross-correlation (s~, q~ centred).

    Args:
        source: ``(pop, n, 2)`` or ``(n, 2)`` curves (mm), sampled like the target.
        target: ``(n, 2)`` or ``(pop, n, 2)`` (mm); one target is transformed once for all.

    Returns:
        Similarity; NaN entries (shift 0) where a source or its target has a NaN sample.
    """
    s, q = _batch(source), _batch(target)
    if q.shape[0] != 1 and s.shape[0] == 1:
        s = np.broadcast_to(s, q.shape)
    n = s.shape[1]
    zs, zq = _complex(s), _complex(q)
    ms, mq = zs.mean(1), zq.mean(1)
    ok = np.isfinite(ms) & np.isfinite(mq)
    cs, cq = _centred(zs, ms), _centred(zq, mq)
    # corr[m] = sum_j conj(s~_j) q~_(j+m); shift k pairs q~_i with s~_(i+k), i.e. m = -k.
    spec = np.fft.fft(cs, axis=1)
    _conj_times(spec, np.fft.fft(cq, axis=1))
    corr = np.fft.ifft(spec, axis=1)
    m = np.empty(len(corr), np.int64)
    cross = np.empty(len(corr), np.complex128)
    _peak(corr, m, cross)
    k = (-m) % n
    energy = np.einsum("ij,ij->i", cs.real, cs.real) + np.einsum("ij,ij->i", cs.imag, cs.imag)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cross / energy
    t = mq - c * ms
    rms = np.empty(len(c))
    _rms(cs, cq, c, k, rms)
    scale, rot = np.abs(c), np.angle(c)
    trans = np.stack([t.real, t.imag], -1)
    for arr in (scale, rot, rms, trans):
        arr[~ok] = np.nan
    k = np.where(ok, k, 0)
    return Similarity(scale=scale, rotation=rot, translation=trans, shift=k, phase=2.0 * np.pi * k / n, rms=rms)


@numba.njit(cache=True, nogil=True)
def _centred(z: C128, mean: C128) -> C128:  # pragma: no cover - compiled
    # z - mean per row, in place (z is a fresh array); rows whose mean is not finite become 0.
    for p in range(z.shape[0]):
        mu = mean[p]
        finite = np.isfinite(mu.real) and np.isfinite(mu.imag)
        for i in range(z.shape[1]):
            z[p, i] = z[p, i] - mu if finite else 0.0
    return z


@numba.njit(cache=True, nogil=True)
def _conj_times(a: C128, b: C128) -> None:  # pragma: no cover - compiled
    # a = conj(a) * b in place; b has one row or as many as a.
    nb = b.shape[0]
    for p in range(a.shape[0]):
        for i in range(a.shape[1]):
            a[p, i] = np.conj(a[p, i]) * b[p if nb > 1 else 0, i]


@numba.njit(cache=True, nogil=True)
def _peak(corr: C128, arg: NDArray[np.int64], value: C128) -> None:  # pragma: no cover - compiled
    # Per row the first index of the largest |corr|^2 (np.argmax's tie rule) and the value there.
    for p in range(corr.shape[0]):
        best, at = -1.0, 0
        for i in range(corr.shape[1]):
            v = corr[p, i]
            e = v.real * v.real + v.imag * v.imag
            if e > best:
                best, at = e, i
        arg[p] = at
        value[p] = corr[p, at]


def _complex(c: F64) -> C128:
    z = np.empty(c.shape[:-1], np.complex128)
    z.real, z.imag = c[..., 0], c[..., 1]
    return z


@numba.njit(cache=True, nogil=True)
def _rms(cs: C128, cq: C128, c: C128, k: NDArray[np.int64], out: F64) -> None:  # pragma: no cover - compiled
    # RMS of q~_i - c s~_(i+k), summed directly (the closed form |q~|^2 - |cross|^2 / |s~|^2 cancels).
    n, nq = cs.shape[1], cq.shape[0]
    for p in range(cs.shape[0]):
        acc, q, j = 0.0, p if nq > 1 else 0, k[p] % n
        for i in range(n):
            r = cq[q, i] - c[p] * cs[p, j]
            acc += r.real * r.real + r.imag * r.imag
            j = j + 1 if j + 1 < n else 0
        out[p] = np.sqrt(acc / n)


def apply_similarity(sim: Similarity, curve: F64) -> F64:
    """``scale R source_(i + shift) + translation``, ``(pop, n, 2)`` (mm)."""
    c = _batch(curve)
    n = c.shape[1]
    idx = (np.arange(n)[None, :] + sim.shift[:, None]) % n
    c = np.broadcast_to(c, (len(sim.scale),) + c.shape[1:])
    rolled = np.take_along_axis(c, idx[..., None], 1)
    z = rolled[..., 0] + 1j * rolled[..., 1]
    factor = sim.scale * np.exp(1j * sim.rotation)
    shift = sim.translation[:, 0] + 1j * sim.translation[:, 1]
    w = factor[:, None] * z + shift[:, None]
    return np.stack([w.real, w.imag], -1)
