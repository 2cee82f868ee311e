"""The public API refuses odd calls naming the argument; odd designs get a violation, the same on both backends."""

from __future__ import annotations

import decimal
import warnings

import numpy as np
import pytest

from core.analysis.evaluate import evaluate, evaluate_paths
from core.kinematics.design import Design
from core.kinematics.model import OutputStage
from core.kinematics.presets import get
from core.kinematics.solver import solve
from core.optimize.problem import make_problem

X3 = get("stephenson1/X3").design()
M = X3.mechanism
NAN = float("nan")

REFUSED = [
    (lambda: solve(M, X3.params, 0), ValueError, "n_samples must be between 1"),
    (lambda: solve(M, X3.params, -360), ValueError, "n_samples must be between 1"),
    (lambda: solve(M, X3.params, True), TypeError, "n_samples must be an integer"),
    (lambda: solve(M, X3.params, 72, backend="bogus"), ValueError, "backend must be one of"),
    (lambda: evaluate(X3, 0), ValueError, "n_samples must be between 8"),
    (lambda: evaluate(X3, 1), ValueError, "n_samples must be between 8"),
    (lambda: evaluate(X3, -4), ValueError, "n_samples must be between 8"),
    (lambda: evaluate(X3, 73), ValueError, "n_samples must be even"),
    (lambda: evaluate(X3, 72, period=NAN), ValueError, r"period \(s\) must be finite"),
    (lambda: evaluate(X3, 72, period=-2.0), ValueError, r"period \(s\) must be > 0"),
    (lambda: evaluate(X3, 72, period=float("inf")), ValueError, r"period \(s\) must be finite"),
    (lambda: evaluate(X3, 72, obstacle=(NAN, 25.0)), ValueError, r"obstacle length \(mm\) must be finite"),
    (lambda: evaluate(X3, 72, obstacle=(25.0, -1.0)), ValueError, r"obstacle height \(mm\) must be >= 0"),
    (lambda: evaluate(X3, 72, trunk=0.0), ValueError, r"trunk \(mm\) must be > 0"),
    (lambda: evaluate(X3, 72, backend="gpu"), ValueError, "backend must be one of"),
    (lambda: make_problem("subtask1", n_samples=1), ValueError, "n_samples must be between 8"),
    (lambda: X3.replace(zz=1.0), ValueError, r"stephenson1 has no parameter 'zz'; its parameters: b, g, x_a"),
    (lambda: OutputStage(k=NAN), ValueError, "output k"),
    (lambda: OutputStage(k=0.0), ValueError, "output k"),
    (lambda: OutputStage(mirror="yes"), TypeError, "mirror must be true or false"),
    (lambda: Design(M, np.array([[str(v) for v in X3.params[0]]])), TypeError, "real numbers"),
    (lambda: Design(M, X3.params.astype(bool)), TypeError, "real numbers"),
    (lambda: Design(M, [[decimal.Decimal(1)] * 16]), TypeError, "real numbers"),
    (lambda: Design(M, X3.params.astype(complex)), TypeError, "real numbers"),
    (lambda: Design(M, X3.params.astype("datetime64[s]")), TypeError, "real numbers"),
    (lambda: solve(M, np.array(["a"] * 16), 72), TypeError, "real numbers"),
    (lambda: solve(M, np.ones((2, 16, 3)), 72), ValueError, r"16 parameters, params of shape \(pop, 16\)"),
    (lambda: solve("stephenson1", X3.params, 72), TypeError, "mechanism must be a Mechanism"),
    (lambda: solve(M, X3.params, 72, output=(-1.0, 150.0, 0.0)), TypeError, "output must be an OutputStage"),
    (lambda: solve(M, X3.params, 72, joints="no"), TypeError, "joints must be true or false"),
    (lambda: solve(M, np.ma.masked_invalid([[NAN] * 16]), 72), TypeError, "masked"),
    (lambda: Design(M, X3.params, output={"k": -1.0}), TypeError, "design output must be an OutputStage"),
    (lambda: evaluate(X3, 72, obstacle=25.0), TypeError, "obstacle must be a pair"),
    (lambda: evaluate(X3, 72, obstacle=(25.0, 25.0, 1.0)), ValueError, "obstacle must be a pair"),
    (lambda: evaluate(X3, 72, period=1e-300), ValueError, r"period \(s\) must be >= 1e-06"),
    (lambda: evaluate(X3, 72, period=1e300), ValueError, r"period \(s\) must be <= 1e\+06"),
    (lambda: evaluate(X3, 72, obstacle=(1e300, 25.0)), ValueError, "obstacle length"),
    (lambda: evaluate(X3, 72, target="cycloid"), TypeError, "target must be a Target"),
    (lambda: evaluate(X3, 72, phase_optimal="yes"), TypeError, "phase_optimal must be true or false"),
    (lambda: evaluate_paths(np.zeros((1, 1, 2)), np.zeros((1, 1, 2))), ValueError, "samples per path"),
    (lambda: evaluate_paths(np.zeros((1, 72, 2)), np.zeros((1, 70, 2))), ValueError, "same shape"),
    (lambda: evaluate_paths(np.zeros((1, 72, 3)), np.zeros((1, 72, 3))), ValueError, r"\(pop, n, 2\)"),
    (lambda: evaluate_paths(np.zeros((72, 2)), np.zeros((72, 2)), period=NAN), ValueError, "period"),
    (lambda: evaluate_paths(np.zeros((72, 2)), np.zeros((72, 2)), np.zeros((72, 2)), [0.0, 1.0]), ValueError,
     "kinematic_violation must have shape"),
    (lambda: OutputStage(k=1e300), ValueError, "output k"),
    (lambda: OutputStage(k=1e-300), ValueError, "output k"),
    (lambda: OutputStage(k=-1.0, ox=1e10), ValueError, "output ox"),
    (lambda: OutputStage.from_dict({"k": 1.0, "ox": 0.0, "oy": 0.0, "mirror": "false"}), TypeError, "mirror"),
    (lambda: make_problem("subtask2", f1_max=NAN), ValueError, "f1_max must be finite"),
    (lambda: make_problem("subtask2", f1_max="6"), TypeError, "f1_max must be a real number"),
    (lambda: make_problem("subtask1", eq30="no"), TypeError, "eq30 must be true or false"),
    (lambda: make_problem("subtask1", target=3), TypeError, "target must be a string"),
    (lambda: make_problem("predesign", n_harmonics=0), ValueError, "n_harmonics must be between 1"),
    (lambda: make_problem("subtask1", backend="bogus"), ValueError, "backend must be one of"),
]


