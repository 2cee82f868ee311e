"""The study follows what the user does: an infeasible stage says so, a topology switch starts a new pipeline, a
restored branch brings its design back."""

from __future__ import annotations

import numpy as np

from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Stage, StageSpec, make_problem
from studio.study import status_text

X2 = get("stephenson1/X2").design()


def test_no_feasible_member_is_named_with_the_unmet_constraint_and_its_values():
    # Eq. 23 with an impossible h_s limit: no member can meet it.
    prob = make_problem("subtask3", n_samples=72, h_s_max=0.01)
    res = Stage(StageSpec("subtask3", prob, s=0.05, d=5.0, algorithm=AlgorithmSpec("nsga2", 12), n_gen=2,
                          seed=1), X2).run()
    assert not res.feasible.any()
    text = status_text(res)
    assert text.startswith("complete — no feasible member: ")
    i = int(np.argmin(res.cv))
    h_s = float(res.metrics["h_s"][i])
    assert f"h_s {h_s:.3g} > 0.01" in text


def test_a_stage_with_feasible_members_just_says_complete():
    prob = make_problem("subtask3", n_samples=72)
    res = Stage(StageSpec("subtask3", prob, s=0.05, d=5.0, algorithm=AlgorithmSpec("nsga2", 12), n_gen=2,
                          seed=1), X2).run()
    assert res.feasible.any() and status_text(res) == "complete"


def test_switching_topology_starts_a_new_pipeline_and_keeps_the_old_as_a_branch():
    import threading

    from studio.chains import RunSettings, chain_for, find
    from studio.runner import Runner
    from studio.state import Session
    from studio.study_view import study_view

    s = Session.default()
    s.study.settings["subtask1"] = RunSettings("subtask1", pop_size=8, n_gen=2, seed=3)
    done = threading.Event()
    runner = Runner(s.lock, lambda: s.study, lambda p: None, done.set)
    chain = chain_for(s.view.design.mechanism)
    stage = find(chain, "subtask1")
    view = s.view
    runner.start(lambda st: st.plan(stage, s.study.settings_for(stage), view.design, view.target, False, chain))
    assert done.wait(60)
    runner.join(10)
    s.study.next_stage, s.study.from_pick = "subtask2", True
    assert s.study.pipeline is not None and not s.study.branches

    s.select_mechanism("jansen")
    assert s.view.design.mechanism.name == "jansen"
    assert s.study.pipeline is None and s.study.next_stage is None and not s.study.from_pick
    assert len(s.study.branches) == 1 and "subtask1" in s.study.branches[0].label
    sv = study_view(s.study, s.view.design, chain_for(s.view.design.mechanism), s.view.target)
    assert sv.result(sv.viewing) is None  # the chart and the candidates are empty
    # Back to a Stephenson preset: the jansen study had no result, so nothing new is branched.
    s.load_preset("stephenson1/X3")
    assert len(s.study.branches) == 1


def test_restoring_a_branch_restores_its_mechanism_and_design_with_the_pipeline():
    import threading

    import numpy as np

    from studio.chains import RunSettings, chain_for, find
    from studio.runner import Runner
    from studio.state import Session

    s = Session.default()
    s.study.settings["subtask1"] = RunSettings("subtask1", pop_size=8, n_gen=2, seed=3)
    done = threading.Event()
    runner = Runner(s.lock, lambda: s.study, lambda p: None, done.set)
    chain = chain_for(s.view.design.mechanism)
    stage = find(chain, "subtask1")
    view = s.view
    runner.start(lambda st: st.plan(stage, s.study.settings_for(stage), view.design, view.target, False, chain))
    assert done.wait(60)
    runner.join(10)
    from dataclasses import replace

    s.study.pipeline.record(0, replace(s.study.pipeline.lineage[-1], picked=3))  # member 3 passed on
    member = 3
    s.select_mechanism("jansen")
    assert s.view.design.mechanism.name == "jansen"
    s.restore_branch(0)
    assert s.view.design.mechanism.name == "stephenson1"
    restored = s.study.pipeline.lineage[-1]
    assert restored.picked == member
    np.testing.assert_allclose(s.view.design.params[0], restored.X[member])
    assert s.study.viewing == restored.name
