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
            seg[i] = np.hypot(c[p, k, 0] - c[p, i, 0], c[p, k, 1] - c[p, i, 1])
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
    k = harmonic_numbers(n_harmonics)
    energy = np.sqrt((np.abs(Z) ** 2).sum(1, keepdims=True))
    with np.errstate(invalid="ignore", divide="ignore"):
        Z = Z / energy
    a1, am1 = np.angle(Z[:, 0]), np.angle(Z[:, n_harmonics])
    sigma = 0.5 * (a1 - am1)
    alpha = 0.5 * (a1 + am1)
    D = Z * np.exp(-1j * (alpha[:, None] + k[None, :] * sigma[:, None]))
    even = (k % 2) == 0
    if even.any():
        idx = np.flatnonzero(even)[np.argmax(np.abs(D[:, even]), 1)]
        flip = np.take_along_axis(D, idx[:, None], 1)[:, 0].real < 0.0
        D = np.where(flip[:, None], D * np.where(even, -1.0, 1.0)[None, :], D)
    return D


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
    C = np.fft.ifft(grid, axis=1) * n_grid  # C(2 pi j / n_grid)
    sig = 2.0 * np.pi * np.argmax(np.abs(C), 1) / n_grid
    for _ in range(3):
        e = np.exp(1j * kk[None, :] * sig[:, None])
        c0 = (w * e).sum(1)
        c1 = (1j * kk * w * e).sum(1)
        c2 = (-(kk**2) * w * e).sum(1)
        g1 = 2.0 * np.real(np.conj(c0) * c1)
        g2 = 2.0 * (np.abs(c1) ** 2 + np.real(np.conj(c0) * c2))
        with np.errstate(invalid="ignore", divide="ignore"):
            sig = np.where(g2 < 0.0, sig - g1 / g2, sig)
    best = np.abs((w * np.exp(1j * kk[None, :] * sig[:, None])).sum(1))
    best = np.maximum(best, np.abs(C).max(1))
    d2 = (np.abs(a) ** 2).sum(1) + (np.abs(b) ** 2).sum(1) - 2.0 * best
    return np.sqrt(np.maximum(d2, 0.0))


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
    cs, cq = zs - ms[:, None], zq - mq[:, None]
    ok = np.isfinite(ms) & np.isfinite(mq)
    cs[~np.isfinite(ms)] = 0.0
    cq[~np.isfinite(mq)] = 0.0
    # corr[m] = sum_j conj(s~_j) q~_(j+m); shift k pairs q~_i with s~_(i+k), i.e. m = -k.
    corr = np.fft.ifft(np.conj(np.fft.fft(cs, axis=1)) * np.fft.fft(cq, axis=1), axis=1)
    m = np.argmax(corr.real**2 + corr.imag**2, 1)
    k = (-m) % n
    cross = corr[np.arange(len(m)), m]
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


def _complex(c: F64) -> C128:
    z = np.empty(c.shape[:-1], np.complex128)
    z.real, z.imag = c[..., 0], c[..., 1]
    return z


@numba.njit(cache=True, nogil=True)
def _rms(cs: C128, cq: C128, c: C128, k: NDArray[np.int64], out: F64) -> None:  # pragma: no cover - compiled
    # RMS of q~_i - c s~_(i+k), summed directly (the closed form |q~|^2 - |cross|^2 / |s~|^2 cancels).
    n, nq = cs.shape[1], cq.shape[0]
    for p in range(cs.shape[0]):
        acc = 0.0
        for i in range(n):
            r = cq[p if nq > 1 else 0, i] - c[p] * cs[p, (i + k[p]) % n]
            acc += r.real * r.real + r.imag * r.imag
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
