"""Studio optimization state without a browser: chains, runs in the worker, picks, branches, session files."""

from __future__ import annotations

import json
import threading
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from core.analysis.targets import parse_target
from core.kinematics import presets
from core.optimize import problem as problem_registry
from core.optimize.box import SUBTASK_STEPS, periodic_mask
from core.optimize.problem import ProblemSpec
from core.optimize.result import StageResult
from studio import palette
from studio.chains import RunSettings, chain_for, find, stage_spec
from studio.runner import LIVE_PERIOD, Runner
from studio.session_pack import pack_array, unpack_study
from studio.state import Session
from studio.study import RunStatus, Study, done_at, last_run
from studio.study_view import study_view
from studio.target import TargetSpec

X3 = presets.get("stephenson1/X3")


def assert_same_design(a: np.ndarray, b: np.ndarray) -> None:
    """Equal parameter vectors, periodic angles (the crank phase g) compared modulo 2 pi."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    per = periodic_mask(X3.mechanism)
    d[..., per] = (d[..., per] + np.pi) % (2.0 * np.pi) - np.pi
    np.testing.assert_allclose(d, 0.0, atol=1e-9)


def tiny(study: Study, name: str, pop: int = 8, gens: int = 3, seed: int = 4) -> None:
    study.settings[name] = RunSettings(name, pop_size=pop, n_gen=gens, seed=seed)


def run(session: Session, name: str, from_pick: bool, on_generation=None, live_period: float = 0.0) -> Runner:
    """Run one stage to the end through a Runner, as the Stages panel does (every generation recorded unless
    ``live_period``: the studio records one every LIVE_PERIOD s)."""
    done = threading.Event()
    runner = Runner(session.lock, lambda: session.study, on_generation or (lambda p: None), done.set, live_period)
    chain = chain_for(session.view.design.mechanism)
    stage = find(chain, name)
    settings = session.study.settings_for(stage)
    view = session.view
    runner.start(lambda s: s.plan(stage, settings, view.design, view.target, from_pick, chain))
    assert done.wait(60), "the run did not finish"
    runner.join(10)
    return runner


@pytest.fixture
def session() -> Session:
    s = Session.default()
    tiny(s.study, "subtask1")
    tiny(s.study, "subtask2")
    return s


# Chains --------------------------------------------------------------------------------------------


def test_six_bar_chain_is_predesign_then_subtasks_with_the_spec_boxes() -> None:
    chain = chain_for(X3.mechanism)
    assert [c.name for c in chain] == ["predesign", "subtask1", "subtask2", "subtask3"]
    assert chain[0].s is None
    for k in (1, 2, 3):
        assert (chain[k].s, chain[k].d) == SUBTASK_STEPS[k]


def test_rtclm_chain_is_its_two_subtasks() -> None:
    assert [c.name for c in chain_for(presets.get("rtclm/case1").mechanism)] == ["rtclm1", "rtclm2"]


def test_a_stage_spec_searches_the_studio_target_with_the_chosen_settings() -> None:
    target = TargetSpec(280.0, 90.0, 1.5)
    stage = find(chain_for(X3.mechanism), "subtask2")
    spec = stage_spec(stage, RunSettings("subtask2", "nsga3", 12, 5, 9), target)
    # The chain's 10 mm step is the paper's for its 300 mm stride: a 280 mm target sizes it to 28/3 mm.
    assert (spec.s, spec.d, spec.n_gen, spec.seed) == (0.1, pytest.approx(10.0 * 280.0 / 300.0), 5, 9)
    assert spec.problem.scale == pytest.approx(280.0 / 300.0)
    assert spec.algorithm.name == "nsga3" and spec.algorithm.pop_size == 12
    assert spec.pick == "best:h_s"
    t = parse_target(spec.problem.options["target"])
    np.testing.assert_allclose(t.sample(360), target.points(360))
    # Another problem in the slot: the chain's pick rule falls back to the knee if it names a missing objective.
    other = stage_spec(stage, RunSettings("path_box"), target)
    assert other.problem.name == "path_box" and other.pick == "knee"


@pytest.mark.parametrize(("field", "value", "message"), [("pop_size", 1, "population"), ("n_gen", 0, "generations"),
                                                          ("seed", -1, "seed"), ("algorithm", "nope", "algorithm")])
def test_run_settings_refuse_bad_values_naming_them(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        RunSettings("subtask1", **{field: value})


# Runs ------------------------------------------------------------------------------------------------


def test_a_run_records_its_result_with_the_chain_pick_and_reports_every_generation(session: Session) -> None:
    seen = []
    run(session, "subtask1", from_pick=False, on_generation=lambda p: seen.append(p.generation))
    study = session.study
    r = study.result("subtask1")
    assert isinstance(r, StageResult) and r.status == "complete" and r.generation == 3 and r.pop == 8
    assert seen == [1, 2, 3]
    assert r.picked == r.shortlist.knees[0]
    assert study.status.state == "idle" and study.status.ok and study.status.message == "complete"
    # The run started a pipeline at subtask 1 from the editor's design: its box is built around X3.
    assert_same_design(r.box.center, X3.values)
    assert study.stage_names() == ("subtask1", "subtask2", "subtask3")


def test_without_a_session_file_the_live_result_is_recorded_at_the_pages_pace_and_the_end_in_full(
        session: Session) -> None:
    # A live result re-evaluates the population's metrics (60 % of a subtask-2 generation at pop 100): made every
    # generation it slowed a run to 1.6 times its compute time. 40 generations of pop 8 take far under 0.25 s.
    tiny(session.study, "subtask1", gens=40)
    seen: list[int] = []
    run(session, "subtask1", from_pick=False, on_generation=lambda p: seen.append(p.generation),
        live_period=LIVE_PERIOD)
    assert seen[0] == 1 and len(seen) < 40
    r = session.study.result("subtask1")
    assert r.status == "complete" and r.generation == 40 and r.picked == r.shortlist.knees[0]


def test_a_stop_between_recorded_generations_keeps_the_generation_it_stopped_at(session: Session) -> None:
    tiny(session.study, "subtask1", gens=5000)
    seen: list[int] = []
    done = threading.Event()
    runner = Runner(session.lock, lambda: session.study, lambda p: seen.append(p.generation), done.set, LIVE_PERIOD)
    chain = chain_for(X3.mechanism)
    stage = find(chain, "subtask1")
    settings, view = session.study.settings_for(stage), session.view
    runner.start(lambda s: s.plan(stage, settings, view.design, view.target, False, chain))
    wait = threading.Event()
    while len(seen) < 3 and not done.is_set():  # a few recorded generations, then Stop at any moment
        wait.wait(0.01)
    runner.stop()
    assert done.wait(60)
    r = session.study.result("subtask1")
    assert r.status == "cancelled" and r.generation == session.study.status.generation >= seen[-1]
    assert f"stopped at generation {r.generation}/5000" in session.study.status.message


def test_a_branch_label_names_the_member_restore_brings_back_and_the_algorithm(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    r = session.study.result("subtask1")
    other = next(i for i in range(r.pop) if i != r.picked)
    session.study.show("subtask1", other)  # browsed, not passed on
    session.study.keep_branch("before a new start")
    label = session.study.branches[0].label
    values = ", ".join(f"{o} {v:.3g}" for o, v in zip(r.objectives, r.F[other], strict=True))
    # It used to name the pick and its values while Restore showed the browsed member.
    assert label.startswith(f"1: {r.mechanism.title} · subtask1 #{r.picked} showing #{other} by NSGA-II · {values} "
                            "(before a new start")
    assert session.study.branches[0].shown == {"subtask1": other}


def test_only_one_run_at_a_time(session: Session) -> None:
    gate = threading.Event()
    runner = Runner(session.lock, lambda: session.study, lambda p: gate.wait(10), lambda: None)
    chain = chain_for(X3.mechanism)
    stage = find(chain, "subtask1")
    settings = session.study.settings_for(stage)
    view = session.view

    def plan(s: Study):
        return s.plan(stage, settings, view.design, view.target, False, chain)

    runner.start(plan)
    with pytest.raises(ValueError, match="already running"):
        runner.start(plan)
    gate.set()
    runner.join(30)
    assert session.study.branches == []  # one pipeline: a second start would have kept the first as a branch


def test_stop_ends_the_run_between_generations_and_keeps_the_partial_result(session: Session) -> None:
    tiny(session.study, "subtask1", gens=50)
    holder: dict[str, Runner] = {}
    gate = threading.Event()

    def on_generation(p) -> None:
        if p.generation == 2:
            gate.wait(10)  # the runner is registered by then
            holder["r"].stop()

    done = threading.Event()
    runner = Runner(session.lock, lambda: session.study, on_generation, done.set, 0.0)
    holder["r"] = runner
    chain = chain_for(X3.mechanism)
    stage = find(chain, "subtask1")
    settings, view = session.study.settings_for(stage), session.view
    runner.start(lambda s: s.plan(stage, settings, view.design, view.target, False, chain))
    gate.set()
    assert done.wait(60)
    r = session.study.result("subtask1")
    assert r.status == "cancelled" and r.generation == 2 and r.pop == 8
    assert "stopped at generation 2/50" in session.study.status.message
    # Picked as a finished run is: History's pick column was blank while the editor showed the stopped run's knee.
    assert r.picked is not None and session.study.shown_member("subtask1") == r.picked
    from studio.candidates import history_rows
    row = history_rows([r], {}, ["subtask1"], {})[0]
    assert row.pick == f"#{r.picked}" and row.values


def test_a_failing_problem_is_reported_and_the_studio_stays_idle(session: Session,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    def boom() -> ProblemSpec:
        def evaluate(design):  # a problem that fails once the run has started
            raise RuntimeError("the solver lost its licence")

        return ProblemSpec("boom", evaluate, ("f1",))

    monkeypatch.setitem(problem_registry._FACTORIES, "boom", boom)
    session.load_preset("rtclm/case4")
    session.study.settings["rtclm1"] = RunSettings("boom", pop_size=4, n_gen=1)
    run(session, "rtclm1", from_pick=False)
    st = session.study.status
    assert st.state == "idle" and not st.ok and st.message == "failed: the solver lost its licence"


def test_a_problem_that_does_not_fit_the_mechanism_is_refused_before_the_run(session: Session) -> None:
    session.load_preset("rtclm/case4")
    session.study.settings["rtclm1"] = RunSettings("predesign", pop_size=4, n_gen=1)  # no placement for RTCLM
    with pytest.raises(ValueError, match="problem 'predesign' does not fit the RTCLM"):
        run(session, "rtclm1", from_pick=False)
    assert session.study.status.state == "idle" and session.study.pipeline is None


@pytest.mark.parametrize(("preset", "stage", "settings", "message"), [
    ("stephenson1/X3", "subtask1", RunSettings("subtask1", "cmoemt", 8, 2), "cmoemt needs a population of at least 10"),
    ("rtclm/case1", "rtclm1", RunSettings("rtclm1", "ctaea", 20, 2), "ctaea needs at least two objectives"),
])
def test_settings_the_algorithm_refuses_stop_the_click_and_change_nothing(session: Session, preset, stage, settings,
                                                                          message) -> None:
    session.load_preset(preset)
    chain = chain_for(session.view.design.mechanism)
    run(session, chain[0].name, from_pick=False)  # some work the designer has: a pipeline with a result
    pipe, branches = session.study.pipeline, list(session.study.branches)
    session.study.settings[stage] = settings
    runner = Runner(session.lock, lambda: session.study, lambda p: None, lambda: None)
    view = session.view
    with pytest.raises(ValueError, match=message):
        runner.start(lambda s: s.plan(find(chain, stage), settings, view.design, view.target, False, chain))
    assert not runner.busy and session.study.pipeline is pipe and session.study.branches == branches
    assert not session.study.status.running


# Picks, next stage, branches ----------------------------------------------------------------------


def test_use_for_next_stage_passes_the_pick_on_and_the_next_box_is_built_around_it(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    study = session.study
    r1 = study.result("subtask1")
    member = next(i for i in range(r1.pop) if i != r1.picked)
    study.show("subtask1", member)
    assert study.shown_member("subtask1") == member and r1.picked != member  # shown, not yet committed
    assert study.use_for_next("subtask1", member, chain_for(X3.mechanism)) == "subtask2"
    assert study.result("subtask1").picked == member and study.from_pick and study.next_stage == "subtask2"
    box = study.next_box("subtask2", session.view.target)
    assert_same_design(box.center, r1.X[member])
    run(session, "subtask2", from_pick=True)
    r2 = study.result("subtask2")
    assert r2.parent_pick == member
    assert_same_design(r2.box.center, box.center)
    assert study.branches == []


def test_a_design_changed_by_hand_is_where_the_next_run_starts(session: Session) -> None:
    # After a pass-on, loading preset X3 left "Start from" on the previous stage's pick: Run searched around the
    # old pick and then replaced the preset just loaded with its result.
    run(session, "subtask1", from_pick=False)
    study = session.study
    chain = chain_for(X3.mechanism)
    study.use_for_next("subtask1", study.result("subtask1").picked, chain)
    assert study.from_pick
    version = study.version
    session.load_preset("stephenson1/X2")
    assert not study.from_pick and study.version > version  # the Stages panel redraws
    study.use_for_next("subtask1", study.result("subtask1").picked, chain)
    session.set_param("r4", session.view.design.named(0)["r4"] + 0.5)
    assert not study.from_pick
    # The studio's own changes of the design keep it: a pick shown, a run's end.
    study.use_for_next("subtask1", study.result("subtask1").picked, chain)
    session.set_design(study.result("subtask1").pick(0))
    assert study.from_pick
    session.set_design(study.result("subtask1").pick(0), by_hand=True)  # a study's design, loaded
    assert not study.from_pick


def test_changing_a_pick_that_later_stages_grew_from_keeps_a_branch_and_it_can_be_restored(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    study = session.study
    chain = chain_for(X3.mechanism)
    first = study.result("subtask1").picked
    study.use_for_next("subtask1", first, chain)
    run(session, "subtask2", from_pick=True)
    old_x2 = study.result("subtask2")
    other = next(i for i in range(study.result("subtask1").pop) if i != first)
    study.use_for_next("subtask1", other, chain)
    assert study.result("subtask2") is None  # the pipeline keeps one lineage
    assert len(study.branches) == 1
    study.restore_branch(0)
    np.testing.assert_array_equal(study.result("subtask2").X, old_x2.X)
    assert study.result("subtask1").picked == first
    assert len(study.branches) == 1  # the replaced pipeline became a branch in turn


def test_a_loaded_session_shows_its_last_run_and_a_stage_stopped_on_its_target_a_full_bar(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    before = session.study.status
    loaded = Study.from_dict(json.loads(json.dumps(session.study.to_dict())), session.view.target)
    st = loaded.status  # it read "Idle. Choose a stage and press Run." beside the finished stage
    assert (st.state, st.stage, st.message, st.ok, st.fraction) == ("idle", "subtask1", "complete", True, 1.0)
    assert st.elapsed == pytest.approx(before.elapsed, rel=0.5)
    assert Study.from_dict({}, session.view.target).status == RunStatus()
    r = session.study.result("subtask1")
    early = replace(r, status="stopped", generation=2)  # the target reached at generation 2 of 3
    assert done_at(early) == 2 and last_run(early).fraction == 1.0
    assert last_run(early).message == "target reached at generation 2"
    assert done_at(replace(r, status="cancelled", generation=2)) == 3  # a stop by hand leaves the bar short


def test_a_topology_switch_starts_the_stages_panel_afresh(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    assert session.study.status.stage == "subtask1" and session.study.status.message
    session.select_mechanism("jansen")
    assert session.study.status.stage is None and session.study.status.message == ""  # no "Last run: subtask1"
    session.restore_branch(0)  # the branch's last stage is the last run again
    st = session.study.status
    assert (st.state, st.stage, st.message, st.ok) == ("idle", "subtask1", "complete", True) and st.elapsed > 0


def test_branch_numbers_never_repeat_after_a_restore(session: Session) -> None:
    # Numbered len + 1, the branch a restore left got the number of one still listed ("5: ..." twice).
    run(session, "subtask1", from_pick=False)
    for _ in range(2):
        run(session, "subtask1", from_pick=False)  # each re-run keeps the previous lineage as a branch
    study = session.study
    assert [b.label.split(":")[0] for b in study.branches] == ["1", "2"]
    study.restore_branch(0)  # 1 comes back; the current one is kept as 3
    numbers = [b.label.split(":")[0] for b in study.branches]
    assert numbers == ["2", "3"] and len(set(b.label for b in study.branches)) == 2


def test_leaving_the_same_pipeline_again_keeps_one_branch_and_undo_still_finds_it(session: Session) -> None:
    # A restored branch left again unchanged was kept once more, told apart only by the clock: the lag walk ended
    # with three copies each of two branches, each one more copy in the session file.
    run(session, "subtask1", from_pick=False)
    study = session.study
    first = study.keep_branch("first")
    assert first is not None and study.keep_branch("again") is first and study.branches == [first]
    study.restore_branch(0)  # the current pipeline, the same, is left for it
    assert len(study.branches) == 1 and study.keep_branch("left again") is study.branches[0]
    # A topology switch that leaves the same pipeline names the branch it is, so Undo brings its stages back.
    kept = study.branches[0]
    view = session.load_preset("jansen")
    assert study.branches == [kept] and study.pipeline is None and view.design.mechanism.name == "jansen"
    session.undo()
    assert session.view.design.mechanism.name == "stephenson1"
    assert study.pipeline is not None and study.pipeline.lineage and study.branches == []


def test_re_running_a_stage_keeps_the_previous_lineage_as_a_branch(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    run(session, "subtask1", from_pick=False)
    assert len(session.study.branches) == 1


def test_re_running_a_stage_from_its_pick_keeps_the_old_results_as_a_branch(session: Session) -> None:
    study, chain = session.study, chain_for(X3.mechanism)
    run(session, "subtask1", from_pick=False)
    study.use_for_next("subtask1", study.result("subtask1").picked, chain)
    run(session, "subtask2", from_pick=True)
    old = study.result("subtask2")
    run(session, "subtask2", from_pick=True)  # again, from the same pick: the first run stays reachable
    assert len(study.branches) == 1 and study.result("subtask2") is not old
    study.restore_branch(0)
    np.testing.assert_array_equal(study.result("subtask2").X, old.X)


def test_a_restored_branch_brings_back_the_settings_its_stages_ran_with(session: Session) -> None:
    # The Stages panel showed the other branch's algorithm and budget beside the restored result (a demo
    # rehearsal's cmoes branch came back as imtcmo 100 x 400), and Run "again" would have run those.
    study = session.study
    study.settings["subtask1"] = RunSettings("subtask1", "cmoes", pop_size=12, n_gen=2, seed=7)
    run(session, "subtask1", from_pick=False)
    study.settings["subtask1"] = RunSettings("subtask1", "imtcmo", pop_size=12, n_gen=3, seed=2)
    run(session, "subtask1", from_pick=False)  # the cmoes pipeline becomes branch 1
    study.settings["subtask2"] = RunSettings("subtask2", "mccmo", pop_size=6, n_gen=2, seed=3)  # not in the branch
    study.restore_branch(0)
    assert study.settings["subtask1"] == RunSettings("subtask1", "cmoes", pop_size=12, n_gen=2, seed=7)
    assert study.settings["subtask2"] == RunSettings("subtask2", "mccmo", pop_size=6, n_gen=2, seed=3)
    study.restore_branch(0)  # and back: the imtcmo run's
    assert study.settings["subtask1"] == RunSettings("subtask1", "imtcmo", pop_size=12, n_gen=3, seed=2)


def test_a_result_whose_record_makes_no_settings_restores_without_them() -> None:
    from studio.study import ran_with

    good = SimpleNamespace(settings={"problem": {"name": "subtask2"}, "algorithm": {"name": "nsga2", "pop_size": 30}},
                           n_gen=12, seed=5)
    assert ran_with(good) == RunSettings("subtask2", "nsga2", pop_size=30, n_gen=12, seed=5)  # type: ignore[arg-type]
    for bad in ({}, {"problem": {"name": "subtask2"}, "algorithm": {"name": "no-such", "pop_size": 30}},
                {"problem": {"name": "subtask2"}, "algorithm": {"name": "nsga2", "pop_size": 1}}):
        assert ran_with(SimpleNamespace(settings=bad, n_gen=12, seed=5)) is None  # type: ignore[arg-type]


def test_a_kept_branch_does_not_change_with_later_picks(session: Session) -> None:
    study, chain = session.study, chain_for(X3.mechanism)
    run(session, "subtask1", from_pick=False)
    r1 = study.result("subtask1")
    first, other = r1.picked, next(i for i in range(r1.pop) if i != r1.picked)
    study.use_for_next("subtask1", first, chain)
    run(session, "subtask2", from_pick=True)
    study.show("subtask1", first)
    study.use_for_next("subtask1", other, chain)  # later stages grew from `first`: they become a branch
    study.show("subtask1", other)
    assert len(study.branches) == 1 and study.branches[-1].shown.get("subtask1", first) == first
    run(session, "subtask2", from_pick=True)  # subtask 2 grows from `other` now
    n = len(study.branches)
    study.use_for_next("subtask1", other, chain)  # the same pick again: nothing to keep, subtask 2 stays
    assert len(study.branches) == n and study.result("subtask2") is not None


def test_show_views_that_stage_and_a_re_run_shows_its_new_pick(session: Session) -> None:
    study = session.study
    run(session, "subtask1", from_pick=False)
    r1 = study.result("subtask1")
    other = next(i for i in range(r1.pop) if i != r1.picked)
    study.viewing = None
    study.show("subtask1", other)
    assert study.viewing == "subtask1" and study.shown_member("subtask1") == other
    run(session, "subtask1", from_pick=False)
    assert study.shown_member("subtask1") == study.result("subtask1").picked


def test_stop_with_nothing_running_changes_nothing() -> None:
    s = Session.default()
    runner = Runner(s.lock, lambda: s.study, lambda p: None, lambda: None, 0.0)
    assert runner.stop() is False and s.study.status.state == "idle" and not s.study.status.running
    tiny(s.study, "subtask1")
    run(s, "subtask1", from_pick=False)
    assert s.study.result("subtask1") is not None and s.study.live is None  # the live copy ends with the run


def test_an_older_sessions_branch_restores_on_its_last_stage_from_its_pick_without_a_target(
        session: Session) -> None:
    import dataclasses

    study, chain = session.study, chain_for(X3.mechanism)
    run(session, "subtask1", from_pick=False)
    first = study.result("subtask1").picked
    study.use_for_next("subtask1", first, chain)
    run(session, "subtask2", from_pick=True)
    assert study.target is not None
    study.use_for_next("subtask1", next(i for i in range(study.result("subtask1").pop) if i != first), chain)
    # as a session saved before branches kept their state: no target, no shown members, no next stage
    study.branches[0] = dataclasses.replace(study.branches[0], target=None, shown={}, next_stage=None,
                                            from_pick=False)
    study.restore_branch(0)
    assert study.target is None and study.next_stage == "subtask2" and study.from_pick
    assert study.shown == {"subtask2": study.result("subtask2").picked}
    back = Study.from_dict(json.loads(json.dumps(study.to_dict())), None)
    assert back.from_pick and back.next_stage == "subtask2"
    tiny(study, "subtask3")
    run(session, "subtask3", from_pick=True)  # the chain's last stage has a result now
    assert study.parent_result(study.pipeline.stages[0].name) is None  # the first stage has no parent
    assert study.target is not None
    study.start_over("another topology")
    assert study.target is None and study.pipeline is None and not study.from_pick


def test_a_shown_member_beyond_the_population_falls_back_to_the_pick(session: Session) -> None:
    from studio.study import member_shown

    run(session, "subtask1", from_pick=False)
    r = session.study.result("subtask1")
    assert member_shown(r, {"subtask1": r.pop}) == r.picked and member_shown(r, {"subtask1": 0}) == 0


def test_the_stage_panel_names_the_pick_the_next_box_is_built_around(session: Session) -> None:
    study, chain = session.study, chain_for(X3.mechanism)
    run(session, "subtask1", from_pick=False)
    r1 = study.result("subtask1")
    member = next(i for i in range(r1.pop) if i not in (r1.picked, r1.shortlist.first))
    study.use_for_next("subtask1", member, chain)
    study.viewing = None
    sv = study_view(study, session.view.design, chain, session.view.target)
    assert sv.box_note == f"around subtask1's pick #{member}"
    assert sv.viewing == sv.names[0]  # nothing chosen to view: the pipeline's first stage


def rtclm1_run(pop: int, gens: int) -> StageResult:
    """RTCLM subtask 1 from a paper row far from h6 (159 mm for 50), seed 1, to the end."""
    s = Session.default("rtclm/case1-CMOES")
    tiny(s.study, "rtclm1", pop=pop, gens=gens, seed=1)
    run(s, "rtclm1", from_pick=False)
    r = s.study.result("rtclm1")
    assert r is not None
    return r


def test_a_stage_that_stops_early_on_its_target_gets_its_automatic_pick() -> None:
    r = rtclm1_run(40, 40)
    assert r.status == "stopped" and r.generation < 40  # |h6 - h6_t| reached: an early stop, not a Stop click
    assert r.picked is not None and r.feasible[r.picked]


def test_a_fresh_session_runs_its_first_stage_first() -> None:
    s = Session.default()
    sv = study_view(s.study, s.view.design, chain_for(s.view.design.mechanism), s.view.target)
    assert sv.next_stage == chain_for(s.view.design.mechanism)[0].name == "predesign"


def test_the_study_view_shows_the_next_box_around_the_editor_design_when_starting_fresh(session: Session) -> None:
    with session.lock:
        session.study.next_stage = "subtask3"
        sv = study_view(session.study, session.view.design, chain_for(X3.mechanism), session.view.target)
    assert sv.next_stage == "subtask3" and sv.box is not None
    h = np.maximum(0.05 * np.abs(X3.values), np.where([p.kind == "angle" for p in X3.mechanism.params],
                                                       0.05 * np.pi, 5.0))
    free = ~sv.box.periodic
    np.testing.assert_allclose(sv.box.upper[free], np.minimum(X3.values + h, X3.mechanism.upper)[free])


# Session files ----------------------------------------------------------------------------------------


def test_a_session_with_a_pipeline_round_trips_through_json_bit_for_bit(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    study = session.study
    study.show("subtask1", 1)
    data = json.loads(json.dumps(session.to_dict()))
    back = Session.from_dict(data)
    r, b = study.result("subtask1"), back.study.result("subtask1")
    np.testing.assert_array_equal(r.X, b.X)
    np.testing.assert_array_equal(r.F, b.F)
    assert b.picked == r.picked and back.study.shown_member("subtask1") == 1
    assert back.study.settings == study.settings and back.study.stage_names() == study.stage_names()
    assert back.to_dict() == data


def test_every_generation_is_saved_and_an_interrupted_run_loads_back_as_such(session: Session) -> None:
    snapshots: list[dict] = []
    run(session, "subtask1", from_pick=False, on_generation=lambda p: snapshots.append(session.to_dict()))
    assert len(snapshots) == 3
    middle = Session.from_dict(json.loads(json.dumps(snapshots[1])))
    r = middle.study.result("subtask1")
    assert r.status == "running" and r.generation == 2 and r.pop == 8
    view = study_view(middle.study, middle.view.design, chain_for(X3.mechanism), middle.view.target)
    assert view.result("subtask1") is r


def first_result(d: dict) -> dict:
    """The stored (packed) result of the pipeline's first stage in a version-3 session."""
    return d["study"]["results"][d["study"]["pipeline"]["results"][0]]


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d["study"].update(pipeline=[]), "pipeline must be an object"),
    (lambda d: d["study"]["pipeline"].update(format="x"), "not a pipeline"),
    (lambda d: first_result(d).update(X=pack_array([[1.0]])), "pipeline"),
    (lambda d: d["study"]["pipeline"]["results"].__setitem__(0, "0" * 20), "no stage result '00000000000000000000'"),
    (lambda d: first_result(d)["X"].update(f64="not base64!"), "X: not base64"),
    (lambda d: first_result(d)["X"].update(shape=[3, 3]), r"bytes for shape \[3, 3\]"),
    (lambda d: first_result(d)["metrics"].update(mse={"shape": [-1]}), "metrics.mse: expected a packed array"),
    (lambda d: d["study"].update(settings={"subtask1": {"problem": "subtask1", "pop_size": 1}}), "population"),
    (lambda d: d["study"].update(shown={"subtask1": "a"}), "member indices"),
    (lambda d: d["study"].update(branches=[{"label": "b"}]), "branch 1"),
    (lambda d: d.update(walk={"layout": "hexapod"}), "walking layout"),
])
def test_a_malformed_study_is_refused_naming_the_problem(session: Session, change, message: str) -> None:
    run(session, "subtask1", from_pick=False)
    data = json.loads(json.dumps(session.to_dict()))
    change(data)
    with pytest.raises(ValueError, match=message):
        Session.from_dict(data)


