"""Fourier descriptors are invariant to translation, rotation, scale and start point; the best
similarity transform maps a transformed curve back exactly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis.fourier import (
    apply_similarity,
    coefficients,
    descriptor_distance,
    descriptors,
    resample_arclength,
    similarity_transform,
)
from core.analysis.targets import compound_cycloid
from core.kinematics.presets import get

SETTINGS = settings(max_examples=30, deadline=None)


def blob(n: int, seed: int = 0) -> np.ndarray:
    """A smooth, asymmetric closed curve ``(n, 2)``."""
    rng = np.random.default_rng(seed)
    th = 2 * np.pi * np.arange(n) / n
    r = 100 + sum(rng.uniform(-12, 12) * np.cos(k * th + rng.uniform(0, 6)) for k in range(2, 6))
    return np.stack([r * np.cos(th), 0.6 * r * np.sin(th)], -1)


def transform(c: np.ndarray, s: float, rot: float, t: tuple[float, float]) -> np.ndarray:
    R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
    return s * c @ R.T + np.array(t)


def test_coefficients_of_a_circle() -> None:
    """A counter-clockwise circle of radius r is z(s) = c + r exp(2 pi i s): only Z_1 = r (phase 0)."""
    th = 2 * np.pi * np.arange(500) / 500
    Z = coefficients(np.stack([3 + 40 * np.cos(th), -2 + 40 * np.sin(th)], -1), 4, 256)[0]
    assert abs(Z[0]) == pytest.approx(40.0, rel=1e-4)
    assert np.abs(Z[1:]).max() < 1e-3


def test_arclength_resampling_is_uniform() -> None:
    """Points of a circle traversed at a varying speed come out equally spaced from the start."""
    u = np.arange(4000) / 4000
    th = 2 * np.pi * (u + 0.1 * np.sin(2 * np.pi * u))  # non-uniform in arc length
    c = np.stack([50 * np.cos(th), 50 * np.sin(th)], -1)
    r = resample_arclength(c, 200)[0]
    ang = np.unwrap(np.arctan2(r[:, 1], r[:, 0]))
    np.testing.assert_allclose(np.diff(ang), 2 * np.pi / 200, rtol=1e-5)
    np.testing.assert_allclose(r[0], c[0])


@SETTINGS
@given(
    st.floats(0.05, 20.0),
    st.floats(-np.pi, np.pi),
    st.floats(-1e3, 1e3),
    st.floats(-1e3, 1e3),
    st.integers(0, 3),
)
def test_descriptors_ignore_translation_rotation_scale(s: float, rot: float, tx: float, ty: float, seed: int) -> None:
    c = blob(400, seed)
    a = descriptors(c)
    b = descriptors(transform(c, s, rot, (tx, ty)))
    np.testing.assert_allclose(b, a, atol=1e-9)


@SETTINGS
@given(st.integers(1, 4095), st.integers(0, 3))
def test_descriptors_ignore_the_start_point(shift: int, seed: int) -> None:
    c = blob(4096, seed)  # fine input: the start point moves along the curve, not to a new shape
    a = descriptors(c)
    b = descriptors(np.roll(c, -shift, 0))
    np.testing.assert_allclose(b, a, atol=2e-5)
    assert descriptor_distance(a, b)[0] < 2e-5


def test_different_shapes_are_far_apart_and_distance_is_symmetric() -> None:
    cyc = descriptors(compound_cycloid(360)[0])
    x3 = descriptors(get("stephenson1/X3").design().solve(360, joints=False, backend="numpy").point)
    other = descriptors(blob(360))
    d_good, d_bad = descriptor_distance(x3, cyc)[0], descriptor_distance(other, cyc)[0]
    assert 0.0 < d_good < d_bad
    assert descriptor_distance(cyc, x3)[0] == pytest.approx(d_good, rel=1e-9)
    assert descriptor_distance(cyc, cyc)[0] == pytest.approx(0.0, abs=1e-7)


def test_distance_is_the_minimum_over_rotation_and_start_point_to_rounding() -> None:
    # Brute force: |a|^2 + |b|^2 - 2 max_sigma |C(sigma)| on 200 000 sigmas; a coarse grid (n_grid 64) is refined by
    # the Newton steps to the true maximum.
    a, b = descriptors(blob(360, 3))[0], descriptors(blob(360, 4))[0]
    kk = np.concatenate([np.arange(1, 17), -np.arange(1, 17)])
    sig = np.linspace(0.0, 2.0 * np.pi, 200_000, endpoint=False)
    C = np.abs(np.exp(1j * sig[:, None] * kk[None, :]) @ (np.conj(a) * b))
    want = np.sqrt(np.sum(np.abs(a) ** 2) + np.sum(np.abs(b) ** 2) - 2.0 * C.max())
    got = descriptor_distance(a, b, n_grid=64)[0]
    assert got == pytest.approx(want, rel=1e-7) and got <= want


def test_distance_does_not_depend_on_the_normalisation_branch() -> None:
    """Flipping the even harmonics is the start point shifted by half the perimeter."""
    a = descriptors(blob(360, 2))
    k = np.concatenate([np.arange(1, 17), -np.arange(1, 17)])
    flipped = a * np.where(k % 2 == 0, -1.0, 1.0)
    assert descriptor_distance(a, flipped)[0] == pytest.approx(0.0, abs=1e-7)


@SETTINGS
@given(
    st.floats(0.1, 10.0),
    st.floats(-np.pi, np.pi),
    st.floats(-500.0, 500.0),
    st.floats(-500.0, 500.0),
    st.integers(0, 359),
)
def test_similarity_transform_is_recovered(s: float, rot: float, tx: float, ty: float, k: int) -> None:
    src = get("stephenson1/X3").design().solve(360, joints=False, backend="numpy").point
    tgt = transform(np.roll(src[0], -k, 0), s, rot, (tx, ty))
    sim = similarity_transform(src, tgt)
    assert sim.shift[0] == k
    assert sim.scale[0] == pytest.approx(s, rel=1e-9)
    assert np.angle(np.exp(1j * (sim.rotation[0] - rot))) == pytest.approx(0.0, abs=1e-9)
    assert sim.phase[0] == pytest.approx(2 * np.pi * k / 360)
    back = apply_similarity(sim, src)
    assert np.abs(back - tgt).max() < 1e-9 * max(1.0, s * 300)
    assert sim.rms[0] < 1e-9 * max(1.0, s * 300)


def test_similarity_transform_batch_equals_loop_and_places_the_target() -> None:
    sol = get("stephenson1/X3").design().solve(360, joints=False, backend="numpy")
    rng = np.random.default_rng(3)
    pop = np.stack([transform(blob(360, i), rng.uniform(0.5, 2), rng.uniform(-3, 3), (i, -i)) for i in range(4)])
    pop = np.concatenate([pop, sol.point, np.full((1, 360, 2), np.nan)])
    target = compound_cycloid(360)[0]
    batch = similarity_transform(pop, target)
    for i in range(len(pop) - 1):
        one = similarity_transform(pop[i], target)
        assert one.shift[0] == batch.shift[i]
        assert one.scale[0] == pytest.approx(batch.scale[i], rel=1e-12)
    assert np.isnan(batch.scale[-1]) and batch.shift[-1] == 0
    # the least-squares placement is never worse (in RMS) than leaving the design where it is
    moved = apply_similarity(batch, pop)[4]
    rms = np.sqrt((np.linalg.norm(moved - target, axis=1) ** 2).mean())
    assert rms == pytest.approx(batch.rms[4], rel=1e-9)
    assert rms <= np.sqrt((np.linalg.norm(sol.point[0] - target, axis=1) ** 2).mean())


def test_similarity_transform_is_the_best_over_every_shift_by_brute_force() -> None:
    # Noisy curves (no exact fit): at each cyclic shift the complex Procrustes fit is closed-form; the
    # FFT search must pick the shift with the smallest residual and report that residual.
    rng = np.random.default_rng(11)
    n = 60
    target = blob(n, 7)
    src = np.stack([transform(np.roll(blob(n, i), 3 * i, 0), rng.uniform(0.5, 2), rng.uniform(-3, 3), (i, 2 * i))
                    + rng.normal(0.0, 4.0, (n, 2)) for i in range(5)])
    sim = similarity_transform(src, target)
    zq = target[:, 0] + 1j * target[:, 1]
    cq = zq - zq.mean()
    for p in range(len(src)):
        res = []
        for k in range(n):
            zs = np.roll(src[p], -k, 0) @ np.array([1.0, 1j])
            cs = zs - zs.mean()
            c = np.vdot(cs, cq) / np.vdot(cs, cs).real
            res.append(np.sqrt(np.mean(np.abs(cq - c * cs) ** 2)))
        assert sim.shift[p] == int(np.argmin(res))
        assert sim.rms[p] == pytest.approx(min(res), rel=1e-10)


def reference_resample(c: np.ndarray, n: int) -> np.ndarray:
    """Arc-length resampling of one closed polyline by np.interp (the plain formula)."""
    ext = np.vstack([c, c[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ext, axis=0), axis=1))])
    u = np.arange(n) * s[-1] / n
    return np.stack([np.interp(u, s, ext[:, 0]), np.interp(u, s, ext[:, 1])], -1)


def test_resampling_matches_interpolation_and_marks_bad_rows_nan() -> None:
    rng = np.random.default_rng(7)
    good = np.stack([blob(90, i) + rng.normal(0, 0.5, (90, 2)) for i in range(5)])
    good[2, 10:13] = good[2, 10]  # repeated points: zero-length segments
    bad = np.stack([good[0], good[0]])
    bad[0, 40, 1] = np.nan
    bad[1] = 3.0  # zero total length
    out = resample_arclength(np.concatenate([good, bad]), 128)
    for i in range(5):
        np.testing.assert_allclose(out[i], reference_resample(good[i], 128), atol=1e-9)
    assert np.isnan(out[5:]).all()


def test_similarity_of_a_nan_source_or_target_is_nan() -> None:
    c = blob(60)
    src = np.stack([c, c])
    src[1, 5, 0] = np.nan
    sim = similarity_transform(src, transform(c, 2.0, 0.3, (5.0, 1.0)))
    assert sim.scale[0] == pytest.approx(2.0) and sim.rms[0] < 1e-9
    assert np.isnan([sim.scale[1], sim.rotation[1], sim.rms[1], *sim.translation[1]]).all() and sim.shift[1] == 0
    tgt = transform(c, 2.0, 0.3, (5.0, 1.0))
    tgt[3, 1] = np.nan
    assert np.isnan(similarity_transform(c, tgt).scale).all()


def test_a_path_without_shape_has_nan_descriptors_and_distance() -> None:
    # A coupler point that does not move (zero length) or a NaN sample: NaN, never an exception (hot path).
    c = blob(90)
    pop = np.stack([c, np.full((90, 2), 4.0), c])
    pop[2, 7, 0] = np.nan
    d = descriptors(pop)
    assert np.isfinite(d[0]).all() and np.isnan(d[1:]).all()
    dist = descriptor_distance(d, descriptors(c))
    assert dist[0] == pytest.approx(0.0, abs=1e-7) and np.isnan(dist[1:]).all()
