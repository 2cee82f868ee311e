"""The study follows what the user does: an infeasible stage says so, a topology switch starts a new pipeline, a
restored branch brings its design back."""

from __future__ import annotations

import numpy as np

from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Stage, StageSpec, make_problem
from studio.state import SESSION_VERSION
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
    # By the problem's own name for it, as the Pick table and the pass-on prompt say it (session 30: the RTCLM's
    # read "order_4 0.00721 > 0" here and "Eq. 30 order t1→t2→t5→t4, auxiliary (rad)" there).
    assert f"f4 = h_s (mm) {h_s:.3g} > 0.01" in text
    assert res.unmet(i) == [f"h_s {h_s:.3g} > 0.01"]  # without labels, the metric's key


def test_a_stage_with_feasible_members_just_says_complete():
    prob = make_problem("subtask3", n_samples=72)
    res = Stage(StageSpec("subtask3", prob, s=0.05, d=5.0, algorithm=AlgorithmSpec("nsga2", 12), n_gen=2,
                          seed=1), X2).run()
    assert res.feasible.any() and status_text(res) == "complete"


def run_stage(s, name: str, from_pick: bool = False):
    """Run stage ``name`` of session ``s`` (8 x 2, seed 3) as the studio's runner runs it; the chain."""
    import threading

    from studio.chains import RunSettings, chain_for, find
    from studio.runner import Runner

    s.study.settings[name] = RunSettings(name, pop_size=8, n_gen=2, seed=3)
    done = threading.Event()
    runner = Runner(s.lock, lambda: s.study, lambda p: None, done.set)
    chain = chain_for(s.view.design.mechanism)
    stage, view = find(chain, name), s.view
    runner.start(lambda st: st.plan(stage, st.settings_for(stage), view.design, view.target, from_pick, chain))
    assert done.wait(60)
    runner.join(10)
    return chain


def session_after_subtask1():
    """A default session whose subtask 1 ran (8 x 2, seed 3) as the studio's runner runs it; and its chain."""
    from studio.state import Session

    s = Session.default()
    return s, run_stage(s, "subtask1")


def test_switching_topology_starts_a_new_pipeline_and_keeps_the_old_as_a_branch():

    from studio.chains import chain_for
    from studio.study_view import study_view

    s, chain = session_after_subtask1()
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


def test_a_branch_restored_on_the_same_mechanism_is_its_own_design_not_the_editors_preset():
    s, _ = session_after_subtask1()
    assert s.view.preset == "stephenson1/X3"
    s.study.keep_branch("by hand")
    s.restore_branch(0)
    assert s.view.design.mechanism.name == "stephenson1" and s.view.preset is None


def test_restoring_a_branch_restores_its_mechanism_and_design_with_the_pipeline():

    import numpy as np


    s, chain = session_after_subtask1()
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


def test_restoring_a_branch_of_another_topology_brings_its_target_back():
    s, _ = session_after_subtask1()
    before = s.view.target
    s.select_mechanism("jansen")
    assert s.view.target.option() != before.option()  # Jansen's own, smaller target
    s.restore_branch(0)
    assert s.view.design.mechanism.name == "stephenson1"
    assert s.view.target.option() == before.option() and s.view.target.curve is None
    np.testing.assert_allclose(s.view.target_design, before.points(len(s.view.target_design)))


def test_a_restored_branch_is_framed_as_a_topology_switch_is():
    # Restored from Watt-I, a Stephenson-I branch was drawn a quarter smaller until the page was reloaded.
    from studio.app import Studio
    from studio.state import Session
    from tests.stage_runs import run_stage

    s = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        s.animator.stop()
        run_stage(s.session, "subtask1", pop=12, gens=2)
        s.session.select_mechanism("watt1")  # keeps the Stephenson-I pipeline as a branch
        s.refresh(fit_camera=True)
        watt = s._fitted.copy()
        s.restore_branch(0, None)
        assert s.session.view.design.mechanism.name == "stephenson1"
        assert np.array_equal(s._fitted, s.scene.frames.composition.bounds) and not np.array_equal(s._fitted, watt)
    finally:
        s.close()


