"""RTCLM stepwise design (paper §4.2): h6 then h4, Eqs. 29-31 as constraints, coupling kept by every pick."""

from __future__ import annotations

import numpy as np
import pytest

from core.analysis.evaluate import evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, RTCLM_PRIMARY, crank_conditions, switching_state
from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Pipeline, StageSpec, make_problem, seeded
from core.optimize.algorithms import make_algorithm, reference_directions
from core.optimize.rtclm import rtclm_metrics

N = 72


def test_metrics_are_the_modes_crossing_heights_and_the_paper_constraints() -> None:
    p = np.vstack([get("rtclm/case4").design().params, get("rtclm/case5").design().params])
    m = rtclm_metrics(p, h6_target=50.0, h4_target=280.0, n_samples=N)
    prim = evaluate(Design(RTCLM_PRIMARY, p), N)
    aux = evaluate(Design(RTCLM_AUXILIARY, p), N)
    np.testing.assert_allclose(m["dh6"], np.abs(prim.h_m - 50.0))
    np.testing.assert_allclose(m["dh4"], np.abs(aux.h_m - 280.0))
    np.testing.assert_allclose(np.c_[m["crank1"], m["crank2"]], crank_conditions(p))
    np.testing.assert_allclose(m["eq31_height_4"], aux.h_m / 4.0 - aux.h_bar)
    np.testing.assert_allclose(m["eq31_psi2_4"], 0.2 - aux.psi2)
    np.testing.assert_allclose(m["theta1_6"], np.deg2rad(15.0) - prim.theta1)
    np.testing.assert_allclose(m["theta2_6"], np.deg2rad(15.0) - prim.theta2)
    np.testing.assert_allclose(m["theta2_4"], np.deg2rad(15.0) - aux.theta2)
    assert not np.allclose(prim.theta1, prim.theta2)  # (so the two margins are told apart)


def test_batch_equals_per_design_loop() -> None:
    p = np.vstack([get(f"rtclm/case{k}").design().params for k in (1, 2, 4, 5)])
    batch = rtclm_metrics(p, n_samples=N)
    for i in range(p.shape[0]):
        one = rtclm_metrics(p[i : i + 1], n_samples=N)
        for k, v in one.items():
            np.testing.assert_allclose(batch[k][i], v[0], rtol=1e-12, atol=1e-12, err_msg=k)


def test_subtask2_holds_subtask1_and_adds_eqs_29_to_31() -> None:
    s1 = make_problem("rtclm1", n_samples=N)
    s2 = make_problem("rtclm2", h4_target=260.0, h6_tol=0.5, n_samples=N)
    assert s1.objectives == ("dh6",) and s2.objectives == ("dh4", "dh6")
    names = [c.metric for c in s2.constraints]
    assert {"violation", "aux_violation", "crank1", "crank2", "order_4", "theta1_4", "theta2_4",
            "eq31_height_4", "eq31_psi2_4"} <= set(names)
    assert next(c for c in s2.constraints if c.metric == "dh6").upper == 0.5
    assert "aux_violation" not in [c.metric for c in s1.constraints]
    s1_aux = make_problem("rtclm1", n_samples=N, auxiliary=True)
    assert {"aux_violation", "crank2", "order_4"} <= {c.metric for c in s1_aux.constraints}


def coupling_holds(params: np.ndarray) -> None:
    """Spec §1: in the switching state both feet are at one height and EH is the same vector for both legs;
    the rocker bodies D-C-H-F of both legs are congruent."""
    s = switching_state(params)
    np.testing.assert_allclose(s["E"][:, 0, 1], s["E"][:, 1, 1], atol=1e-7)
    eh = s["H"] - s["E"]
    np.testing.assert_allclose(eh[:, 0], eh[:, 1], atol=1e-7)
    for a, b in (("D", "C"), ("D", "H"), ("D", "F"), ("C", "H"), ("C", "F"), ("H", "F")):
        d = np.linalg.norm(s[a] - s[b], axis=-1)
        np.testing.assert_allclose(d[:, 0], d[:, 1], atol=1e-7)


@pytest.fixture(scope="module")
def rtclm_run() -> list:  # type: ignore[type-arg]
    alg = AlgorithmSpec("nsga2", 24)
    stages = seeded([
        StageSpec("rtclm1", make_problem("rtclm1", h4_target=240.0, n_samples=N), algorithm=alg, n_gen=15,
                  stop_below=(0.5,), pick="best:dh6"),
        StageSpec("rtclm2", make_problem("rtclm2", h4_target=240.0, n_samples=N), algorithm=alg, n_gen=15,
                  stop_below=(0.5, 0.5), pick="best:dh4"),
    ], seed=3)
    return Pipeline(stages, Design(RTCLM_PRIMARY, 0.5 * (RTCLM_PRIMARY.lower + RTCLM_PRIMARY.upper))).run()