def test_a_version_1_session_still_loads() -> None:
    data = Session.default().to_dict()
    data["version"] = 1
    for key in ("walk", "study"):
        del data[key]
    back = Session.from_dict(data)
    assert back.study.pipeline is None and back.view.walk.layout == "biped"


def test_restore_takes_over_a_loaded_session_but_not_while_a_stage_runs(session: Session) -> None:
    other = Session.default("stephenson1/X0")
    session.restore(other)
    assert session.view.preset == "stephenson1/X0" and session.study is other.study
    session.study.status = session.study.status.__class__("running", "subtask1")
    with pytest.raises(ValueError, match="running"):
        session.restore(Session.default())


def test_the_studio_saves_a_running_stage_every_few_seconds_and_every_pick(tmp_path, monkeypatch) -> None:
    # Saved after every generation, a run with a session file took about 15 times as long (a session of a few
    # dozen branches takes 30-45 ms to write, a generation a few ms).
    import studio.app as app
    from studio.session_file import load_session

    path = tmp_path / "session.json"
    saved: list[dict] = []
    real = app.save_session

    def spy(session: Session, p) -> None:
        real(session, p)
        saved.append(json.loads(p.read_text()))

    monkeypatch.setattr(app, "save_session", spy)
    studio = app.Studio(Session.default(), host="127.0.0.1", port=0, session_path=path)
    try:
        tiny(studio.session.study, "subtask2", pop=16, gens=15)
        with studio.session.lock:
            studio.session.study.next_stage = "subtask2"
        saved.clear()
        # A page makes the animator refresh the panels every STUDY_PUSH_PERIOD s, and each live update changes the
        # study: refresh saved at each of those too (3 of a run's 4.6 s with a 2.6 MB session).
        done = threading.Event()

        def page() -> None:
            while not done.is_set():
                studio.refresh()
                time.sleep(0.01)

        watcher = threading.Thread(target=page)
        assert studio.start_run()
        watcher.start()
        studio.runner.join(60)
        done.set()
        watcher.join()
        studies = [unpack_study(s["study"]) for s in saved]
        generations = [st["pipeline"]["results"][0]["generation"] for st in studies
                       if st["pipeline"] and st["pipeline"]["results"][0]]
        # The first generation reaches the disk at once and the end always; in between at most one save every
        # SAVE_PERIOD s (these 15 generations take well under 2 s).
        assert generations[0] == 1 and generations[-1] == 15
        assert len(saved) <= 4, generations
        r = load_session(path).study.result("subtask2")
        assert r.status == "complete" and r.generation == 15
        member = next(i for i in range(r.pop) if i != r.picked)
        saved.clear()
        studio.pick("subtask2", member, None)
        assert saved and saved[-1]["study"]["shown"]["subtask2"] == member
        back = load_session(path)
        assert back.study.shown_member("subtask2") == member
        np.testing.assert_array_equal(back.view.design.params[0], r.X[member])
    finally:
        studio.close()


