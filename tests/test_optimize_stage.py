"""A stage: reproducible from its seed, one callback per generation, cancellable, feasible picks."""

from __future__ import annotations

import threading
import warnings
from dataclasses import replace

import numpy as np
import pytest

from core.kinematics.design import Design
from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Progress, Stage, StageResult, StageSpec, make_problem
from core.optimize.algorithms import ALGORITHMS
from core.optimize.problem import ASSEMBLY, Constraint, ProblemSpec

X0 = get("stephenson1/X0").design()


def spec(problem: str = "path_box", name: str = "nsga2", pop: int = 12, n_gen: int = 4, seed: int = 3,
         **kw: object) -> StageSpec:
    return StageSpec("stage", make_problem(problem), s=0.2, d=20.0, algorithm=AlgorithmSpec(name, pop), n_gen=n_gen,
                     seed=seed, **kw)  # type: ignore[arg-type]


def same(a: StageResult, b: StageResult) -> bool:
    return (
        np.array_equal(a.X, b.X)
        and np.array_equal(a.F, b.F, equal_nan=True)
        and np.array_equal(a.G, b.G, equal_nan=True)
        and a.shortlist == b.shortlist
    )


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))  # AGE-MOEA's first use compiles numba kernels (~10 s)
def test_same_seed_gives_identical_results_and_picks(algorithm: str) -> None:
    s = spec("bowl", algorithm)
    a, b = Stage(s, X0).run(), Stage(s, X0).run()
    assert a.status == "complete" and a.pop > 0
    assert same(a, b)
    assert a.choose("knee") == b.choose("knee")


def test_another_seed_gives_another_population() -> None:
    a, b = Stage(spec(seed=1), X0).run(), Stage(spec(seed=2), X0).run()
    assert not np.array_equal(a.X, b.X)


def test_callback_once_per_generation_with_consistent_shapes() -> None:
    calls = []
    s = spec(n_gen=5, pop=10)
    stage = Stage(s, X0, index=2, callback=calls.append)
    res = stage.run()
    assert [p.generation for p in calls] == [1, 2, 3, 4, 5]
    assert [p.fraction for p in calls] == [0.2, 0.4, 0.6, 0.8, 1.0]
    assert all(p.index == 2 and p.stage == "stage" and p.n_gen == 5 for p in calls)
    elapsed = [p.elapsed for p in calls]
    assert elapsed == sorted(elapsed)
    evals = [p.n_evals for p in calls]
    assert evals == sorted(evals) and evals[0] >= 10
    for p in calls:
        pop = p.X.shape[0]
        assert p.X.shape == (pop, 16) and p.F.shape == (pop, 2) and p.G.shape == (pop, 1) and p.cv.shape == (pop,)
        assert p.feasible.shape == (pop,)
        assert set(p.front) <= set(np.flatnonzero(p.feasible))
        assert stage.box.contains(p.X).all()
    np.testing.assert_array_equal(calls[-1].X, res.X)


def test_picks_satisfy_their_stage_constraints() -> None:
    # Subtask-2-like: objectives under constraints on other metrics, re-checked on the picked designs.
    base = make_problem("path_box")
    constrained = ProblemSpec("path_box_c", base.evaluate, ("f1",  "f2"),
                              (ASSEMBLY, Constraint("width", lower=280.0), Constraint("y_min", upper=-90.0)))
    s = StageSpec("c", constrained, s=0.1, d=10.0, algorithm=AlgorithmSpec("nsga2", 16), n_gen=4, seed=5)
    res = Stage(s, X0).run()
    assert res.shortlist.knees
    for i in res.shortlist.candidates:
        d = res.pick(i)
        F, G = constrained.columns(constrained.evaluate_metrics(d))
        assert (G <= 0.0).all()
        np.testing.assert_allclose(F[0], res.F[i], rtol=1e-12)  # one design == its row of the batch


def test_the_start_design_seeds_the_initial_population() -> None:
    first = []
    Stage(spec(n_gen=1), X0, callback=first.append).run()
    d = np.abs(first[0].X - X0.params[0]).max(axis=1)
    assert d.min() < 1e-9


def test_cancel_between_generations_leaves_a_valid_loadable_result() -> None:
    cancel = threading.Event()

    def on_gen(p: Progress) -> None:
        if p.generation == 2:
            cancel.set()

    stage = Stage(spec(n_gen=6), X0)
    res = stage.run(on_gen, cancel)
    assert res.status == "cancelled" and res.generation == 2 and res.pop == 12
    back = StageResult.from_json(res.to_json())
    assert same(back, res) and back.status == "cancelled"
    assert back.pick(back.choose("knee")).pop == 1
    # Resuming the same stage finishes it exactly as an uninterrupted run would.
    cancel.clear()
    resumed = stage.run(None, cancel)
    assert resumed.status == "complete" and resumed.generation == 6
    assert same(resumed, Stage(spec(n_gen=6), X0).run())