def test_the_camera_frames_the_views_again_when_a_design_outgrows_them():
    from studio.app import Studio
    from studio.state import Session

    s = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        first = s._fitted.copy()
        cam0 = np.array(s.server.initial_camera.position)
        s.session.set_param(s.session.view.design.mechanism.params[0].name,
                            float(s.session.view.design.params[0, 0]) * 1.0001)  # a small edit: no refit
        s.refresh()
        assert np.array_equal(s._fitted, first)
        s.session.select_mechanism("jansen")  # a different size entirely: refit
        s.refresh()
        assert not np.array_equal(s._fitted, first)
        assert not np.allclose(np.array(s.server.initial_camera.position), cam0)
        b = s.scene.frames.composition.bounds
        assert np.array_equal(s._fitted, b)
        # Views that lost a third of their height (a design without a walking view loses the lower row) are framed
        # again: they sat in the top half of an empty page (QA session 38); a tenth less is not.
        x0, y0, x1, y1 = b
        s._fitted = np.array([x0, y0 - 0.5 * (y1 - y0), x1, y1])
        assert s._outgrown()
        s._fitted = np.array([x0, y0 - 0.1 * (y1 - y0), x1, y1])
        assert not s._outgrown()
    finally:
        s.close()


def test_each_mechanism_comes_with_a_target_of_its_own_size_and_says_so():
    from studio.state import Session
    from studio.target import Curve

    s = Session.default()
    assert "(the paper's)" not in s.view.target.label()  # the opening session: the plain default
    for name in ("jansen", "klann"):
        s.select_mechanism(name)
        t = s.view.target
        pts = s.view.solution.point[0]
        span = pts.max(axis=0) - pts.min(axis=0)
        assert (t.length, t.height) == (round(float(span[0])), round(float(span[1])))
        assert f"scaled to the {name} path" in t.label()
        mse = next(r.value for r in s.view.rows if r.key == "mse")
        assert mse < 0.2 * max(t.length, t.height)  # was 206 and 111 mm against the 300 x 100 mm cycloid
    s.select_mechanism("rtclm_primary")
    assert "the RTCLM stages optimize h6 and h4, not this curve" in s.view.target.label()
    s.select_mechanism("stephenson1")
    assert s.view.target.label().endswith("(the paper's)") and s.view.target.length == 300.0
    # An uploaded curve is the designer's: it stays when the mechanism changes.
    s.set_curve(Curve("mine.csv", ((0.0, 0.0), (50.0, 0.0), (25.0, 20.0)), None, 2.0))
    s.select_mechanism("jansen")
    assert s.view.target.curve is not None and s.view.target.curve.name == "mine.csv"


def test_the_passed_on_ring_marks_only_what_was_passed_on():

    from studio.panels.pareto import passed_on
    from studio.study_view import study_view

    s, chain = session_after_subtask1()

    def sv():
        return study_view(s.study, s.view.design, chain, s.view.target)

    r = s.study.result("subtask1")
    assert r.picked is not None and passed_on(sv()) is None  # the automatic pick is not "passed on"
    member = next(i for i in range(r.pop) if i != r.picked)
    s.study.use_for_next("subtask1", member, chain)
    assert passed_on(sv()) == member


def test_a_branch_brings_back_the_target_its_stages_ran_against_even_a_hand_edited_one():
    import json

    from studio.state import Session

    s, _ = session_after_subtask1()
    ran = s.view.target
    s.set_target(length=280.0, height=90.0)  # edited after the run: the branch keeps what the run used
    s.select_mechanism("jansen")
    s.set_target(length=50.0)
    assert s.study.branches[0].target == ran.to_dict()
    # ... through a session file too
    s = Session.from_dict(json.loads(json.dumps(s.to_dict())))
    s.restore_branch(0)
    assert s.view.design.mechanism.name == "stephenson1"
    assert s.view.target.option() == ran.option()
    assert s.study.target is not None and s.study.target.option() == ran.option()
    # The Jansen study had no result, so no branch of it was kept; back to Jansen and the Stephenson
    # pipeline is a branch again, with its target.
    s.select_mechanism("jansen")
    assert len(s.study.branches) == 1 and s.study.branches[0].target == ran.to_dict()