def test_every_pick_keeps_the_coupling_of_both_legs(rtclm_run: list) -> None:  # type: ignore[type-arg]
    picks = np.vstack([r.X[r.picked] for r in rtclm_run])
    assert np.isfinite(picks).all()
    coupling_holds(picks)


def test_subtask1_pick_satisfies_its_constraints_and_approaches_h6(rtclm_run: list) -> None:  # type: ignore[type-arg]
    r = rtclm_run[0]
    i = r.picked
    assert r.feasible[i]
    assert (r.G[i] <= 0).all()
    assert r.metrics["dh6"][i] < np.nanmedian(r.metrics["dh6"])


def test_early_stop_ends_a_stage_at_the_first_generation_with_a_member_below_the_threshold() -> None:
    seen: list[bool] = []
    spec = StageSpec("rtclm1", make_problem("rtclm1", n_samples=N), algorithm=AlgorithmSpec("nsga2", 24), n_gen=40,
                     stop_below=(1e6,), seed=5)
    start = Design(RTCLM_PRIMARY, 0.5 * (RTCLM_PRIMARY.lower + RTCLM_PRIMARY.upper))
    res = Pipeline([spec], start).run(callback=lambda p: seen.append(bool(p.feasible.any())))[0]
    assert res.status == "stopped"
    assert seen[-1] and not any(seen[:-1])
    assert res.generation == len(seen) < 40


@pytest.mark.parametrize("name", ["nsga3", "unsga3", "moead_cmt", "cmoemt"])
def test_reference_direction_algorithms_run_subtask1_s_single_objective(name: str) -> None:
    # The most Das-Dennis partitions under the population size never ended for one objective (one direction
    # whatever the partitions): setup hung and the studio's Stop could not reach it.
    spec = StageSpec("rtclm1", make_problem("rtclm1", n_samples=N), algorithm=AlgorithmSpec(name, 20), n_gen=2, seed=5)
    start = Design(RTCLM_PRIMARY, 0.5 * (RTCLM_PRIMARY.lower + RTCLM_PRIMARY.upper))
    res = Pipeline([spec], start).run()[0]
    assert res.status == "complete" and res.pop >= 20 and res.F.shape[1] == 1


def test_c_taea_refuses_a_single_objective_by_name() -> None:
    # Its population is one member per reference direction: one, for one objective.
    with pytest.raises(ValueError, match="ctaea needs at least two objectives.*has 1"):
        make_algorithm(AlgorithmSpec("ctaea", 20), 1, 5)
    with pytest.raises(ValueError, match="ctaea needs at least two objectives.*has 1"):  # not "set pop_size = 1"
        make_algorithm(AlgorithmSpec("ctaea", 20, {"n_partitions": 4}), 1, 5)
    assert np.array_equal(reference_directions(1, 20), [[1.0]])


@pytest.mark.parametrize("name", ["agemoea", "agemoea2"])
def test_age_moea_refuses_a_single_objective_by_name(name: str) -> None:
    # pymoo's AGE-MOEA-II divided by zero on RTCLM subtask 1 started from our clm-case1 preset (its first front: the
    # start alone): it fits the front's curvature, which one objective does not have.
    with pytest.raises(ValueError, match=f"{name} needs at least two objectives.*has 1"):
        make_algorithm(AlgorithmSpec(name, 20), 1, 5)
    assert make_algorithm(AlgorithmSpec(name, 20), 2, 5) is not None


@pytest.mark.parametrize(("name", "pop", "kept"), [("ctaea", 10, 10), ("nsga3", 12, 12), ("ctaea", 12, None),
                                                   ("nsga3", 9, None), ("unsga3", 20, 20)])
def test_n_partitions_and_pop_size_must_agree(name: str, pop: int, kept: int | None) -> None:
    # 9 partitions give 10 directions for two objectives. C-TAEA keeps one member per direction, the NSGA-IIIs at
    # least one; a pop_size that cannot hold was replaced silently by the directions' count.
    spec = AlgorithmSpec(name, pop, {"n_partitions": 9})
    if kept is None:
        with pytest.raises(ValueError, match=rf"^{name}: n_partitions = 9 gives 10 reference directions for 2 "
                                             rf"objectives, so the population would be 10, not pop_size = {pop}"):
            make_algorithm(spec, 2, 5)
    else:
        assert make_algorithm(spec, 2, 5).pop_size == kept