def test_a_second_run_click_within_the_double_click_time_starts_nothing() -> None:
    import studio.app as app

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        tiny(studio.session.study, "subtask2", pop=8, gens=1)
        with studio.session.lock:
            studio.session.study.next_stage = "subtask2"
        assert studio.start_run()
        studio.runner.join(30)
        assert not studio.start_run()  # the run already finished: still the same double click
        assert studio.session.study.branches == []
    finally:
        studio.close()


def test_a_run_click_for_another_stage_right_after_a_run_is_a_new_run() -> None:
    import studio.app as app

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        tiny(studio.session.study, "subtask2", pop=8, gens=1)
        tiny(studio.session.study, "subtask3", pop=8, gens=1)
        with studio.session.lock:
            studio.session.study.next_stage = "subtask3"
        assert studio.start_run()
        studio.runner.join(30)
        with studio.session.lock:
            studio.session.study.next_stage = "subtask2"  # the designer chose another stage, within a second
        assert studio.start_run()
        studio.runner.join(30)
        assert studio.session.study.result("subtask2") is not None
    finally:
        studio.close()


def test_clicking_a_candidate_sphere_in_the_scene_picks_it() -> None:
    import studio.app as app
    from studio.candidates import candidates

    studio = app.Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        tiny(studio.session.study, "subtask2", pop=40, gens=20)
        with studio.session.lock:
            studio.session.study.next_stage = "subtask2"
        studio.start_run()
        studio.runner.join(60)
        r = studio.session.study.result("subtask2")
        shown = {c.member for c in candidates(r) if c.kind in ("knee", "best")}
        assert set(r.front) - shown  # front members that are neither a knee nor a best (below)
        # The run's end puts its pick into the editor (design edits are refused while it runs: not this one).
        end = studio.session.study.shown_member("subtask2")
        assert end is not None
        np.testing.assert_array_equal(studio.session.view.design.params[0], r.X[end])
        # One clickable sphere per knee / best member, and the pick's (the automatic pick, best h_s among the members
        # with I <= 1, need not be a knee or a best).
        assert set(studio.inset._spheres) == shown | {end}
        member = next(m for m in shown if m != r.picked)

        class Click:
            client = None

        where = {m: tuple(h.position) for m, h in studio.inset._spheres.items()}
        studio.inset._clicked(member)(Click())  # type: ignore[arg-type]
        assert studio.session.study.shown_member("subtask2") == member
        np.testing.assert_array_equal(studio.session.view.design.params[0], r.X[member])
        # The picked design lays the views out again (its leg view is a little larger or smaller): the spheres
        # stay put, so the next click lands on what the designer aimed at (they moved 1-2 % of the inset).
        now = {m: tuple(h.position) for m, h in studio.inset._spheres.items()}
        assert set(now) >= shown and all(now[m] == where[m] for m in shown)  # the pick's own sphere may go
        assert not np.array_equal(studio.scene.frames.composition.inset, studio._inset_box)
        studio.refresh(fit_camera=True)  # the camera frames the views again: the inset follows the layout
        np.testing.assert_array_equal(studio._inset_box, studio.scene.frames.composition.inset)
        assert {m: tuple(h.position) for m, h in studio.inset._spheres.items()} != where
        # A plain front member picked with the slider or the dropdown gets a red sphere of its own (it stayed a grey
        # dot: nothing in the scene said which member was shown).
        plain = next(m for m in r.front if m not in shown)
        studio.pick("subtask2", plain, None)
        assert set(studio.inset._spheres) == shown | {plain}
        assert tuple(studio.inset._spheres[plain].color) == palette.FOOT
        studio.pick("subtask2", member, None)
        assert set(studio.inset._spheres) == shown
    finally:
        studio.close()