def test_a_restored_branch_offers_the_stage_and_shows_the_members_it_was_left_with():
    import json

    from studio.state import Session

    s, chain = session_after_subtask1()
    assert (s.study.next_stage, s.study.from_pick) == ("subtask1", False)  # as a run leaves it: run it again
    s.select_mechanism("jansen")
    s.restore_branch(0)
    assert (s.study.next_stage, s.study.from_pick) == ("subtask1", False)
    # Member 5 shown, member 2 passed on ("Use for next stage"): the branch brings back both.
    s.study.show("subtask1", 5)
    s.study.use_for_next("subtask1", 2, chain)
    s.study.show("subtask1", 5)
    s.select_mechanism("jansen")
    assert s.study.next_stage is None and s.study.shown == {}
    s = Session.from_dict(json.loads(json.dumps(s.to_dict())))  # through a session file
    s.restore_branch(0)
    assert (s.study.next_stage, s.study.from_pick) == ("subtask2", True)
    assert s.study.shown == {"subtask1": 5} and s.study.pipeline.lineage[-1].picked == 2
    np.testing.assert_allclose(s.view.design.params[0], s.study.pipeline.lineage[-1].X[5])  # the editor showed 5


def test_a_malformed_branch_state_is_refused_with_where_and_what():
    import json

    import pytest

    from studio.state import Session

    s, chain = session_after_subtask1()
    s.select_mechanism("jansen")
    data = json.loads(json.dumps(s.to_dict()))
    branch = data["study"]["branches"][0]
    for key, value, message in (("target", {"L": -1.0, "H": 100.0, "T": 2.0}, "branch 1 target: target length"),
                                ("shown", {"subtask1": "five"}, "branch 1 shown must map stage names"),
                                ("next_stage", 3, "next_stage")):
        bad = json.loads(json.dumps(data))
        bad["study"]["branches"][0] = {**branch, key: value}
        with pytest.raises(ValueError, match=message):
            Session.from_dict(bad)
    bad = json.loads(json.dumps(data))
    bad["study"]["target"] = {"L": 300.0, "H": 0.0, "T": 2.0}
    with pytest.raises(ValueError, match="study target: target height"):
        Session.from_dict(bad)


def test_a_pipeline_run_against_two_uploaded_curves_opens_where_neither_is_stored(tmp_path, monkeypatch):
    import json

    from studio import study_targets, target
    from studio.state import Session
    from studio.target import Curve

    def ellipse(a: float) -> Curve:
        t = np.arange(40) / 40
        pts = tuple((150.0 + a * np.cos(2 * np.pi * u), -50.0 + 50.0 * np.sin(2 * np.pi * u)) for u in t)
        return Curve(f"ellipse{a:g}.csv", pts, None, 2.0)

    s = Session.default()
    s.set_curve(ellipse(150.0))
    run_stage(s, "subtask1")
    s.set_curve(ellipse(140.0))
    run_stage(s, "subtask2", from_pick=True)  # the pipeline's stages ran against two curves
    s.set_curve(ellipse(130.0))  # and the editor holds a third
    s.select_mechanism("jansen")  # the pipeline becomes a branch (its target: the latest run's curve)
    data = json.loads(json.dumps(s.to_dict()))
    curves = data["study"]["curves"]
    assert data["version"] == SESSION_VERSION == 6  # a format change bumps both, on purpose
    assert {c["points"][0][0] for c in curves.values()} == {300.0, 290.0}  # both stages' curves travel with it
    # Another machine: an empty target store.
    monkeypatch.setattr(target, "CURVE_DIR", tmp_path / "store")
    monkeypatch.setattr(study_targets, "CURVE_DIR", tmp_path / "store")
    back = Session.from_dict(data)
    back.restore_branch(0)
    assert back.view.target.curve is not None and back.view.target.curve.name == "ellipse140.csv"
    assert [r.name for r in back.study.pipeline.lineage] == ["subtask1", "subtask2"]


def test_restoring_a_branch_without_results_starts_afresh():
    from studio.study import Branch

    s, chain = session_after_subtask1()
    s.study.show("subtask1", 2)
    empty = json_pipeline_without_results(s)
    s.study.branches.append(Branch("empty", empty))
    s.study.restore_branch(0)
    assert (s.study.shown, s.study.next_stage, s.study.from_pick) == ({}, None, False)