@pytest.mark.parametrize(("call", "error", "message"), REFUSED, ids=[r[2] + str(i) for i, r in enumerate(REFUSED)])
def test_odd_calls_are_refused_naming_the_argument(call, error, message):
    with pytest.raises(error, match=message):
        call()


@pytest.mark.parametrize("kw", [{"period": NAN}, {"obstacle": (25.0, -1.0)}, {"trunk": np.inf}, {"target": "x"}],
                         ids=str)
def test_both_backends_refuse_the_same_calls_the_same_way(kw):
    errors = []
    for backend in ("numpy", "numba"):
        with pytest.raises((TypeError, ValueError)) as e:
            evaluate(X3, 72, backend=backend, **kw)
        errors.append((e.type, str(e.value)))
    assert errors[0] == errors[1]


def test_integer_parameters_convert_and_are_judged_like_floats():
    rounded = np.round(X3.params)
    a = evaluate(Design(M, rounded.astype(np.int64), X3.output), 72)
    b = evaluate(Design(M, rounded, X3.output), 72)
    assert Design(M, rounded.astype(np.int32)).params.dtype == np.float64
    np.testing.assert_array_equal(a.violation, b.violation)
    np.testing.assert_array_equal(a.mse, b.mse)


def both(params: np.ndarray, n: int = 72):
    d = Design(M, params, X3.output)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return [evaluate(d, n, backend=b) for b in ("numpy", "numba")]


@pytest.mark.parametrize(("name", "value"), [("r4", -128.33), ("r12", -115.54), ("r1", 0.0), ("r5", -51.2),
                                             ("r7", -99.62)])
def test_a_non_positive_length_is_infeasible_on_both_backends(name, value):
    for e in both(X3.replace(**{name: value}).params):
        assert e.violation[0] >= abs(value) > 0 or (value == 0 and e.violation[0] > 0)
    assert all(s.violation[0] > 0 for s in (solve(M, X3.replace(**{name: value}).params, 72, backend=b)
                                             for b in ("numpy", "numba")))