def test_the_inset_stays_put_for_a_small_relayout_that_leaves_the_leg_view_room() -> None:
    from types import SimpleNamespace

    import studio.app as app

    def placed(old: list[float], new: list[float], text_mm: float) -> list[float]:
        me = SimpleNamespace(_inset_box=np.array(old))
        frames = SimpleNamespace(composition=SimpleNamespace(inset=np.array(new)), text_height=text_mm * 1e-3)
        return list(app.Studio._steady_inset(me, frames))  # type: ignore[arg-type]

    old = [100.0, 0.0, 200.0, 100.0]  # a 100 mm square; 3 % of it is 3 mm
    assert placed(old, [98.0, -2.5, 197.5, 97.0], 2.0) == old  # a pick's 1-3 % move: kept
    assert placed(old, [101.5, 0.0, 201.5, 100.0], 2.0) == old  # the leg view grew by less than a text height
    assert placed(old, [102.5, 0.0, 202.5, 100.0], 2.0) == [102.5, 0.0, 202.5, 100.0]  # more: it must move
    assert placed(old, [100.0, 3.5, 200.0, 103.5], 2.0) == [100.0, 3.5, 200.0, 103.5]  # beyond 3 %
    assert placed(old, [96.5, 0.0, 196.5, 100.0], 9.0) == [96.5, 0.0, 196.5, 100.0]