def json_pipeline_without_results(s):
    import json

    data = json.loads(s.study.pipeline.to_json(indent=None))
    data["results"] = [None] * len(data["results"])
    data["picks"] = [None] * len(data.get("picks", data["results"]))
    return data


def test_curves_a_session_carries_are_read_once_and_written_only_for_a_file_that_passes(tmp_path, monkeypatch):
    import json

    import pytest

    from studio import study_targets, target
    from studio.state import Session
    from studio.target import Curve

    t = np.arange(40) / 40
    s = Session.default()
    s.set_curve(Curve("c.csv", tuple((150.0 + 150.0 * np.cos(2 * np.pi * u), 50.0 * np.sin(2 * np.pi * u))
                                      for u in t), None, 2.0))
    run_stage(s, "subtask1")
    s.select_mechanism("jansen")
    data = json.loads(json.dumps(s.to_dict()))
    branch = data["study"]["branches"][0]
    data["study"]["branches"] = [{**branch, "label": f"b{j}"} for j in range(30)]  # 30 branches, one curve
    store = tmp_path / "store"
    monkeypatch.setattr(target, "CURVE_DIR", store)
    monkeypatch.setattr(study_targets, "CURVE_DIR", store)
    reads = []
    from_dict = Curve.from_dict
    monkeypatch.setattr(Curve, "from_dict", staticmethod(lambda d: reads.append(1) or from_dict(d)))
    back = Session.from_dict(data)
    assert len(back.study.branches) == 30 and len(reads) <= 3  # the table's curve and the session's own
    # A file refused for anything else writes nothing to the store.
    for f in store.iterdir():
        f.unlink()
    bad = json.loads(json.dumps(data))
    bad["study"]["shown"] = {"subtask1": "x"}
    with pytest.raises(ValueError, match="study shown"):
        Session.from_dict(bad)
    assert not any(store.iterdir())
    # A store that cannot be written is a clear error, not an OSError.
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setattr(target, "CURVE_DIR", blocker / "targets")
    with pytest.raises(ValueError, match="cannot write the session's target curves"):
        Session.from_dict(data)
    # A curve of too many points is refused.
    huge = json.loads(json.dumps(data))
    key = next(iter(huge["study"]["curves"]))
    huge["study"]["curves"][key]["points"] = [[float(i), 0.0] for i in range(target.MAX_CURVE_POINTS + 1)]
    with pytest.raises(ValueError, match="too many"):
        Session.from_dict(huge)


def test_an_edit_goes_to_the_stage_the_fields_show_while_the_stage_dropdown_lags():
    # A refresh that began before a stage change sets the Stage dropdown back to the old stage until the next
    # refresh; a Population typed in between went to the old stage while the page showed it on the new one (the
    # browser test's 'subtask2 settings did not reach the server': the page 8, the server 40).
    from studio.app import Studio
    from studio.panels._inputs import set_value
    from studio.state import Session

    s = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        chain = s.chain()
        first, shown = chain[0], next(c for c in chain if c.name == "subtask2")
        with s.session.lock:
            s.session.study.next_stage = shown.name
            s.session.study.touch()
        s.refresh()
        field = s.stages.pop_size
        assert field.handle.value == str(s.session.study.settings_for(shown).pop_size)
        before = s.session.study.settings_for(first)
        set_value(s.stages.stage, first.title)  # the stale refresh's dropdown
        field.handle._impl.value = "8"  # the designer's text reaches the server
        field.arrived("8")
        field.edit(None)  # type: ignore[arg-type]
        assert s.session.study.settings_for(shown).pop_size == 8
        assert s.session.study.settings_for(first) == before
        assert s.stages._getter("pop_size")() == 8.0
    finally:
        s.close()



