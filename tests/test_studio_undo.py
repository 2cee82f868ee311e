"""Undo and Redo of the editor: a designer who typed a wrong value, chose the wrong preset or topology, or lost a
hand-edited design to a pick or a run's end gets it back exactly; the study is not rewound."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from core.kinematics.presets import get
from studio.state import UNDO_DEPTH, Session, change_summary


def nudge(s: Session, name: str, factor: float) -> float:
    value = s.view.values[name] * factor
    s.set_param(name, value)
    return value


def test_undo_takes_edits_back_in_reverse_order_and_redo_makes_them_again() -> None:
    s = Session.default()
    first = s.view
    a = nudge(s, "r4", 1.002)
    second = s.view
    nudge(s, "r5", 0.998)
    assert s.change_names("undo") == "r5" and s.change_names("redo") == ""
    assert s.undo() is second and s.view.values["r4"] == a and s.view.values["r5"] == first.values["r5"]
    assert s.change_names("redo") == "r5" and s.change_names("undo") == "r4"
    assert s.undo() is first
    np.testing.assert_array_equal(s.view.design.params, first.design.params)
    with pytest.raises(ValueError, match="^nothing to undo$"):
        s.undo()
    assert s.view is first
    assert s.redo() is second and s.redo().values["r5"] != first.values["r5"]
    with pytest.raises(ValueError, match="^nothing to redo$"):
        s.redo()


def test_a_new_edit_after_an_undo_forgets_what_was_undone() -> None:
    s = Session.default()
    nudge(s, "r4", 1.002)
    s.undo()
    nudge(s, "r6", 1.001)
    assert s.redone == [] and s.change_names("undo") == "r6"
    with pytest.raises(ValueError, match="nothing to redo"):
        s.redo()


def test_refused_and_empty_edits_leave_nothing_to_undo() -> None:
    s = Session.default()
    with pytest.raises(ValueError):
        s.set_param("r4", -1.0)
    s.set_param("r4", s.view.values["r4"])  # the same value: no change
    s.set_walk(a=s.view.walk.a)
    assert s.undone == []
    with pytest.raises(ValueError, match="nothing to undo"):
        s.undo()


def test_a_topology_switch_a_preset_a_target_and_the_walking_view_are_undone_too() -> None:
    s = Session.default()
    start = s.view
    s.load_preset("stephenson1/X1")
    assert s.change_names("undo") == "preset → X3"  # what Undo brings back
    s.set_target(length=310.0)
    s.set_walk(a=30.0)
    s.select_mechanism("jansen")
    assert s.view.design.mechanism.name == "jansen"
    assert s.change_names("undo") == "topology → Stephenson-I six-bar"
    s.undo()
    assert s.view.design.mechanism.name == "stephenson1" and s.view.walk.a == 30.0 and s.view.target.length == 310.0
    assert s.undo().walk.a == start.walk.a
    assert s.undo().target.length == start.target.length
    assert s.undo() is start and s.view.preset == start.preset
    assert [st.view.design.mechanism.name for st in s.redone] == ["jansen", "stephenson1", "stephenson1", "stephenson1"]


def test_a_pick_that_replaced_a_hand_edited_design_is_undone() -> None:
    s = Session.default()
    edited = s.view.values["r4"] * 1.002
    s.set_param("r4", edited)
    s.set_design(get("stephenson1/X1").design())  # a candidate from the Pick panel, or a run's end
    assert s.undo().values["r4"] == edited


def test_undo_is_refused_while_a_stage_runs_and_nothing_moves() -> None:
    s = Session.default()
    nudge(s, "r4", 1.002)
    s.study.status = replace(s.study.status, state="running", stage="subtask2")
    view, undone = s.view, list(s.undone)
    with pytest.raises(ValueError, match="^a stage is running"):
        s.undo()
    assert s.view is view and s.undone == undone and s.redone == []
    s.set_target(length=305.0)  # the target may change during a run, and that change can be undone then
    assert s.undo() is view


def test_undo_keeps_the_last_fifty_changes() -> None:
    s = Session.default()
    views = [s.view]
    for k in range(UNDO_DEPTH + 10):
        s.set_target(length=300.0 + k + 1)
        views.append(s.view)
    assert len(s.undone) == UNDO_DEPTH
    for _ in range(UNDO_DEPTH):
        s.undo()
    assert s.view is views[10] and s.view.target.length == 310.0
    with pytest.raises(ValueError, match="nothing to undo"):
        s.undo()


def test_loading_a_session_starts_a_fresh_undo_history() -> None:
    s = Session.default()
    nudge(s, "r4", 1.002)
    s.undo()
    s.restore(Session.from_dict(Session.default().to_dict()))
    assert s.undone == [] and s.redone == []


def test_the_change_summary_names_what_differs() -> None:
    s = Session.default()
    a = s.view
    for name in ("r4", "r5", "r6", "r7", "r8"):
        nudge(s, name, 1.001)
    assert change_summary(a, s.view) == "r4, r5, r6 and 2 more"
    assert change_summary(a, a) == ""
    s.set_target(height=95.0)
    assert change_summary(a, s.view) == "r4, r5, r6 and 2 more · target"
    s.load_preset("stephenson1/X1")
    assert change_summary(a, s.view) == "preset → X1 · target"
    # A run's pick or a restored branch changes most parameters: a count, or the design, not three names of 16.
    b = Session.default()
    x0 = b.view
    for name in ("r4", "r5", "r6", "r7", "r8", "r9"):
        nudge(b, name, 1.001)
    assert change_summary(x0, b.view) == "6 parameters"
    for name in b.view.design.mechanism.param_names:
        b.set_param(name, b.view.values[name] + 0.01)
    assert change_summary(x0, b.view) == "design"


def test_the_mechanism_panels_undo_and_redo_follow_the_history_and_rest_during_a_run() -> None:
    import studio.app as app

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        panel = studio.mechanism
        assert panel.undo.disabled and panel.redo.disabled
        nudge(studio.session, "r4", 1.002)
        studio.refresh()
        assert not panel.undo.disabled and panel.redo.disabled and panel.undo.hint == "take back: r4"
        assert (panel.undo.label, panel.redo.label) == ("Undo r4", "Redo")  # viser draws no hint on a button
        panel.hold(True)  # a stage runs: its end replaces the design
        assert panel.undo.disabled
        panel.hold(False)
        assert not panel.undo.disabled
        studio.session.undo()
        studio.refresh()
        assert panel.undo.disabled and not panel.redo.disabled and panel.redo.hint == "make again: r4"
        assert (panel.undo.label, panel.redo.label) == ("Undo", "Redo r4")
    finally:
        studio.close()


def test_undoing_a_topology_switch_brings_the_stages_it_kept_as_a_branch_back() -> None:
    from tests.stage_runs import run_stage

    s = Session.default()
    run_stage(s, "subtask1")
    pipe, shown = s.study.pipeline, dict(s.study.shown)
    assert pipe is not None and pipe.lineage
    s.select_mechanism("jansen")  # the pipeline is kept as a branch and the study starts afresh
    assert s.study.pipeline is None and len(s.study.branches) == 1
    s.undo()
    assert s.view.design.mechanism.name == "stephenson1" and s.study.branches == []
    assert s.study.pipeline is not None and s.study.pipeline.to_json() == pipe.to_json()
    assert s.study.shown == shown and s.study.next_stage == "subtask1"
    s.redo()  # the switch again: kept again
    assert s.view.design.mechanism.name == "jansen" and s.study.pipeline is None and len(s.study.branches) == 1
    run_stage(s, "predesign", pop=8, gens=1)  # work on the other topology, then back
    jansen_work = s.study.pipeline
    assert jansen_work is not None
    while s.view.design.mechanism.name == "jansen":
        s.undo()
    assert s.study.pipeline is not None and s.study.pipeline.to_json() == pipe.to_json()
    assert [b.pipeline == json.loads(jansen_work.to_json(indent=None)) for b in s.study.branches] == [True]


def test_undoing_a_branch_restore_brings_back_the_stages_it_left_on_either_topology() -> None:
    # QA walk (session 36): Jansen stages run, the Stephenson-I branch restored, then Undo: the Jansen design came
    # back with "No stage has run yet", its run left in the branch list as if lost.
    from tests.stage_runs import run_stage

    s = Session.default()
    run_stage(s, "subtask1")
    stephenson = s.study.pipeline
    s.select_mechanism("jansen")
    run_stage(s, "predesign", pop=8, gens=1)
    jansen, jansen_design = s.study.pipeline, s.view.design
    assert stephenson is not None and jansen is not None and len(s.study.branches) == 1
    s.restore_branch(0)
    assert s.view.design.mechanism.name == "stephenson1" and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == stephenson.to_json() and len(s.study.branches) == 1
    assert s.change_names("undo") == "branch restore"
    s.undo()
    assert s.view.design == jansen_design and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == jansen.to_json() and s.study.viewing == "predesign"
    assert len(s.study.branches) == 1  # the Stephenson-I stages, kept again
    s.redo()
    assert s.view.design.mechanism.name == "stephenson1" and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == stephenson.to_json() and len(s.study.branches) == 1
    # Restored back by hand, then two Undos: each finds the stages it left although a restore kept them as a new
    # branch (review of session 36: the second Undo showed the Jansen design without its stages).
    s.undo()  # back on Jansen, its stages
    s.restore_branch(0)  # Stephenson-I
    s.restore_branch(0)  # Jansen again, by hand
    s.undo()
    assert s.view.design.mechanism.name == "stephenson1" and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == stephenson.to_json()
    s.undo()
    assert s.view.design.mechanism.name == "jansen" and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == jansen.to_json() and len(s.study.branches) == 1
    s.redo()
    s.redo()
    assert s.view.design.mechanism.name == "jansen" and s.study.pipeline is not None
    assert s.study.pipeline.to_json() == jansen.to_json() and len(s.study.branches) == 1
    s.restore_branch(0)
    # On one topology too: Undo takes the restore back, pipeline and design.
    run_stage(s, "subtask1", seed=6)  # a second run of the stage: the first one's pipeline becomes a branch
    again, design = s.study.pipeline, s.view.design
    assert again is not None and len(s.study.branches) == 2
    s.restore_branch([b.pipeline == json.loads(stephenson.to_json(indent=None)) for b in s.study.branches].index(True))
    assert s.study.pipeline is not None and s.study.pipeline.to_json() == stephenson.to_json()
    s.undo()
    assert s.view.design == design and s.study.pipeline is not None and s.study.pipeline.to_json() == again.to_json()


def test_a_deleted_branch_is_not_brought_back_and_the_design_still_is() -> None:
    from tests.stage_runs import run_stage

    s = Session.default()
    run_stage(s, "subtask1")
    s.select_mechanism("jansen")
    s.study.delete_branch(s.study.branches[0].label)
    s.undo()
    assert s.view.design.mechanism.name == "stephenson1" and s.study.pipeline is None and s.study.branches == []


def test_a_long_change_is_shortened_to_fit_the_button() -> None:
    from studio.panels.mechanism import STEP_LABEL, step_label

    assert step_label("Undo", "") == "Undo" and step_label("Redo", "preset → X3") == "Redo preset → X3"
    long = step_label("Undo", "r4, r5, r6 and 2 more · target · walking view")
    assert len(long) == STEP_LABEL and long.endswith("…") and long.startswith("Undo r4, r5, r6 and 2 more")


def test_undo_takes_a_pass_on_back_and_then_the_pick_and_the_panels_agree() -> None:
    # Undo right after "Use for next stage" took back the pick before it: the editor went back to the run's pick
    # while the Candidate, Pick panel, inset and Stages (next stage from #9) still showed the member passed on.
    import studio.app as app
    from tests.stage_runs import run_stage

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        s = studio.session
        run_stage(s, "subtask1", pop=12, gens=3)
        study = s.study
        r = study.result("subtask1")
        first = study.shown_member("subtask1")
        other = next(i for i in range(r.pop) if i != first and r.feasible[i])
        before_pick = s.view
        studio.pick("subtask1", other, None)
        assert study.shown_member("subtask1") == other and s.change_names("undo") == "pick"  # not its parameters
        depth = len(s.undone)
        studio.pick("subtask1", other, None)  # a page echoing the dropdown: no new step (it cleared Redo)
        assert len(s.undone) == depth
        picked_view = s.view
        studio.use_for_next("subtask1", None)
        assert study.result("subtask1").picked == other and study.next_stage == "subtask2" and study.from_pick
        assert s.change_names("undo") == "pass-on"
        # The buttons follow though the design did not change (they were redrawn only with a new design).
        assert studio.mechanism.undo.label == "Undo pass-on" and studio.mechanism.redo.label == "Redo"
        s.undo()  # the pass-on: the pick and the stage to run next go back; the design stays
        studio.refresh()
        assert studio.mechanism.redo.label == "Redo pass-on" and not studio.mechanism.redo.disabled
        assert s.view is picked_view and study.shown_member("subtask1") == other
        assert study.result("subtask1").picked == r.picked and (study.next_stage, study.from_pick) != ("subtask2",
                                                                                                       True)
        s.undo()  # the pick: the editor and every panel back on the member shown before
        assert study.shown_member("subtask1") == first and s.view is before_pick
        s.redo()
        s.redo()  # both made again
        assert s.view is picked_view and np.array_equal(s.view.design.params[0], r.X[other])
        assert study.shown_member("subtask1") == other and study.result("subtask1").picked == other
        assert (study.next_stage, study.from_pick) == ("subtask2", True)
        # Once a run came between, the study is not rewound (its populations changed): only the design moves.
        run_stage(s, "subtask2", pop=12, gens=2)
        ran, shown = study.result("subtask2"), dict(study.shown)
        s.set_param("r4", s.view.values["r4"] + 0.25)
        s.undo()
        assert ran is not None and study.result("subtask2") is ran and study.shown == shown
    finally:
        studio.close()


def test_a_pass_on_is_undone_and_redone_after_its_stages_came_back_from_a_branch() -> None:
    # Review of session 36: once an Undo of a topology switch (or of a restore) had brought the stages back, rebuilt
    # from their JSON, the pass-on made before them could not be undone: Undo read "the same design" and did nothing.
    import studio.app as app
    from tests.stage_runs import run_stage

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        s, study = studio.session, studio.session.study
        run_stage(s, "subtask1", pop=12, gens=3)
        before = (study.next_stage, study.from_pick)
        studio.use_for_next("subtask1", None)
        passed = (study.next_stage, study.from_pick)
        assert passed == ("subtask2", True) and passed != before
        for _ in range(2):  # the second time through, the stages are a copy of a copy
            s.select_mechanism("jansen")
            s.undo()  # Stephenson-I again, its stages rebuilt from the branch
            assert s.view.design.mechanism.name == "stephenson1" and s.change_names("undo") == "pass-on"
            s.undo()
            assert (study.next_stage, study.from_pick) == before and s.change_names("redo") == "pass-on"
            s.redo()
            assert (study.next_stage, study.from_pick) == passed
    finally:
        studio.close()


def test_a_target_typed_back_to_the_paper_s_values_is_the_paper_s_again() -> None:
    s = Session.default()
    s.set_target(length=250.0)
    assert s.view.target.origin == "set by hand"
    s.set_target(length=300.0)  # it stayed "(set by hand)" with the paper's numbers
    assert s.view.target.origin == "the paper's" and s.view.target.label().endswith("(the paper's)")


def test_a_step_whose_selection_a_run_overtook_is_named_by_its_design_alone() -> None:
    # An edit made before a run kept the study's selection of then; after the run it read "r4 · pass-on",
    # though Undo brings back only r4 (the run changed the populations).
    from tests.stage_runs import run_stage

    s = Session.default()
    nudge(s, "r4", 1.002)
    run_stage(s, "subtask1", pop=12, gens=2)
    assert s.study.result("subtask1") is not None
    assert s.change_names("undo") == "r4"


def test_undo_names_the_change_by_what_made_it_a_run_s_pick_a_shown_stage_or_a_restore() -> None:
    # A rehearsal read "Undo 15 parameters" after a run ended and "Undo design" after a Stop: true, but it did not
    # say that Undo takes back the run's pick.
    import studio.app as app
    from studio.chains import RunSettings

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        s = studio.session
        nudge(s, "r4", 1.002)
        s.study.settings["subtask1"] = RunSettings("subtask1", pop_size=12, n_gen=3, seed=5)
        with s.lock:
            s.study.next_stage = "subtask1"
        assert studio.start_run()
        studio.runner.join(60)
        studio.refresh()
        assert s.change_names("undo") == "subtask1's pick"
        assert studio.mechanism.undo.label == "Undo subtask1's pick"
        s.undo()
        assert s.change_names("redo") == "subtask1's pick" and s.change_names("undo") == "r4"
        s.redo()
        s.set_param("r5", s.view.values["r5"] * 1.002)
        studio.view_stage("subtask1", None)
        assert s.change_names("undo") == "showing subtask1"
        s.select_mechanism("watt1")  # keeps the Stephenson-I stages as a branch
        studio.restore_branch(0, None)
        assert s.change_names("undo") == "branch restore"
        assert s.view.design.mechanism.name == "stephenson1"
    finally:
        studio.close()