def test_a_short_run_reads_in_hundredths_of_a_second_not_as_zero() -> None:
    # A 60 x 25 subtask 2 takes ~0.05 s; the status said "complete (0.0 s)", which reads as if nothing ran.
    from studio.panels.stages import seconds

    assert [seconds(t) for t in (0.0, 0.004, 0.046, 0.999, 1.0, 12.34)] == \
        ["< 0.01 s", "< 0.01 s", "0.05 s", "1.00 s", "1.0 s", "12.3 s"]


def test_branches_of_one_pipeline_share_their_results_json_and_save_as_before(session: Session) -> None:
    run(session, "subtask1", from_pick=False)
    study = session.study
    study.keep_branch("first")
    tiny(study, "subtask2")
    run(session, "subtask2", from_pick=True)
    study.keep_branch("second")  # subtask 1's same result: an afternoon's branches each parsed a copy of it
    a, b = (br.pipeline["results"] for br in study.branches)
    assert a[0] is b[0] and a[0] == json.loads(study.pipeline.to_json(indent=None))["results"][0]
    study.restore_branch(0)  # a restored pipeline's results are new objects: kept again, the dicts are shared
    study.keep_branch("third")
    assert study.branches[-1].pipeline["results"][0] is a[0]
    loaded = Study.from_dict(json.loads(json.dumps(study.to_dict())), session.view.target)
    assert [br.pipeline for br in loaded.branches] == [br.pipeline for br in study.branches]