def test_a_negative_offset_stays_a_valid_design():
    a, b = both(X3.replace(r6=-4.21).params)
    assert a.violation[0] == b.violation[0] == 0.0


@pytest.mark.parametrize("value", [1e300, -1e300, 1e7])
def test_astronomic_parameters_are_infinitely_infeasible_on_both_backends(value):
    a, b = both(X3.replace(x_a=value).params)
    assert a.violation[0] == b.violation[0] == np.inf and not a.feasible[0] and not b.feasible[0]


@pytest.mark.parametrize("preset", ["stephenson1/X3", "rtclm/case2", "rtclm/case2/auxiliary", "jansen", "klann",
                                    "watt1/paper", "fourbar/chebyshev", "stephenson3/paper"])
def test_astronomic_parameters_are_not_solved_so_nothing_overflows(preset):
    # 1e300 squared overflowed in the numpy backend, and in the RTCLM's derived coupling on both backends.
    d = get(preset).design()
    for j in range(d.mechanism.n_params):
        params = d.params.copy()
        params[0, j] = 1e300
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            sols = [solve(d.mechanism, params, 36, output=d.output, backend=b) for b in ("numpy", "numba")]
        for s in sols:
            assert s.violation[0] == np.inf and np.isnan(s.point).all() and np.isnan(s.crank_margin).all()


def test_an_empty_population_gives_the_same_empty_result():
    a, b = both(np.zeros((0, M.n_params)))
    assert a.violation.shape == b.violation.shape == (0,) and a.mse.shape == b.mse.shape == (0,)


def test_stage_specs_and_pipelines_check_their_arguments():
    from core.optimize.pipeline import Pipeline
    from core.optimize.stage import StageSpec

    prob = make_problem("subtask2", n_samples=72)
    for kw, message in (({"n_gen": 0}, "n_gen"), ({"seed": -1}, "seed"), ({"seed": 2**40}, "seed"),
                        ({"s": 0.0}, "box s"), ({"d": NAN}, "box d"), ({"stop_below": (1.0, NAN)}, "stop_below")):
        with pytest.raises(ValueError, match=message):
            StageSpec("s", prob, **kw)
    with pytest.raises(TypeError, match="ProblemSpec"):
        StageSpec("s", "subtask2")
    with pytest.raises(TypeError, match="StageSpecs"):
        Pipeline(["subtask2"], X3)
    with pytest.raises(TypeError, match="Design"):
        Pipeline([StageSpec("s", prob)], X3.params)
    with pytest.raises(ValueError, match="finite parameters"):
        Pipeline([StageSpec("s", prob)], X3.replace(r1=NAN))
    with pytest.raises(TypeError, match="StageResults or None"):
        Pipeline([StageSpec("s", prob)], X3, [{"status": "complete"}])
    pipe = Pipeline([StageSpec("s", prob)], X3)
    with pytest.raises(TypeError, match="stage index must be an integer"):
        pipe.stage(0.0)
    with pytest.raises(TypeError, match="StageSpec"):
        pipe.stage(0, spec="subtask2")
    with pytest.raises(TypeError, match="records StageResults"):
        pipe.record(0, None)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_domain_edge_of_a_million_is_inside_and_the_next_float_outside(backend: str) -> None:
    from core.formats.design import value_problem
    from core.kinematics.checks import MAX_ABS

    d = get("stephenson1/X3").design()
    spec = d.mechanism.params[d.mechanism.param_names.index("x_a")]
    beyond = float(np.nextafter(MAX_ABS, np.inf))
    assert value_problem(spec, MAX_ABS) is None and value_problem(spec, -MAX_ABS) is None
    assert "within +-1e+06" in (value_problem(spec, beyond) or "")
    rows = np.tile(d.params, (3, 1))
    rows[0, 2], rows[1, 2] = MAX_ABS, beyond
    v = solve(d.mechanism, rows, 36, output=d.output, backend=backend).violation
    assert np.isfinite(v[0])  # the crank pivot a kilometre away: inside the domain, solved
    assert v[1] == np.inf and v[2] == 0.0  # past the domain: out of it, not solved