def test_cancel_before_the_first_generation_gives_an_empty_result() -> None:
    cancel = threading.Event()
    cancel.set()
    res = Stage(spec(), X0).run(cancel=cancel)
    assert res.status == "cancelled" and res.pop == 0 and res.X.shape == (0, 16)
    back = StageResult.from_json(res.to_json())
    assert back.pop == 0 and back.F.shape == (0, 2)
    with pytest.raises(ValueError, match="no population"):
        back.choose("knee")


def test_stepping_matches_run() -> None:
    stage = Stage(spec(), X0)
    stage.setup()
    n = 0
    while stage.has_next():
        stage.next()
        n += 1
    assert n == 4
    with pytest.raises(RuntimeError):
        stage.next()
    assert same(stage.result(), Stage(spec(), X0).run())


def test_early_stop_when_objectives_reach_their_thresholds() -> None:
    res = Stage(spec(n_gen=10, stop_below=(1e12, 1e12)), X0).run()
    assert res.status == "stopped" and res.generation == 1
    res = Stage(spec(n_gen=3, stop_below=(-1.0, -1.0)), X0).run()
    assert res.status == "complete" and res.generation == 3


def test_early_stop_needs_every_objective_below_its_threshold() -> None:
    # f1 can never go below -1: meeting the f2 threshold alone does not stop the stage
    res = Stage(spec(n_gen=3, stop_below=(-1.0, 1e12)), X0).run()
    assert res.status == "complete" and res.generation == 3


def test_fixed_parameters_stay_at_the_start_value() -> None:
    res = Stage(spec(n_gen=2, fixed=("x_a", "r4")), X0).run()
    names = X0.mechanism.param_names
    for name in ("x_a", "r4"):
        j = names.index(name)
        assert (res.X[:, j] == X0.params[0, j]).all() and res.box.fixed[j]
    assert np.ptp(res.X[:, names.index("r1")]) > 0  # the others move


def test_a_member_with_undefined_objectives_is_never_feasible() -> None:
    p = ProblemSpec("p", None, ("f1",), (ASSEMBLY,))  # type: ignore[arg-type]
    F, G = p.columns({"f1": np.array([np.nan, 1.0]), "violation": np.array([0.0, 0.0])})
    assert F[0, 0] == np.inf and G[0, 0] == np.inf and G[1, 0] == 0.0


def test_metrics_of_every_member_are_kept() -> None:
    res = Stage(spec(), X0).run()
    assert set(res.metrics) >= {"f1", "f2", "width", "y_min", "violation"}
    np.testing.assert_array_equal(res.metrics["f1"][res.feasible], res.F[res.feasible, 0])
    np.testing.assert_allclose((res.metrics["width"] - 300.0) ** 2, res.metrics["f1"], rtol=1e-12)


def test_unassemblable_members_are_constraint_violations_not_penalties() -> None:
    # The global box: most random Stephenson-I designs do not assemble.
    s = StageSpec("global", make_problem("path_box"), s=None, algorithm=AlgorithmSpec("nsga2", 30), n_gen=1, seed=0,
                  seed_start=False)
    res = Stage(s, X0).run()
    bad = res.metrics["violation"] > 0
    assert bad.any()
    assert (res.cv[bad] == res.metrics["violation"][bad]).all()  # the continuous assembly shortfall
    assert np.isinf(res.F[bad]).all() and np.isnan(res.metrics["f1"][bad]).all()
    assert (res.F[~bad] < 1e9).all()


def test_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="'moead'"):
        spec(name="moead")
    with pytest.raises(ValueError, match="'crossover_rate'"):
        StageSpec("s", make_problem("bowl"), algorithm=AlgorithmSpec("nsga2", 10, {"crossover_rate": 0.5}))
    with pytest.raises(ValueError, match="'width_mm'"):
        make_problem("path_box", width_mm=3.0)
    with pytest.raises(ValueError, match="n_gen"):
        spec(n_gen=0)
    with pytest.raises(ValueError, match="one design"):
        Stage(spec(), Design(X0.mechanism, np.repeat(X0.params, 2, 0)))