def test_the_studio_picks_as_clm_design_does() -> None:
    # The automatic pick: subtask 2's best h_s among the members with I <= 1 (when any) that meet subtask 3's limits;
    # subtask 3's best S (a metric, not an objective) among those with I <= 0.44; the knee if a rule cannot apply.
    from core.optimize.lineage import auto_pick, next_feasible
    from studio.study import studio_pick

    s = Session.default()
    tiny(s.study, "subtask2", pop=30, gens=6)
    run(s, "subtask2", from_pick=False)
    st = s.study
    r = st.result("subtask2")
    plan = SimpleNamespace(pipeline=st.pipeline, index=st.index("subtask2"), stage=find(chain_for(
        s.view.design.mechanism), "subtask2"), spec=st.pipeline.stages[st.index("subtask2")])
    got = studio_pick(r, plan)
    assert r.picked == got  # what the run recorded
    ok = next_feasible(r, st.pipeline.stages[st.index("subtask3")].problem)
    low = ok & (r.metrics["I"] <= 1.0)
    cands = np.flatnonzero(low if low.any() else ok)
    assert len(cands) and low.any()  # the run gives the rule something to narrow
    assert r.metrics["h_s"][got] == r.metrics["h_s"][cands].min()  # the rule, by hand
    assert got == auto_pick(r, "best:h_s", None, st.pipeline.stages[st.index("subtask3")].problem,
                            find(chain_for(s.view.design.mechanism), "subtask2").pick_where)
    # A rule naming a metric the result lacks falls back to the knee, never raises.
    odd = SimpleNamespace(**{**vars(plan), "spec": SimpleNamespace(pick="best:nonesuch", stop_below=None)})
    assert studio_pick(r, odd) == r.choose("knee")


