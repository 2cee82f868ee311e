"""The numba analysis kernel gives the numpy reference's results, odd paths included."""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.analysis.evaluate import Evaluation, evaluate, evaluate_paths
from core.kinematics.design import Design
from core.kinematics.presets import get


def assert_same(a: Evaluation, b: Evaluation) -> None:
    """Every field of the kernel's evaluation ``b`` equals the reference's ``a``; a failure names every field that
    differs, not only the first (session 27 saw the odd-paths case fail once, on violation alone as reported, and
    could not reproduce it: which other fields moved with it would tell where)."""
    wrong = []
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            try:
                np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-9, equal_nan=True, err_msg=f.name)
            except AssertionError as exc:
                wrong.append(str(exc))
        elif x != y:
            wrong.append(f"{f.name}: {y!r} (kernel) != {x!r} (reference)")
    assert not wrong, "\n".join(wrong)


def odd_population(n: int) -> np.ndarray:
    th = 2 * np.pi * np.arange(n) / n
    c, s = np.cos(th), np.sin(th)
    P = np.stack(
        [
            np.stack([150 * c, 50 * s], -1),  # ellipse
            np.stack([150 * c, 50 * (s - 0.36 * np.sin(3 * th))], -1),  # extra landing roots
            np.stack([150 * s, 60 * np.sin(2 * th) + 20 * s], -1),  # figure eight
            np.stack([150 * c, 0 * c], -1),  # folded: no root
            np.stack([150 * c, -50 * s], -1),  # clockwise
            np.stack([150 * c + 30 * np.cos(2 * th), 50 * s + 20 * np.cos(3 * th + 1)], -1),
            np.stack([150 * c, 50 * s], -1),
        ]
    )
    P[-1, 3] = np.nan  # partly unplaced
    return P


@pytest.mark.parametrize("n", [360, 361, 64])
def test_kernel_matches_reference_on_odd_paths(n: int) -> None:
    P = odd_population(n)
    ref = evaluate_paths(P, P, None, obstacle=(20.0, 30.0), trunk=380.0, kernel=False)
    fast = evaluate_paths(P, P, None, obstacle=(20.0, 30.0), trunk=380.0, kernel=True)
    assert_same(ref, fast)
    assert ref.feasible.tolist() == [True, False, False, False, True, True, False]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=4),
    st.sampled_from([64, 91, 360]),
    st.floats(0.0, 6.3),
)
def test_kernel_charges_every_extra_lobe_like_the_reference(amps: list[float], n: int, phase: float) -> None:
    """y = sin t + sum a_k sin((2k + 1) t): f(t) = 2 y(t) has up to 2(2k + 1) roots, and lobes of every size (equal
    ones too: a = 0 makes the two main lobes tie). The kernel's root count and violation (every lobe of |f| but the
    two largest, less LOBE_TOL) are the reference's (session 27 saw the kernel charge the two main lobes once)."""
    th = 2 * np.pi * np.arange(n) / n + phase
    y = np.sin(th) + sum(a * np.sin((2 * k + 3) * th) for k, a in enumerate(amps))
    P = np.stack([150 * np.cos(th), 50 * y], -1)[None]
    ref = evaluate_paths(P, P, None, kernel=False)
    fast = evaluate_paths(P, P, None, kernel=True)
    assert fast.path_violation[0] == pytest.approx(ref.path_violation[0], rel=1e-9, abs=1e-9)
    assert (fast.path_violation[0] == 0.0) == (ref.path_violation[0] == 0.0)


@pytest.mark.parametrize("parallel", [False, True])
def test_kernel_matches_reference_on_a_perturbed_population(parallel: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    if parallel:  # the kernel goes parallel from the solver's threshold on; force it here
        monkeypatch.setattr("core.kinematics.solver.PARALLEL_MIN_POP", 1)
    base = get("stephenson1/X3").design()
    rng = np.random.default_rng(11)
    p = base.params * (1 + 0.04 * rng.standard_normal((300, base.params.shape[1])))
    d = Design(base.mechanism, p, base.output)
    ref = evaluate(d, 360, backend="numpy")
    fast = evaluate(d, 360, backend="numba")
    assert 50 < ref.feasible.sum() < 300  # both assembled and unassemblable members
    assert_same(ref, fast)


def test_fused_kernel_applies_a_mirrored_output_stage_like_the_reference() -> None:
    base = get("klann").design()
    assert base.output.mirror
    rng = np.random.default_rng(5)
    p = base.params * (1 + 0.02 * rng.standard_normal((40, base.params.shape[1])))
    d = Design(base.mechanism, p, replace(base.output, k=-0.8, ox=12.0, oy=-7.0))
    assert_same(evaluate(d, 180, backend="numpy"), evaluate(d, 180, backend="numba"))