@pytest.mark.parametrize("algorithm", ["nsga2", "gde3"])
def test_a_problem_repair_replaces_members_before_evaluation(algorithm: str) -> None:
    # A stand-in for predesign's analytic placement: r3 becomes a function of r2 (inside the box).
    base = make_problem("bowl")
    j2, j3 = X0.mechanism.param_names.index("r2"), X0.mechanism.param_names.index("r3")
    box = StageSpec("r", base, s=0.2, d=20.0).box(X0)

    def tie(r2: np.ndarray) -> np.ndarray:
        u = (r2 - box.lower[j2]) / (box.upper[j2] - box.lower[j2])
        return box.lower[j3] + (1.0 - u) * (box.upper[j3] - box.lower[j3])

    def repair(design: Design) -> np.ndarray:
        p = np.array(design.params)
        p[:, j3] = tie(p[:, j2])
        return p

    s = StageSpec("r", replace(base, repair=repair), s=0.2, d=20.0, algorithm=AlgorithmSpec(algorithm, 12), n_gen=3)
    res = Stage(s, X0).run()
    np.testing.assert_allclose(res.X[:, j3], tie(res.X[:, j2]), rtol=1e-12)
    F, _ = base.columns(base.evaluate_metrics(Design(X0.mechanism, res.X)))
    np.testing.assert_array_equal(F, res.F)  # objectives belong to the repaired designs


@pytest.mark.parametrize("algorithm", ["nsga2", "nsga2_pymoo"])
def test_bulk_constraint_violation_is_pymoos_own(algorithm: str) -> None:
    """Every member's CV is computed at once (by the array core, or handed to pymoo's evaluator in bulk); the
    pymoo Population at the API boundary holds what pymoo computes per member."""
    from pymoo.core.individual import calc_cv

    stage = Stage(replace(spec("subtask2", n_gen=3), algorithm=AlgorithmSpec(algorithm, 20)), X0)
    stage.run()
    pop = stage.algorithm.pop  # type: ignore[union-attr]
    assert len(pop) == 20
    for ind in pop:
        if algorithm == "nsga2_pymoo":
            assert "_CV" in ind.evaluated
        assert ind.CV.shape == (1,)
        assert ind.CV[0] == calc_cv(G=ind.G, config=ind.config)


@pytest.mark.parametrize("algorithm", ["nsga2", "imtcmo"])
def test_the_stage_result_keeps_the_algorithms_trace_through_json(algorithm: str) -> None:
    res = Stage(replace(spec("subtask2", n_gen=3), algorithm=AlgorithmSpec(algorithm, 12)), X0).run()
    assert len(res.trace) == 3 and [row["gen"] for row in res.trace] == [1.0, 2.0, 3.0]
    assert all(0.0 <= row.get("feasible_ratio", row.get("feasible_ratio_P1", 0.0)) <= 1.0 for row in res.trace)
    if algorithm == "imtcmo":
        assert all("eps" in row for row in res.trace)
    back = StageResult.from_json(res.to_json())
    assert back.trace == res.trace


@pytest.mark.parametrize("algorithm", ["nsga2", "cmoes", "mccmo"])
def test_an_evaluation_budget_ends_the_stage_within_one_generation(algorithm: str) -> None:
    # CMOES spends 3N a generation in its first stage and less later; MCCMO more or less as its populations wake.
    # Whatever the rate, the stage ends at the end of the generation that spends max_evals, before n_gen binds.
    calls: list[Progress] = []
    s = spec("path_box", algorithm, pop=12, n_gen=1000, max_evals=300)
    res = Stage(s, X0, callback=calls.append).run()
    assert res.status == "complete" and calls[-1].generation < 1000
    evals = [p.n_evals for p in calls]
    assert evals[-2] < 300 <= evals[-1] <= 300 + 3 * 12
    assert calls[-1].fraction == 1.0 and all(0 < p.fraction <= 1 for p in calls)
    assert StageSpec.from_dict(s.to_dict()).max_evals == 300


def test_the_generation_limit_still_binds_first_when_it_is_smaller() -> None:
    res = Stage(spec(n_gen=3, pop=10, max_evals=10**6), X0).run()
    assert res.generation == 3 and res.n_evals == 30


def test_a_generation_s_nan_and_inf_print_no_numpy_warning() -> None:
    # pymoo's SPEA2 normalises subtask 1's front by (nadir - ideal), 0 / 0 on this seed; the stage reads NaN as a
    # penalty, and the studio's, CLI's and study workers' consoles stay clean.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = Stage(spec("subtask1", "spea2", pop=12, n_gen=6), X0).run()
    assert result.status == "complete" and result.pop == 12