def test_a_stage_keeps_its_metric_pick_rule_for_its_own_problem_only() -> None:
    from studio.chains import stage_spec
    from studio.target import TargetSpec

    s3 = find(chain_for(Session.default().view.design.mechanism), "subtask3")
    assert s3.pick == "best:S"  # S is a metric subtask 3 reports, not one of its objectives
    assert stage_spec(s3, RunSettings("subtask3"), TargetSpec()).pick == "best:S"
    assert stage_spec(s3, RunSettings("subtask2"), TargetSpec()).pick == "knee"  # another problem in the slot


def test_the_rtclms_other_mode_is_the_same_leg_and_keeps_its_stages() -> None:
    # Switching to "RTCLM, auxiliary mode" loaded another preset and sent the leg's stages to a branch: an optimized
    # leg's auxiliary mode (its h4) could not be seen in the studio.
    from core.kinematics.design import Design
    from core.kinematics.mechanisms import get as mechanism
    from core.optimize.problem import make_problem

    s = Session.default()
    s.load_preset("rtclm/case4")
    tiny(s.study, "rtclm1", pop=20, gens=3, seed=1)
    run(s, "rtclm1", from_pick=False)
    pipe, branches = s.study.pipeline, len(s.study.branches)
    primary = s.view.design
    v = s.select_mechanism("rtclm_auxiliary")
    assert v.design.mechanism.name == "rtclm_auxiliary" and (v.design.params == primary.params).all()
    assert v.preset == "rtclm/case4/auxiliary" and v.target == s.undone[-1].view.target
    assert s.study.pipeline is pipe and len(s.study.branches) == branches  # its stages stay
    # What the editor shows in this mode is the h4 the RTCLM stages measure for the same leg.
    h4 = make_problem("rtclm2").evaluate_metrics(Design(mechanism("rtclm_primary"), primary.params))["h4"][0]
    assert np.isfinite(h4) and v.evaluation.h_m[0] == pytest.approx(float(h4), rel=1e-9)
    back = s.select_mechanism("rtclm_primary")
    assert back.preset == "rtclm/case4" and (back.design.params == primary.params).all()
    s.select_mechanism("stephenson1")  # another topology still starts over, keeping the stages as a branch
    assert len(s.study.branches) == branches + 1


