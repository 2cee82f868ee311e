"""Stage results and pipelines survive JSON bit for bit, NaN and infinities included; no pickle."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Pipeline, Stage, StageResult, StageSpec, make_problem
from core.optimize.result import decode_float, dumps, encode

X0 = get("stephenson1/X0").design()


def small_result() -> StageResult:
    s = StageSpec("subtask", make_problem("path_box"), s=0.2, d=20.0, algorithm=AlgorithmSpec("nsga2", 10), n_gen=2,
                  seed=4, stop_below=(1e-3, 1e-3))
    return Stage(s, X0).run().with_pick("knee")


def bits(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a, dtype=np.float64).tobytes()


def assert_same(a: StageResult, b: StageResult, timings: bool = True) -> None:
    for f in ("X", "F", "G", "cv"):
        assert bits(getattr(a, f)) == bits(getattr(b, f)) and getattr(a, f).shape == getattr(b, f).shape, f
    assert a.metrics.keys() == b.metrics.keys()
    for k in a.metrics:
        assert bits(a.metrics[k]) == bits(b.metrics[k]), k
    for f in ("name", "index", "objectives", "constraints", "shortlist", "seed", "status", "generation", "n_gen",
              "n_evals", "picked", "parent_pick", "versions", "output"):
        assert getattr(a, f) == getattr(b, f), f
    assert a.mechanism.name == b.mechanism.name
    assert encode(a.settings) == encode(b.settings)
    assert not timings or encode(a.timings) == encode(b.timings)
    assert encode(a.box.to_dict()) == encode(b.box.to_dict())


def strict_loads(text: str) -> object:
    def refuse(name: str) -> None:
        raise AssertionError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_stage_result_round_trip_is_lossless_with_nan_inf_and_negative_zero() -> None:
    r = small_result()
    F = r.F.copy()
    F[0] = [np.nan, np.inf]
    F[1] = [-np.inf, -0.0]
    F[2] = [5e-324, 1.7976931348623157e308]  # smallest subnormal, largest float
    metrics = dict(r.metrics)
    metrics["odd"] = np.r_[np.nan, -0.0, np.full(r.pop - 2, 0.1 + 0.2)]
    r = replace(r, F=F, metrics=metrics, timings={**r.timings, "never": np.inf})
    text = r.to_json()
    strict_loads(text)
    back = StageResult.from_json(text)
    assert_same(back, r)
    assert np.signbit(back.F[1, 1]) and np.isnan(back.F[0, 0])
    assert back.to_json() == text


def test_saved_result_names_parameters_front_shortlist_and_pick() -> None:
    r = small_result()
    d = strict_loads(r.to_json())
    assert isinstance(d, dict)
    assert d["pick"] == r.named(r.picked)  # type: ignore[arg-type]
    assert set(d["pick"]) == set(X0.mechanism.param_names)
    assert d["front"] == list(r.front) and d["shortlist"]["knees"] == list(r.shortlist.knees)
    assert d["settings"]["algorithm"] == {"name": "nsga2", "pop_size": 10, "options": {}}
    assert d["seed"] == 4 and set(d["versions"]) >= {"pymoo", "numpy", "python"}
    assert set(d["timings"]) >= {"total", "generations"}


@given(st.floats(allow_nan=True, allow_infinity=True))
@settings(max_examples=200, deadline=None)
def test_every_float_round_trips(x: float) -> None:
    y = decode_float(json.loads(dumps(x)))
    assert (np.isnan(x) and np.isnan(y)) or (x == y and np.signbit(x) == np.signbit(y))


def test_loading_refuses_other_documents() -> None:
    with pytest.raises(ValueError, match="not a stage result"):
        StageResult.from_dict({"format": "something"})
    with pytest.raises(ValueError, match="not a pipeline"):
        Pipeline.from_dict({"format": "clm-stage-result"})


def test_pipeline_round_trip_is_lossless_and_resumable() -> None:
    alg = AlgorithmSpec("nsga2", 10)
    stages = [StageSpec("a", make_problem("path_box"), s=0.2, d=20.0, algorithm=alg, n_gen=2, seed=1),
              StageSpec("b", make_problem("bowl", limit=0.05), s=0.1, d=10.0, algorithm=alg, n_gen=2, seed=2,
                        pick="best:f2")]
    pipe = Pipeline(stages, X0)
    pipe.run()
    text = pipe.to_json()
    strict_loads(text)
    back = Pipeline.from_json(text)  # stage specs rebuilt from the problem registry
    assert back.to_json() == text
    for a, b in zip(pipe.lineage, back.lineage, strict=True):
        assert_same(a, b)
    # A loaded pipeline re-runs its last stage from the saved pick exactly like the original.
    r1 = pipe.run(start=1)[1]
    r2 = back.run(start=1)[1]
    assert_same(r1, r2, timings=False)