def test_the_pick_panel_holds_the_result_its_labels_were_drawn_from():
    # During a run the live result is replaced four times a second. The panel keyed its last drawing on id(result)
    # only: once that result was freed, a later one could take its id, and its labels (objective values) were never
    # redrawn (the key matched) while the Pareto chart showed the later front. Holding the result keeps its id.
    import dataclasses
    import gc
    import weakref

    from studio.app import Studio
    from studio.candidates import candidates
    from studio.state import Session
    from studio.study_view import study_view

    s = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        chain = run_stage(s.session, "subtask1")
        base = study_view(s.session.study, s.session.view.design, chain, s.session.view.target)
        r = base.result("subtask1")
        k = base.names.index("subtask1")

        def view(shift: float):
            other = dataclasses.replace(r, F=r.F + shift)
            return dataclasses.replace(base, results=(*base.results[:k], other, *base.results[k + 1:])), other

        sv, first = view(1.0)
        s.pick_panel.show(sv)
        drawn = weakref.ref(first)
        del sv, first
        gc.collect()
        assert drawn() is not None  # its id cannot go to another result while the panel's key names it
        sv, later = view(2.0)
        s.pick_panel.show(sv)
        want = tuple(c.label for c in candidates(later))
        assert tuple(s.pick_panel.candidate.options)[:len(want)] == want
        assert drawn() is None  # and it is let go once a later one is drawn
    finally:
        s.close()


def test_design_edits_are_refused_while_a_stage_runs_since_its_pick_replaces_the_design():
    # A parameter typed or a preset chosen mid-run was applied, then silently replaced by the run's pick at its end.
    from dataclasses import replace

    import pytest

    from studio.state import Session

    s = Session.default()
    before = s.view
    s.study.status = replace(s.study.status, state="running", stage="subtask2")
    edits = {"parameter": lambda: s.set_param("r4", 129.33), "preset": lambda: s.load_preset("stephenson1/X1"),
             "reset": s.reset_to_preset, "design": lambda: s.set_design(get("stephenson1/X1").design())}
    for what, edit in edits.items():
        with pytest.raises(ValueError, match="^a stage is running, and its pick replaces the design when it ends; "
                                             "stop it or wait before editing the design$"):
            edit()
        assert s.view is before, what
    with pytest.raises(ValueError, match="before switching the mechanism$"):
        s.select_mechanism("jansen")
    assert s.view is before
    s.set_target(length=310.0)  # the target is not the design: it may change
    assert s.view.design is before.design and s.view.target.length == 310.0
    s.study.status = replace(s.study.status, state="idle")
    assert s.set_param("r4", 129.33).design.named(0)["r4"] == 129.33


def test_a_chart_names_an_uploaded_curve_target_never_its_path_in_the_servers_cache():
    # The Pareto chart's title printed "target /root/.cache/clm-studio/targets/target-7b54....csv" for every curve
    # target (each non-paper topology's and every upload's): the server's home folder, and a line that ran off the
    # chart.
    from studio.charts import target_text
    from studio.panels.pareto import pareto_figure
    from studio.state import Session
    from studio.study_view import study_view
    from studio.target import CURVE_DIR, Curve

    t = np.arange(40) / 40
    pts = tuple((150.0 + 150.0 * np.cos(2 * np.pi * u), -50.0 + 50.0 * np.sin(2 * np.pi * u)) for u in t)
    s = Session.default()
    s.set_curve(Curve("my leg.csv", pts, None, 2.0))
    chain = run_stage(s, "subtask1")
    sv = study_view(s.study, s.view.design, chain, s.view.target)
    title = pareto_figure(sv).layout.title.text
    assert title.endswith(" · target curve my leg.csv") and str(CURVE_DIR) not in title
    # Without the upload's name (an older stage's curve, a config's file): the file name, not its folders.
    settings = sv.result("subtask1").settings
    assert target_text(settings).startswith("curve target-") and "/" not in target_text(settings)
    cycloid = {"problem": {"options": {"target": "cycloid:L=300.0,H=100.0,T=2.0"}}}
    assert target_text(cycloid) == "cycloid L=300 mm, H=100 mm, T=2 s"  # units: it read "L=300.0"
    folder = {"problem": {"options": {"target": "cycloids/leg.csv"}}}  # a file, though it starts with "cycloid"
    assert target_text(folder) == "curve leg.csv"
    assert target_text(folder, {"cycloids/leg.csv": "curve <b>x</b>.csv"}) == "curve &lt;b&gt;x&lt;/b&gt;.csv"