def test_a_stage_that_runs_out_of_generations_short_of_its_stop_says_so() -> None:
    # An RTCLM stage that stalled read "Last run: rtclm2 complete" beside an h4 94 mm off its target.
    from studio.study import status_text

    r = rtclm1_run(12, 1)
    assert r.status == "complete" and r.picked is not None and float(r.F[r.picked, 0]) > 0.5
    dh6 = float(r.F[r.picked, 0])
    assert status_text(r).startswith(f"complete — its early stop [0.5] not reached (pick: dh6 {dh6:.3g})")


def test_a_constraint_reads_to_four_digits_and_says_when_that_rounds_it() -> None:
    from core.optimize.problem import Constraint
    from studio.study_view import constraint_text

    labels = {"f2": "f2 = width penalty (mm²)", "h_s": "f4 = h_s (mm)"}
    # A 200 mm leg's sized limits (k = 2/3) read "≤ 2.22222" and "≤ 13.3333".
    assert constraint_text(Constraint("f2", upper=5.0 * (2 / 3) ** 2), labels) == "f2 = width penalty (mm²) ≤ 2.222…"
    assert constraint_text(Constraint("I", upper=20.0 * 2 / 3)) == "I ≤ 13.33…"
    assert constraint_text(Constraint("h_s", upper=6.5), labels) == "f4 = h_s (mm) ≤ 6.5"  # exact: as typed
    assert constraint_text(Constraint("theta1", lower=0.25)) == "theta1 ≥ 0.25"
    assert constraint_text(Constraint("violation", upper=0.0)) == "assembles"


def test_a_branch_of_a_stopped_run_says_it_was_stopped(session: Session) -> None:
    # A rehearsal's Stop at 348/400 made a branch "subtask3 showing #87 by imtcmo", read as a finished run's.
    from studio.study import branch_stages

    run(session, "subtask1", from_pick=False)
    r = session.study.result("subtask1")
    assert "stopped" not in branch_stages([r], {})
    cut = replace(r, status="cancelled", generation=2)
    assert branch_stages([cut], {}).endswith(f"by NSGA-II, stopped at 2/{r.n_gen}")


def test_a_result_smaller_than_its_run_asked_for_says_why() -> None:
    # "55 feasible of 55" at population 60: CMOEMT keeps one member per Das-Dennis weight vector (55 for 3
    # objectives), and nothing on screen said where the other five went.
    from types import SimpleNamespace

    from core.optimize.evolve.weights import simplex_lattice
    from studio.study import population_note

    def result(name: str, asked: int, pop: int) -> SimpleNamespace:
        return SimpleNamespace(settings={"algorithm": {"name": name, "pop_size": asked}}, pop=pop)

    n = len(simplex_lattice(60, 3))
    assert n == 55
    note = population_note(result("cmoemt", 60, n))
    assert note == "55 members, not the 60 asked: CMOEMT keeps one per weight vector"
    assert population_note(result("spea2", 60, 58)) == "58 members, not the 60 asked"
    assert population_note(result("nsga2", 60, 60)) == "" and population_note(SimpleNamespace(settings={}, pop=3)) == ""


def test_a_pick_of_the_rtclm_keeps_the_mode_on_screen() -> None:
    # Rehearsal 7: picking an rtclm2 candidate while the auxiliary mode was shown flipped the editor to the primary
    # mode mid-demo. A stage's member is the same leg: it is shown in the mode on screen; a design file keeps its own.
    s = Session.default("rtclm/clm-case1")
    tiny(s.study, "rtclm1", pop=12, gens=2, seed=1)
    run(s, "rtclm1", from_pick=False)
    r = s.study.result("rtclm1")
    assert r is not None and r.pick(0).mechanism.name == "rtclm_primary"
    s.select_mechanism("rtclm_auxiliary")
    view = s.set_design(r.pick(0), cause="rtclm1's pick")
    assert view.design.mechanism.name == "rtclm_auxiliary"
    np.testing.assert_array_equal(view.design.params, r.pick(0).params)
    filed = s.set_design(r.pick(1), by_hand=True, cause="design leg.json")
    assert filed.design.mechanism.name == "rtclm_primary"


def test_an_rtclm_branch_names_the_heights_and_the_transmission_limit_it_ran_against() -> None:
    # Rehearsal 7: branches run against h4 220, 300, and 300 with mu >= 20 read alike but for the clock.
    s = Session.default("rtclm/clm-case1")
    s.set_heights(h6=55.0, h4=300.0)
    s.study.settings["rtclm1"] = RunSettings("rtclm1", pop_size=8, n_gen=2, seed=2, transmission_min=20)
    run(s, "rtclm1", from_pick=False)
    kept = s.study.keep_branch("test")
    assert kept is not None and " · h6=55, h4=300, mu>=20 (test, " in kept.label
    six = Session.default()
    tiny(six.study, "predesign", pop=8, gens=2)
    run(six, "predesign", from_pick=False)
    other = six.study.keep_branch("test")
    assert other is not None and "h4=" not in other.label and "mu>=" not in other.label
