"""Fuzzing solve/evaluate with any float input of the right shape, on every mechanism and both backends.

Invariants: no exception; violation == 0 implies every path sample and every metric finite; a length
<= 0 implies violation > 0; the two backends agree on feasibility exactly, on the violation to rounding,
and, for feasible designs, on the metrics. ``CLM_FUZZ_EXAMPLES`` sets the examples per mechanism (CI: 2 000
in all, split over the mechanisms); the output stage and the scalar arguments get their own, smaller fuzz.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from core.analysis.evaluate import Evaluation, evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms import MECHANISMS
from core.kinematics.model import OutputStage
from core.kinematics.presets import PRESETS
from core.kinematics.solver import solve

N_MECH = len(MECHANISMS)
EXAMPLES = int(os.environ.get("CLM_FUZZ_EXAMPLES", str(-(-2000 // N_MECH))))
ODD = [0.0, -0.0, -1.0, 1e-300, 1e300, -1e300, np.inf, -np.inf, np.nan, 1e6, -1e6, 5e-7]
BACKENDS = ("numpy", "numba")
N = 24  # samples: coarse, so that 2 000 examples fit in CI; odd paths are as odd at 24 as at 360
PATHS = ("point", "leg", "dpoint", "dleg", "joints", "djoints")
METRICS = ("h_s", "S", "I", "mse", "l_s", "theta1", "theta2", "landing_speed", "width", "y_min", "step_length",
           "h_m", "h_bar", "psi2", "psi4", "times", "points", "constraints")


def start(name: str) -> np.ndarray:
    """A preset of the mechanism if there is one (mostly assembling rows), else the middle of its bounds."""
    for p in PRESETS.values():
        if p.mechanism.name == name:
            return np.asarray(p.design().params[0], dtype=np.float64)
    m = MECHANISMS[name]
    return 0.5 * (m.lower + m.upper)


def output_of(name: str) -> OutputStage:
    return next((p.design().output for p in PRESETS.values() if p.mechanism.name == name), OutputStage())


@st.composite
def rows(draw, name: str) -> np.ndarray:
    """A small population: the start design jittered, with some entries replaced by odd values."""
    m = MECHANISMS[name]
    base = start(name)
    pop = draw(st.integers(1, 4))
    out = np.empty((pop, m.n_params))
    for i in range(pop):
        scale = draw(st.sampled_from([0.0, 0.01, 0.2, 1.0]))
        noise = np.asarray(draw(st.lists(st.floats(-1, 1), min_size=m.n_params, max_size=m.n_params)))
        row = base * (1.0 + scale * noise)
        for _ in range(draw(st.integers(0, 2))):
            row[draw(st.integers(0, m.n_params - 1))] = draw(st.sampled_from(ODD))
        out[i] = row
    return out


def both(d: Design, **kw) -> dict[str, Evaluation]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return {be: evaluate(d, N, backend=be, **kw) for be in BACKENDS}


def assert_sound(ev: dict[str, Evaluation], short: np.ndarray) -> None:
    """Each backend: violation >= 0 and never NaN, positive where a length is short, metrics finite where 0."""
    for be, e in ev.items():
        assert e.violation.shape == (len(short),)
        assert not np.isnan(e.violation).any() and (e.violation >= 0).all(), (be, e.violation)
        assert (e.violation[short] > 0).all(), (be, e.violation)
        ok = e.violation == 0
        for k in METRICS:
            assert np.isfinite(np.asarray(getattr(e, k))[ok]).all(), (be, k)


def assert_agree(a: Evaluation, b: Evaluation, scale: float = 1.0) -> None:
    """The backends' answers: feasibility exactly, the violation to rounding, the feasible rows' metrics.

    The backends differ by ~1e-12 in d/dtheta (analytic vs rigid-body derivative); the violations they
    measured differed by at most 3e-13 relative over 2 400 fuzzed populations. Landing and take-off are
    roots of the vertical velocity; on a near-flat stance they are ill-conditioned, and that 1e-12 moves
    them by up to ~1e-3 of a sample at this coarse sampling: the metrics then agree to ~1e-2 mm (times the
    output ratio ``scale``, which scales every leg-frame length).
    """
    np.testing.assert_array_equal(a.violation == 0, b.violation == 0)
    np.testing.assert_array_equal(np.isinf(a.violation), np.isinf(b.violation))
    np.testing.assert_allclose(a.violation, b.violation, rtol=1e-9, atol=1e-12)
    ok = a.violation == 0
    for k in ("h_s", "I", "mse", "l_s"):
        np.testing.assert_allclose(getattr(a, k)[ok], getattr(b, k)[ok], rtol=1e-3, atol=2e-2 * scale, err_msg=k)


def check(name: str, params: np.ndarray) -> None:
    m = MECHANISMS[name]
    d = Design(m, params, output_of(name))
    lengths = [j for j, p in enumerate(m.params) if p.kind == "length"]
    short = (params[:, lengths] <= 0).any(axis=1) if lengths else np.zeros(len(params), bool)
    ev = both(d)
    assert_sound(ev, short)
    assert_agree(ev["numpy"], ev["numba"])
    # solve: a zero violation means every joint, path sample and derivative is finite; and solve judges
    # the assembly exactly as evaluate's fused kernel does.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for be in BACKENDS:
            sol = solve(m, params, N, output=d.output, backend=be)
            assert (sol.violation[short] > 0).all(), be
            ok = sol.violation == 0
            for k in PATHS:
                assert np.isfinite(getattr(sol, k)[ok]).all(), (be, k)
            np.testing.assert_allclose(sol.violation, ev[be].kinematic_violation, rtol=1e-12, atol=0)


@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_any_float_input_is_answered_not_raised(name):
    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(rows(name))
    def run(params):
        check(name, params)

    run()


def signed_log(lo: float, hi: float):
    """Numbers of either sign with magnitude log-uniform in [lo, hi]."""
    mag = st.floats(np.log10(lo), np.log10(hi)).map(lambda e: 10.0**e)
    return st.tuples(mag, st.sampled_from([-1.0, 1.0])).map(lambda t: t[0] * t[1])


@settings(max_examples=int(os.environ.get("CLM_FUZZ_EXAMPLES", "60")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(k=signed_log(1e-6, 1e6), ox=st.floats(-1e6, 1e6), oy=st.floats(-1e6, 1e6), mirror=st.booleans(),
       period=st.floats(-6, 6).map(lambda e: 10.0**e), a=st.floats(0, 1e6), b=st.floats(0, 1e6),
       trunk=st.floats(1e-3, 1e6), jitter=st.floats(-0.3, 0.3))
def test_any_accepted_output_stage_and_scalars_keep_the_invariants(k, ox, oy, mirror, period, a, b, trunk, jitter):
    """Every output stage and scalar argument the API accepts: no exception, a feasible row's metrics finite,
    the backends agreeing (leg-frame lengths scale with |k|, so does the tolerance)."""
    name = "stephenson1"
    params = start(name)[None] * np.array([[1.0], [1.0 + jitter]])
    d = Design(MECHANISMS[name], params, OutputStage(k, ox, oy, mirror))
    ev = both(d, period=period, obstacle=(a, b), trunk=trunk)
    assert_sound(ev, np.zeros(2, bool))
    a_, b_ = ev["numpy"], ev["numba"]
    np.testing.assert_array_equal(a_.violation == 0, b_.violation == 0)
    ok = a_.violation == 0
    for key in ("h_s", "l_s", "mse"):  # lengths; I is a speed (1/T), compared relatively only
        np.testing.assert_allclose(getattr(a_, key)[ok], getattr(b_, key)[ok], rtol=1e-3,
                                   atol=2e-2 * max(1.0, abs(k) + abs(ox) * 1e-9), err_msg=key)
    np.testing.assert_allclose(a_.I[ok], b_.I[ok], rtol=1e-3, atol=2e-2 * max(1.0, abs(k)) / period)
