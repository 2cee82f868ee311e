"""The RTCLM's h6 and h4 targets in the studio: kept in the target, saved with the session, given to its stages,
named on its charts. (Until session 24 the studio's RTCLM stages always ran case 1's 50 / 220 mm.)"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from studio.chains import RunSettings, build_problem, takes_heights
from studio.charts import target_text
from studio.session_file import load_session
from studio.state import Session, preset_target
from studio.target import Curve, TargetSpec


def test_the_heights_round_trip_and_a_six_bars_target_is_written_as_before() -> None:
    t = TargetSpec(h6=60.0, h4=260.0)
    assert TargetSpec.from_dict(json.loads(json.dumps(t.to_dict()))) == t
    assert set(TargetSpec().to_dict()) == {"L", "H", "T"}  # the defaults (case 1) are not written
    assert TargetSpec.from_dict({"L": 300, "H": 100, "T": 2}) == TargetSpec()  # an older session: case 1's
    for bad, why in (({"h4": -5.0}, "target h4 must be a positive number (mm), got -5.0"),
                     ({"h6": "50"}, "target h6 must be a positive number (mm), got '50'"),
                     ({"h5": 1.0}, "unknown target key 'h5'")):
        with pytest.raises(ValueError, match=why.replace("(", "\\(").replace(")", "\\)")):
            TargetSpec.from_dict({"L": 300, "H": 100, "T": 2, **bad})


def test_a_curve_upload_and_the_way_back_keep_the_heights() -> None:
    t = TargetSpec(h6=55.0, h4=240.0)
    curve = Curve.from_target(TargetSpec(length=200.0).target())
    up = t.with_curve(curve)
    assert (up.h6, up.h4, up.origin) == (55.0, 240.0, "uploaded")
    s = Session.default("rtclm/case1")
    s.set_heights(h6=55.0, h4=240.0)
    s.set_curve(curve)
    s.set_curve(None)
    assert (s.view.target.h6, s.view.target.h4, s.view.target.curve) == (55.0, 240.0, None)
    s.set_target(length=280.0)  # editing the cycloid leaves the heights alone
    assert (s.view.target.h6, s.view.target.h4) == (55.0, 240.0)
    with pytest.raises(ValueError, match="target h4 must be a positive number"):
        s.set_heights(h4=0.0)
    assert s.view.target.h4 == 240.0


def test_the_rtclm_problems_get_the_heights_and_the_others_the_curve() -> None:
    t = TargetSpec(h6=60.0, h4=260.0)
    assert takes_heights("rtclm1") and takes_heights("rtclm2") and not takes_heights("subtask2")
    for name in ("rtclm1", "rtclm2"):
        p = build_problem(name, t)
        assert (p.options["h6_target"], p.options["h4_target"]) == (60.0, 260.0)
    assert "h6_target" not in build_problem("subtask2", t).options
    settings = {"problem": {"name": "rtclm2", "options": build_problem("rtclm2", t).options}}
    assert target_text(settings) == "h6=60 mm, h4=260 mm"


def test_a_case_preset_brings_its_own_h4_unless_the_designer_set_one() -> None:
    assert preset_target("rtclm/case3").h4 == 260.0 and preset_target("rtclm/case5").h4 == 300.0
    assert preset_target("stephenson1/X3").h4 == 220.0
    s = Session.default()
    s.load_preset("rtclm/case4")
    assert s.view.target.h4 == 280.0
    assert Session.default("rtclm/case4").view.target.h4 == 280.0
    s.load_preset("rtclm/case2")  # another case: its h4
    assert s.view.target.h4 == 240.0
    s.set_heights(h4=233.0)
    s.load_preset("rtclm/case5")  # set by hand: it stays
    assert s.view.target.h4 == 233.0


def test_the_metrics_name_the_modes_height_and_how_far_it_is_from_its_target() -> None:
    s = Session.default("rtclm/case4")
    row = next(r for r in s.view.rows if r.key == "h_m")
    assert row.label == "h6 (crossing height hₘ)" and f"off by {abs(row.value - 50.0):.3g} mm" in row.note
    s.select_mechanism("rtclm_auxiliary")
    row = next(r for r in s.view.rows if r.key == "h_m")
    assert row.label.startswith("h4") and "target 280 mm" in row.note
    assert next(r for r in Session.default().view.rows if r.key == "h_m").label == "Crossing height hₘ"


def test_the_stages_run_to_the_heights_set_and_the_session_keeps_them(tmp_path: Path) -> None:
    from studio.app import Studio

    path = tmp_path / "session.json"
    s = Studio(Session.default("rtclm/case1"), host="127.0.0.1", port=0, session_path=path)
    try:
        s.session.set_playing(False)
        s.session.set_heights(h6=60.0, h4=260.0)
        with s.session.lock:
            st = s.session.study
            st.next_stage, st.from_pick = "rtclm1", False
            # The chain's population (100): at 40 x 30, 3 of 8 seeds stalled far from h6 once the stage held the
            # ground clearance too (session 30); at 100 every seed reached it within 33 generations.
            st.settings["rtclm1"] = replace(RunSettings("rtclm1"), pop_size=100, n_gen=40, seed=3)
        s.start_run()
        s.runner.join(600)
        r = s.session.study.result("rtclm1")
        assert r is not None and r.picked is not None
        # The objective is |h6 - 60|: the pick's h6 is that far from 60, not from case 1's 50.
        h6, dh6 = float(r.metrics["h6"][r.picked]), float(r.metrics["dh6"][r.picked])
        assert dh6 == pytest.approx(abs(h6 - 60.0), abs=1e-6) and dh6 < 5.0
        s.autosave()
    finally:
        s.close()
    data = json.loads(path.read_text())
    assert (data["target"]["h6"], data["target"]["h4"]) == (60.0, 260.0)
    back = load_session(path)
    assert (back.view.target.h6, back.view.target.h4) == (60.0, 260.0)


def test_the_heights_follow_the_rtclm_presets_from_anywhere_and_a_typed_h6_stays() -> None:
    # From a six-bar with an uploaded curve, rtclm/case3 kept case 1's 220 mm; the other mode's preset reset h6.
    s = Session.default()
    s.set_curve(Curve.from_target(TargetSpec(length=200.0).target()))
    s.load_preset("rtclm/case3")
    assert s.view.target.h4 == 260.0 and s.view.target.curve is not None
    s.load_preset("rtclm/case4")
    s.set_heights(h6=60.0)
    s.load_preset("rtclm/case4/auxiliary")
    assert (s.view.target.h6, s.view.target.h4) == (60.0, 280.0)


def test_what_changed_since_a_run_is_said_where_the_stages_look() -> None:
    now = TargetSpec(h4=260.0)
    assert now.changed_from(TargetSpec(), rtclm=True) == "h6 = 50 mm (primary mode), h4 = 220 mm (auxiliary mode)"
    assert now.changed_from(TargetSpec(), rtclm=False) == ""  # a six-bar's stages do not look at the heights
    assert now.changed_from(TargetSpec(length=280.0), rtclm=False).startswith("compound cycloid L = 280 mm")
    # Typing the paper's cycloid back makes it the paper's again, whatever heights the target carries.
    s = Session.default()
    s.set_curve(Curve.from_target(TargetSpec(length=200.0).target()))
    s.load_preset("rtclm/case3")
    s.select_mechanism("stephenson1")
    s.set_target(length=299.0)
    s.set_target(length=300.0)
    assert s.view.target.origin == "the paper's"


def test_the_rtclms_shape_error_says_its_stages_do_not_use_that_curve() -> None:
    row = next(r for r in Session.default("rtclm/case4").view.rows if r.key == "mse")
    assert "the RTCLM stages do not use" in row.note
    assert "the RTCLM" not in next(r for r in Session.default().view.rows if r.key == "mse").note
