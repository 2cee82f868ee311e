"""The analytic placement's "hold" fit and its operand guards, on hand-built curves and mechanisms.

``keep_rotation`` is the least-squares similarity with the rotation held at zero and the cyclic shift kept:
for a source that is the target shifted by k samples, scaled by 1/s, rotated by -phi and moved, pairing
target sample i with source sample i + k (``fourier.Similarity``'s convention) gives, in closed form,
scale s cos(phi) and the translation that maps the source's centroid onto the target's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core.analysis import fourier
from core.kinematics.design import Design
from core.kinematics.mechanisms import get as get_mechanism
from core.kinematics.model import Crank, Ground
from core.kinematics.presets import get
from core.optimize.objectives import load_target, shape_metrics
from core.optimize.predesign import apply_placement, keep_rotation, place, placement

N = 64


def target() -> np.ndarray:
    """An asymmetric closed curve: no cyclic shift but the right one maps it onto itself."""
    th = 2 * np.pi * np.arange(N) / N
    return 50.0 * np.column_stack([np.cos(th) + 0.3 * np.cos(2 * th), np.sin(th) + 0.2 * np.sin(3 * th)])


def source(q: np.ndarray, scale: float, phi: float, t: complex, k: int) -> np.ndarray:
    """The curve p with scale e^(i phi) p_(i + k) + t = q_i."""
    zq = q[:, 0] + 1j * q[:, 1]
    zp = np.roll((zq - t) / (scale * np.exp(1j * phi)), k)  # p_j = (q_(j - k) - t) / (s e^(i phi))
    return np.column_stack([zp.real, zp.imag])


def similarity(shift: int, rotation: float = 0.8, scale: float = 3.0) -> fourier.Similarity:
    """An arbitrary similarity with the given shift (keep_rotation keeps only its shift and phase)."""
    return fourier.Similarity(np.array([scale]), np.array([rotation]), np.array([[1.0, 2.0]]), np.array([shift]),
                              np.array([2 * np.pi * shift / N]), np.array([0.5]))


@pytest.mark.parametrize("k", [0, 9, 41])
def test_keep_rotation_without_rotation_maps_the_source_exactly(k):
    q = target()
    p = source(q, 1.7, 0.0, 12.0 - 30.0j, k)
    assert fourier.similarity_transform(p, q).shift[0] == k  # the convention keep_rotation shares
    held = keep_rotation(similarity(k), p[None], q)
    np.testing.assert_allclose(held.scale, [1.7], rtol=1e-12)
    np.testing.assert_array_equal(held.rotation, [0.0])
    np.testing.assert_allclose(held.translation, [[12.0, -30.0]], atol=1e-9)
    assert held.shift.tolist() == [k] and held.phase.tolist() == [2 * np.pi * k / N]
    np.testing.assert_allclose(fourier.apply_similarity(held, p)[0], q, atol=1e-9)


@pytest.mark.parametrize(("k", "phi"), [(5, 0.4), (30, -1.0), (63, 0.25)])
def test_keep_rotation_is_the_zero_rotation_least_squares_fit(k, phi):
    q = target()
    p = source(q, 1.7, phi, 12.0 - 30.0j, k)
    held = keep_rotation(similarity(k), p[None], q)
    # min over real c of sum |c p~_(i+k) - q~_i|^2 with q~ = s e^(i phi) p~ (centred): c = s cos(phi).
    np.testing.assert_allclose(held.scale, [1.7 * np.cos(phi)], rtol=1e-12)
    zp, zq = p[:, 0] + 1j * p[:, 1], q[:, 0] + 1j * q[:, 1]
    t = zq.mean() - 1.7 * np.cos(phi) * zp.mean()
    np.testing.assert_allclose(held.translation, [[t.real, t.imag]], atol=1e-9)
    # and it is the best zero-rotation fit: nudging the scale or the translation only adds to the residual
    def residual(scale: float, tx: float, ty: float) -> float:
        sim = fourier.Similarity(np.array([scale]), np.zeros(1), np.array([[tx, ty]]), np.array([k]),
                                 np.zeros(1), np.zeros(1))
        return float(((fourier.apply_similarity(sim, p)[0] - q) ** 2).sum())
    best = residual(held.scale[0], *held.translation[0])
    for d in ((0.01, 0, 0), (-0.01, 0, 0), (0, 0.5, 0), (0, 0, -0.5)):
        assert residual(held.scale[0] + d[0], held.translation[0, 0] + d[1], held.translation[0, 1] + d[2]) > best


def test_hold_fit_keeps_the_design_frames_orientation_and_matches_width_and_lowest_point():
    x3 = get("stephenson1/X3").design()
    sim = fourier.Similarity(np.array([1.4]), np.array([0.7]), np.array([[40.0, -90.0]]), np.array([33]),
                             np.array([2 * np.pi * 33 / 120]), np.array([0.0]))
    moved = Design(x3.mechanism, apply_placement(placement(x3.mechanism), x3.params, sim), x3.output)
    placed, held = place(moved, n_samples=120, backend="numpy", fit="hold")
    _, lsq = place(moved, n_samples=120, backend="numpy", fit="lsq")
    assert abs(lsq.rotation[0]) > 0.3  # the least-squares fit would turn it back
    assert held.rotation.tolist() == [0.0] and held.shift.tolist() == lsq.shift.tolist()
    tgt = load_target("cycloid").sample(120)
    m = shape_metrics(Design(x3.mechanism, placed, x3.output), n_samples=120)
    np.testing.assert_allclose(m["width"], np.ptp(tgt[:, 0]), atol=1e-8)
    np.testing.assert_allclose(m["y_min"], tgt[:, 1].min(), atol=1e-8)
    # only scaled and moved: the placed path is the moved design's path under (scale, 0, translation, shift)
    sol = moved.solve(120, joints=False, backend="numpy").point
    again = Design(x3.mechanism, placed, x3.output).solve(120, joints=False, backend="numpy").point
    np.testing.assert_allclose(again, fourier.apply_similarity(held, sol), atol=1e-8)


def negated(mechanism, step: str, **field: str):
    steps = tuple(dataclasses.replace(s, **field) if s.name == step else s for s in mechanism.steps)
    return dataclasses.replace(mechanism, name=mechanism.name + "_negated", steps=steps)


@pytest.mark.parametrize(("step", "field", "cls"), [("B", {"phase": "-g"}, Crank), ("D", {"angle": "-b"}, Ground)])
def test_a_negated_angle_operand_has_no_analytic_placement(step, field, cls):
    # Adding the rotation to g (or b) would turn a "-g" crank (or "-b" ground link) the other way.
    m = get_mechanism("fourbar")
    assert isinstance(next(s for s in m.steps if s.name == step), cls)
    placement(m)  # the plain four-bar is placeable
    with pytest.raises(ValueError, match="angle operand"):
        placement(negated(m, step, **field))
