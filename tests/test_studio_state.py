"""Studio session state: opening design, validated edits, playback, session files, thread safety."""

from __future__ import annotations

import json
import math
import re
import threading
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from core.analysis.features import FEATURE_NAMES
from core.kinematics import presets
from core.kinematics.solver import solve
from studio.metrics import feature_labels, metrics_html, min_transmission_angle, shape_error
from studio.state import (
    MAX_SPEED,
    Playback,
    Session,
    build_view,
    check_value,
    opening_preset,
    preset_label,
    presets_for,
)
from studio.target import TargetSpec

X3 = "stephenson1/X3"


@pytest.fixture(scope="module")
def x3_session_data() -> dict:
    return Session.default().to_dict()


@pytest.fixture
def session(x3_session_data: dict) -> Session:
    return Session.from_dict(x3_session_data)


def rows(view) -> dict:
    return {r.key: r for r in view.rows}


# Opening state ------------------------------------------------------------------------------


def test_default_session_is_the_paper_x3_design_animating_against_the_paper_target(session: Session) -> None:
    view = session.view
    assert view.preset == X3
    assert view.design.mechanism.name == "stephenson1"
    np.testing.assert_array_equal(view.design.params[0], presets.get(X3).values)
    assert view.target == TargetSpec(300.0, 100.0, 2.0)
    assert session.playback.playing
    assert view.edited == ()
    assert view.solution.joints is not None and view.solution.joints.shape == (1, 360, 8, 2)


# Paper Appendix B-1 MSE (mm) of the Stephenson-I stages; spec allows 0.6 mm (one-sample vs exact).
@pytest.mark.parametrize(("row", "paper_mse"), [("X0", 9.91), ("X1", 5.09), ("X2", 4.80), ("X3", 3.97)])
def test_shape_error_row_reproduces_the_papers_mse(row: str, paper_mse: float) -> None:
    view = Session.default(f"stephenson1/{row}").view
    assert abs(rows(view)["mse"].value - paper_mse) < 0.6


def test_x1_width_and_apex_rows_meet_the_papers_subtask1_objectives() -> None:
    # Paper §3.2.3: X1 has f2 = (l - 300)^2 and f3 = (y_min + 100)^2 both below 0.01 mm^2.
    r = rows(Session.default("stephenson1/X1").view)
    assert (r["width"].value - 300.0) ** 2 < 0.01
    assert (r["y_min"].value + 100.0) ** 2 < 0.01


def test_every_registered_preset_opens_and_reports_whether_it_assembles() -> None:
    for name in presets.PRESETS:
        view = Session.default(name).view
        assert view.preset == name
        assert preset_label(name) in {preset_label(n) for n in presets_for(view.design.mechanism.name)}
        assert view.assembles == (view.solution.violation[0] == 0.0)
        if not view.assembles:
            assert rows(view)["feasible"].value is False and rows(view)["why"].text() != "-"


@pytest.mark.parametrize("name", ["jansen", "klann", "fourbar/chebyshev", "rtclm/case3", "stephenson3/paper"])
def test_a_session_on_a_preset_is_the_one_the_topology_and_preset_dropdowns_load(name: str) -> None:
    # Session.default(name) gave every preset the paper's cycloid and the paper's 25 x 25 mm obstacle on a 450 mm
    # trunk: a Jansen leg read MSE 206 mm through the API and 2.3 mm in the studio (session 38's note).
    shown = Session.default()
    shown.load_preset(name)
    made = Session.default(name).view
    np.testing.assert_array_equal(made.design.params, shown.view.design.params)
    assert made.walk == shown.view.walk
    # the same target; the paper's mechanisms' target says "the paper's" once switched to from another mechanism
    assert replace(made.target, origin="") == replace(shown.view.target, origin="")
    assert made.target.origin == shown.view.target.origin or made.target.origin == ""
    assert rows(made)["mse"].text() == rows(shown.view)["mse"].text()


def test_the_gait_numbers_of_a_path_that_does_not_walk_are_marked_not_defined() -> None:
    # Rehearsal 7: the paper's RTCLM case 4 assembles but does not walk, and printed I = 387 mm/s as a property of
    # the leg. Marked (dimmed, the reason first in the tooltip) exactly when it assembles and does not walk.
    # Listed here, not read from studio.metrics: a key missing there must fail this test (review of session 31: the
    # "Gait constraints" verdict, computed from these, was not dimmed).
    gait_keys = {"h_s", "S", "S_paper", "I", "theta1", "theta2", "l_s", "h_m", "h_bar", "psi2", "psi4", "gait"}
    seen = set()
    for name in presets.PRESETS:
        view = Session.default(name).view
        rs = rows(view)
        walks = bool(rs["feasible"].value)
        marked = {k for k, r in rs.items() if r.undefined}
        expected = set() if walks or not view.assembles else {k for k in gait_keys if k in rs}
        if name.startswith("rtclm"):  # its shape error is against a curve its stages do not use
            expected.add("mse")
        if view.solution.violation[0] > 0:  # no worst transmission angle where it does not turn fully ("NaN" read)
            expected.add("mu_min")
            assert rs["mu_min"].text() == "-"
        assert marked == expected, name
        table = metrics_html(tuple(rs.values()))
        assert table.count('data-undefined="1"') == len({k for k in marked if not rs[k].warn})
        seen.add(bool(marked))
    assert seen == {True, False}  # both kinds of preset were met


# Target --------------------------------------------------------------------------------------


@given(length=st.floats(10, 1000), height=st.floats(1, 500), n_quarter=st.integers(2, 200))
@settings(max_examples=40, deadline=None)
def test_compound_cycloid_passes_through_its_closed_form_points(length: float, height: float, n_quarter: int) -> None:
    n = 4 * n_quarter
    p = TargetSpec(length, height).points(n)
    np.testing.assert_allclose(p[0], [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(p[n // 4], [length / 2, -height], rtol=1e-12, atol=1e-9)  # arch apex
    np.testing.assert_allclose(p[n // 2], [length, 0.0], rtol=1e-12, atol=1e-9)  # end of the arch
    np.testing.assert_allclose(p[3 * n // 4], [length / 2, 0.0], rtol=1e-12, atol=1e-9)  # return line, halfway
    assert p[:, 1].min() >= -height - 1e-9 and p[:, 1].max() <= 1e-9


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, "300", True])
def test_target_rejects_non_positive_or_non_numbers(bad: object) -> None:
    with pytest.raises(ValueError, match="length"):
        TargetSpec(length=bad)  # type: ignore[arg-type]


def test_target_in_the_leg_frame_is_the_output_stage_image_of_the_design_frame_target(session: Session) -> None:
    view = session.view
    np.testing.assert_allclose(view.target_leg, view.design.output.apply(view.target_design))
    # The paper's pantograph (k = -1 about (150, 0)) turns the hanging arch upward.
    assert view.target_leg[:, 1].max() == pytest.approx(100.0)


def test_changing_the_target_re_evaluates_the_shape_error(session: Session) -> None:
    before = rows(session.view)["mse"].value
    view = session.set_target(height=80.0)
    assert view.target.height == 80.0
    # Spec §3: the mean distance between sample i of the path and sample i of the target.
    expected = np.linalg.norm(view.solution.point[0] - TargetSpec(300, 80).points(360), axis=-1).mean()
    assert rows(view)["mse"].value == pytest.approx(expected, rel=1e-9)
    assert rows(view)["mse"].value != before
    with pytest.raises(ValueError):
        session.set_target(period=-2.0)
    assert session.view is view


# Edits ---------------------------------------------------------------------------------------


def test_a_valid_edit_re_solves_and_marks_the_parameter_edited(session: Session) -> None:
    old = session.view
    view = session.set_param("r4", 130.0)
    assert view.values["r4"] == 130.0 and view.edited == ("r4",)
    expected = solve(view.design.mechanism, view.design.params, 360, output=view.design.output, backend="numpy")
    np.testing.assert_allclose(view.solution.point, expected.point, atol=1e-9)
    assert old.values["r4"] == presets.get(X3).values[7]  # the old view is untouched
    assert session.version == 1


# r4 = 500 puts D so far from A that |BD| >= r4 - r1 > r2 + r3: the dyad C can never close.
@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("r4", -5.0, "must be > 0"),
        ("r4", 0.0, "must be > 0"),
        ("r2", math.nan, "finite"),
        ("r2", math.inf, "finite"),
        ("r4", 600.0, "outside its bounds"),
        ("r6", -501.0, "outside its bounds"),
        ("x_a", 1e4, "outside its bounds"),
        ("r4", 1e9, r"r4 = 1e\+09 mm is outside its bounds \["),  # not the file format's "within +-1e+06 mm"
        ("r6", -1e9, r"r6 = -1e\+09 mm is outside its bounds \["),
        ("r4", "12", "must be a number"),
        ("r4", 500.0, "does not assemble"),
        ("nope", 1.0, "no parameter"),
    ],
)
def test_an_invalid_edit_is_refused_with_its_reason_and_changes_nothing(
    session: Session, name: str, value: object, reason: str
) -> None:
    old, version = session.view, session.version
    with pytest.raises(ValueError, match=reason):
        session.set_param(name, value)
    assert session.view is old and session.version == version


def test_angles_are_periodic_not_bounded(session: Session) -> None:
    g = session.view.values["g"]
    p0 = session.view.solution.point.copy()
    view = session.set_param("g", g + 2.0 * math.pi)
    np.testing.assert_allclose(view.solution.point, p0, atol=1e-9)


@given(value=st.floats(allow_nan=True, allow_infinity=True, width=64), name=st.sampled_from(["r1", "r3", "r9", "r12"]))
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_after_any_edit_the_current_design_assembles(session: Session, name: str, value: float) -> None:
    try:
        session.set_param(name, value)
    except ValueError:
        pass
    view = session.view
    assert view.solution.violation[0] == 0.0
    assert np.isfinite(view.solution.joints).all()


def test_a_design_that_does_not_assemble_is_shown_and_can_be_repaired_by_edits(session: Session) -> None:
    broken = presets.get(X3).design().replace(r4=500.0)  # |BD| >= r4 - r1 > r2 + r3
    view = session.set_design(broken, X3)
    assert not view.assembles and view.edited == ("r4",)
    assert not session.set_param("r4", 400.0).assembles  # still broken: accepted, the designer is repairing
    assert session.set_param("r4", 128.0).assembles
    with pytest.raises(ValueError, match="does not assemble"):
        session.set_param("r4", 500.0)  # now it assembles, breaking it again is refused
    assert session.view.values["r4"] == 128.0


def test_check_value_keeps_lengths_positive_and_in_bounds() -> None:
    r1 = presets.get(X3).mechanism.params[4]
    assert check_value(r1, 56) == 56.0 and isinstance(check_value(r1, 56), float)
    assert check_value(r1, r1.lo) == r1.lo and check_value(r1, r1.hi) == r1.hi  # the bounds themselves are in
    for bad in (r1.lo - 1e-9, r1.hi + 1e-9, -1.0):
        with pytest.raises(ValueError, match="r1"):
            check_value(r1, bad)
    # An angle is periodic but still within the design files' +-1e6: a session holding 2e6 rad did not load back.
    b = presets.get(X3).mechanism.params[0]
    assert b.kind == "angle" and check_value(b, 7.5) == 7.5
    with pytest.raises(ValueError, match=r"^b must be within \+-1e\+06 rad, got 2e\+06 rad$"):
        check_value(b, 2e6)


def test_reset_returns_to_the_preset_values(session: Session) -> None:
    session.set_param("r4", 130.0)
    view = session.reset_to_preset()
    np.testing.assert_array_equal(view.design.params[0], presets.get(X3).values)
    assert view.edited == ()


def test_switching_topology_loads_its_first_preset_and_unknown_ones_are_refused(session: Session) -> None:
    view = session.select_mechanism("stephenson3")
    assert view.design.mechanism.name == "stephenson3" and view.preset == presets_for("stephenson3")[0]
    assert session.select_mechanism("stephenson3") is view  # same topology: nothing to do
    with pytest.raises(ValueError, match="unknown mechanism"):
        session.select_mechanism("nine-bar")
    assert session.view is view
    with pytest.raises(ValueError, match="unknown preset"):
        session.load_preset("stephenson1/X9")


@pytest.mark.parametrize("mechanism", ["rtclm_primary", "rtclm_auxiliary"])
def test_a_topology_opens_on_a_preset_that_walks(session: Session, mechanism: str) -> None:
    # Its first preset, a paper row that does not reproduce, opened RTCLM's auxiliary mode on a linkage that jams for
    # 42 % of the cycle (a yellow "does not assemble" warning and NaN metrics) and its primary mode infeasible.
    first = build_view(presets.get(presets_for(mechanism)[0]).design(), None, session.view.target)
    assert not first.assembles or first.evaluation.violation[0] > 0
    view = session.select_mechanism(mechanism)
    assert view.design.mechanism.name == mechanism and view.assembles and view.evaluation.violation[0] == 0
    assert view.preset == opening_preset(mechanism) and opening_preset("stephenson3") == presets_for("stephenson3")[0]


def test_concurrent_edits_leave_a_consistent_view(session: Session) -> None:
    values = [float(v) for v in 128.33 + np.linspace(-1.5, 1.5, 16)]  # all assemble (crank margin 3.24 mm)
    threads = [threading.Thread(target=session.set_param, args=("r4", v)) for v in values]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    view = session.view
    assert view.values["r4"] in values
    assert session.version == len(values)
    fresh = build_view(view.design, view.preset, view.target)
    np.testing.assert_allclose(view.solution.point, fresh.solution.point, atol=1e-12)


# Playback ------------------------------------------------------------------------------------


@given(speed=st.floats(0.1, MAX_SPEED), dt=st.floats(0.0, 0.5), start=st.floats(0.0, 6.28))
@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_playback_turns_the_crank_once_per_target_period(
    session: Session, speed: float, dt: float, start: float
) -> None:
    session.playback = Playback(True, speed, start)
    pb = session.advance(dt)
    expected = (start + 2.0 * math.pi * speed * dt / session.view.target.period) % (2.0 * math.pi)
    assert math.isclose(pb.angle, expected, abs_tol=1e-9) or math.isclose(abs(pb.angle - expected), 2 * math.pi)


def test_paused_playback_holds_and_scrubbing_pauses_and_wraps(session: Session) -> None:
    pb = session.scrub(2.0 * math.pi + 1.0)
    assert not pb.playing and pb.angle == pytest.approx(1.0)
    assert session.advance(1.0).angle == pytest.approx(1.0)
    assert session.set_playing(True).playing
    for bad in (0.0, -1.0, math.nan, MAX_SPEED * 2):
        with pytest.raises(ValueError, match="speed"):
            session.set_speed(bad)


# Session files -------------------------------------------------------------------------------


def test_a_session_whose_design_does_not_assemble_still_loads(x3_session_data: dict) -> None:
    data = json.loads(json.dumps(x3_session_data))
    data["design"]["params"]["r4"] = 500.0
    view = Session.from_dict(data).view
    assert not view.assembles and rows(view)["feasible"].value is False


def test_session_round_trips_through_json(session: Session) -> None:
    session.set_param("r4", 131.5)
    session.set_target(length=280.0)
    session.scrub(1.25)
    data = json.loads(json.dumps(session.to_dict()))
    back = Session.from_dict(data)
    np.testing.assert_array_equal(back.view.design.params, session.view.design.params)
    assert back.view.design.output == session.view.design.output
    assert back.view.preset == X3 and back.view.edited == ("r4",)
    assert back.view.target == session.view.target
    assert back.playback == session.playback


def test_every_parameter_edit_counts_as_edited_the_first_too(session: Session) -> None:
    b = session.view.values["b"]
    view = session.set_param("b", b + 0.01)
    assert view.edited == ("b",)


def oval(session: Session) -> TargetSpec:
    """Set a cycloid by hand (280 x 90 mm, T = 1 s), then upload an oval curve over it; the cycloid set."""
    from studio.target import Curve

    session.set_target(length=280.0, height=90.0, period=1.0)
    before = session.view.target
    session.set_curve(Curve.from_csv(OVAL, "oval.csv"))
    return before


OVAL = ("x,y\n" + "".join(f"{150 + 100 * np.cos(2 * np.pi * a):.6f},{-40 + 40 * np.sin(2 * np.pi * a):.6f}\n"
                          for a in np.arange(40) / 40)).encode()


def test_back_to_the_cycloid_after_a_curve_keeps_the_cycloids_length_and_height(session: Session) -> None:
    from studio.target import Curve

    before = oval(session)
    assert session.view.target.period == 2.0  # the curve's (no times: 2 s)
    back = session.set_curve(None).target
    # The cycloid as it was: its T too, not the curve's 2 s, and still "(set by hand)".
    assert back == before and back.label() == "compound cycloid L = 280 mm, H = 90 mm, T = 1 s (set by hand)"
    session.set_curve(Curve.from_csv(OVAL, "oval.csv"))
    assert session.set_target(height=95.0).target.curve is None  # editing the cycloid returns to it


def test_the_replaced_cycloid_survives_a_saved_session(session: Session, tmp_path) -> None:
    """A session saved while an uploaded curve is the target keeps the cycloid it replaced: after a reload (or a
    Load session), "Back to the compound cycloid" brings back the designer's L, H and T, not the defaults."""
    from studio.session_file import load_session, save_session

    before = oval(session)
    save_session(session, tmp_path / "s.json")
    loaded = load_session(tmp_path / "s.json")
    assert loaded.set_curve(None).target == before
    other = Session(session.view)  # Load session into a running studio takes it over too
    other.restore(load_session(tmp_path / "s.json"))
    assert other.set_curve(None).target == before
    # Without an upload there is nothing to keep, and a bad cycloid is named.
    data = json.loads((tmp_path / "s.json").read_text())
    assert "cycloid" in data and "cycloid" not in loaded.to_dict()
    data["cycloid"] = {"L": -5, "H": 90, "T": 1}
    with pytest.raises(ValueError, match="^cycloid: "):
        Session.from_dict(data)


def test_restoring_a_loaded_session_takes_its_playback_too(session: Session, x3_session_data: dict) -> None:
    data = json.loads(json.dumps(x3_session_data))
    data["playback"] = {"playing": False, "speed": 3.0, "angle": 1.0}
    other = Session.from_dict(data)
    session.restore(other)
    assert session.playback == other.playback and not session.playback.playing and session.playback.speed == 3.0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.update(format="other"), "not a studio session"),
        # A design file (clm presets show) chosen by mistake: it read "format None".
        (lambda d: (d.clear(), d.update(mechanism="stephenson1", params={"r4": 1.0})), "^this is a design file"),
        (lambda d: d.update(version=99), "unsupported session version"),
        (lambda d: d.pop("design"), "no 'design'"),
        (lambda d: d["design"]["params"].update(r4=-1.0), "r4"),
        (lambda d: d["target"].update(H="high"), "height"),
        (lambda d: d.update(playback={"speed": math.nan}), "speed"),
        (lambda d: d.update(playback={"playing": True, "speed": 0.0, "angle": 0.0}), "speed"),
        (lambda d: d.update(playback={"playing": True, "speed": 50.0, "angle": 0.0}), "speed"),
    ],
)
def test_a_malformed_session_is_refused_naming_the_problem(x3_session_data: dict, change, message: str) -> None:
    data = json.loads(json.dumps(x3_session_data))
    change(data)
    with pytest.raises(ValueError, match=message):
        Session.from_dict(data)


# Metric rows ---------------------------------------------------------------------------------


def test_transmission_angle_row_matches_the_angle_measured_from_the_joints(session: Session) -> None:
    view = session.view
    sol = view.solution
    names = sol.joint_names
    worst = math.inf
    for step in view.design.mechanism.steps:
        if type(step).__name__ != "Dyad":
            continue
        x, p, q = (sol.joints[0, :, names.index(n)] for n in (step.name, step.p, step.q))
        u, v = p - x, q - x
        cos = (u * v).sum(-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
        mu = np.arccos(np.clip(cos, -1.0, 1.0))
        worst = min(worst, float(np.minimum(mu, np.pi - mu).min()))
    assert min_transmission_angle(sol) == pytest.approx(worst, abs=1e-9)


def test_metrics_table_has_one_addressable_row_per_metric(session: Session) -> None:
    r = session.view.rows
    html = metrics_html(r)
    assert len({x.key for x in r}) == len(r)
    for x in r:
        assert f'data-key="{x.key}"' in html and f'data-value="{x.text()}"' in html
    wanted = {"feasible", "why", "mse", "h_s", "S", "I", "theta1", "theta2", "l_s", "h_m", "h_bar", "psi2", "psi4"}
    assert wanted <= {x.key for x in r}


def test_the_papers_s_is_shown_beside_ours_for_the_papers_stride_only(session: Session) -> None:
    """Rehearsal 3 compared the studio's S 2.00 % of X3 with Appendix B's 1.93 % and found no h_s / 300 mm, which
    `clm evaluate` prints: the paper's S is a row under S for the paper's 300 mm cycloid, and only then."""
    r = rows(session.view)
    assert r["S_paper"].value == pytest.approx(100 * float(session.view.evaluation.h_s[0]) / 300.0)
    assert r["S_paper"].value < r["S"].value  # X3's stance is shorter than 300 mm
    assert "S_paper" not in rows(session.set_target(length=280.0))
    session.load_preset("rtclm/clm-case1")
    assert "S_paper" not in rows(session.view)  # its target is heights


def test_paper_metric_rows_show_the_evaluation_in_display_units(session: Session) -> None:
    ev, r = session.view.evaluation, rows(session.view)
    for key in ("mse", "h_s", "S", "I", "l_s", "h_m", "h_bar", "width", "y_min"):
        assert r[key].value == pytest.approx(float(getattr(ev, key)[0]))
    for key in ("theta1", "theta2"):
        assert r[key].value == pytest.approx(math.degrees(float(getattr(ev, key)[0])))
        assert r[key].unit == "deg"
    for key in ("psi2", "psi4"):
        assert r[key].value == pytest.approx(100.0 * float(getattr(ev, key)[0]))
        assert r[key].unit == "%"
    assert r["feasible"].value is bool(ev.feasible[0]) and r["why"].text() == "-"


def test_an_unassemblable_design_is_reported_infeasible_with_the_reason() -> None:
    view = build_view(presets.get(X3).design().replace(r4=500.0), X3, TargetSpec())
    r = rows(view)
    assert r["feasible"].value is False and "does not assemble" in r["why"].text()
    assert view.stance is None and view.features == ()


def test_stance_is_the_half_cycle_from_landing_to_take_off_and_holds_the_lowest_point(session: Session) -> None:
    view = session.view
    n, ev = view.n_samples, view.evaluation
    assert view.stance is not None and abs(int(view.stance.sum()) - n // 2) <= 1
    t3 = int(round(ev.times[0, FEATURE_NAMES.index("t3")] * n / ev.period)) % n
    assert view.stance[t3]
    lowest = int(np.argmin(view.solution.leg[0, :, 1]))
    assert view.stance[lowest]


def test_feature_labels_name_every_feature_point_once_merging_coincident_ones(session: Session) -> None:
    labels = feature_labels(session.view.evaluation)
    names = [n for label, _ in labels for n in re.split("[=,]", label)]
    assert sorted(names) == sorted(FEATURE_NAMES)
    points = [xy for _, xy in labels]
    assert len(set(points)) == len(points)


# Session files on disk and the command line ----------------------------------------------------


def test_clm_studio_refuses_a_malformed_session_file_with_one_line(tmp_path, capsys) -> None:
    from studio.serve import main

    bad = tmp_path / "s.json"
    bad.write_text('{"format": "clm-studio-session", "version": 1, "design": {"mechanism": "x"}}')
    assert main(["--session", str(bad), "--port", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clm-studio: error: ") and "s.json" in err[0]
    # A session in a folder that does not exist (lab rehearsal: "[Errno 2] ... 's.json.tmp'").
    missing = tmp_path / "nodir" / "s.json"
    assert main(["--session", str(missing), "--port", "0"]) == 2
    assert capsys.readouterr().err == (f"clm-studio: error: --session {missing}: there is no folder {missing.parent}; "
                                       "create it, or give a session file in a folder that exists\n")
    assert not missing.parent.exists()
    bad.write_text("{not json")
    assert main(["--session", str(bad), "--port", "0"]) == 2
    assert "not JSON" in capsys.readouterr().err
    bad.write_text("\n")  # QA (session 37): "not JSON (Expecting value: line 1 column 1 (char 0))"
    assert main(["--session", str(bad), "--port", "0"]) == 2
    assert capsys.readouterr().err.strip().endswith(f"{bad}: the file is empty")


def test_the_studio_autosaves_its_session_after_every_change(tmp_path) -> None:
    from studio.app import Studio
    from studio.session_file import load_session

    path = tmp_path / "session.json"
    studio = Studio(Session.default(), host="127.0.0.1", port=0, session_path=path)
    try:
        assert load_session(path).view.values == studio.session.view.values
        studio.session.set_param("r4", 129.0)
        studio.refresh()
        assert load_session(path).view.values["r4"] == 129.0
    finally:
        studio.close()


def test_a_session_past_what_a_file_may_hold_keeps_its_last_save_and_the_studio_says_so_once(tmp_path, monkeypatch,
                                                                                              capsys) -> None:
    import studio.session_file as session_file
    from studio.app import Studio
    from studio.session_file import load_session, save_session

    path = tmp_path / "session.json"
    studio = Studio(Session.default(), host="127.0.0.1", port=0, session_path=path)
    try:
        before = path.read_bytes()
        monkeypatch.setattr(session_file, "MAX_SESSION_BYTES", len(before) - 1)  # it would not load again
        with pytest.raises(ValueError, match=r"past the 0 MB a session file may hold, so .* keeps its last save"):
            save_session(studio.session, path)
        studio.session.set_param("r4", 129.0)
        studio.refresh()  # the autosave fails: no exception out of the page's callback
        studio.session.set_param("r4", 130.0)
        studio.refresh()
        assert path.read_bytes() == before  # the last save, which loads
        err = capsys.readouterr().err
        assert err.count("clm-studio: session not saved: the session has grown to") == 1  # said once
        monkeypatch.undo()
        studio.session.set_param("r4", 131.0)
        studio.refresh()
        assert load_session(path).view.values["r4"] == 131.0 and studio._save_error is None
    finally:
        studio.close()


def test_a_session_file_keeps_its_mode_a_read_only_one_is_refused_and_a_failed_write_leaves_no_tmp(tmp_path,
                                                                                                       monkeypatch):
    # QA (session 37): a 600 file became 644, a 444 one was replaced by a writable one, and a full disk left a
    # partial s.json.tmp beside the session.
    import errno
    import os
    import stat

    from studio.session_file import load_session, save_session

    path = tmp_path / "s.json"
    save_session(Session.default(), path)
    path.chmod(0o600)
    save_session(Session.default("fourbar/chebyshev"), path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600 and load_session(path).view.preset == "fourbar/chebyshev"
    path.chmod(0o444)
    with pytest.raises(ValueError, match=r"s.json is read-only \(mode 444\): the studio does not write over it"):
        save_session(Session.default(), path)
    assert load_session(path).view.preset == "fourbar/chebyshev"
    path.chmod(0o644)

    def full(*args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "replace", full)
    with pytest.raises(OSError, match="No space left"):
        save_session(Session.default(), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]  # no s.json.tmp left


def test_work_the_file_cannot_take_is_kept_in_the_cache_when_the_studio_stops_and_pages_are_told(tmp_path,
                                                                                                  monkeypatch):
    # QA (session 37): after the disk filled, edits and a run were made, Ctrl-C printed "CLM Studio stopped." and
    # they were gone; a page opened meanwhile, or a later failure, heard nothing; nothing said when saving worked again.
    import studio.app as app
    import studio.session_file as session_file
    from studio.session_file import load_session

    monkeypatch.setattr(session_file, "LOCK_DIR", tmp_path / "cache" / "sessions")
    path = tmp_path / "s.json"
    studio = app.Studio(Session.default(), host="127.0.0.1", port=0, session_path=path)
    said: list[tuple[str, str]] = []
    monkeypatch.setattr(studio, "notify", lambda client, title, text, color="red": said.append((title, color)))
    monkeypatch.setattr(studio.server, "get_clients", lambda: {1: object()})
    try:
        real = app.save_session

        def full(session: Session, where: object) -> None:
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(app, "save_session", full)
        studio.session.set_param("r4", 129.0)
        studio.autosave()
        studio.autosave()  # the same failure a moment later: not said again at once
        assert said == [("Session not saved", "yellow")]
        monkeypatch.setattr(app, "SAVE_REMIND", 0.0)
        studio.autosave()  # while it lasts, said again (a run that ended unsaved said nothing)
        assert said[-1] == ("Session not saved", "yellow") and len(said) == 2
        message = studio.final_save()
        assert message is not None and "its latest state is in" in message
        kept = next((tmp_path / "cache" / "unsaved").glob("s-*.json"))
        assert str(kept) in message and load_session(kept).view.values["r4"] == 129.0
        monkeypatch.setattr(app, "save_session", real)
        studio.autosave()
        assert said[-1] == ("Session saved again", "green") and load_session(path).view.values["r4"] == 129.0
        assert studio.final_save() is None
    finally:
        studio.close()


@pytest.mark.parametrize(("name", "value", "note"), [
    ("r2", 250.0, "; non-Grashof: s + l = 310 > p + q = 270 mm, so no link turns fully"),  # 60+250 > 120+150
    ("r3", 30.0, "; Grashof, but the shortest link is the rocker DC (30 mm), so AB only rocks"),
])
def test_a_four_bar_that_cannot_turn_its_crank_says_which_grashof_case_it_is(name, value, note) -> None:
    # The refusal said where the four-bar stops assembling; a designer (or a class) wants Grashof's reason too.
    s = Session.default("fourbar/chebyshev")
    with pytest.raises(ValueError, match=r"does not assemble over") as got:
        s.set_param(name, value)
    assert str(got.value).endswith(note)
    s.set_param("r1", 160.0)  # the ground (120) is then the shortest: a drag link, the crank turns fully
    assert s.view.assembles


def test_other_mechanisms_get_no_grashof_note() -> None:
    from studio.state import grashof_note

    assert grashof_note(Session.default().view) == ""


def test_the_session_summary_gives_the_metrics_rows_mse_for_a_target_without_times(session: Session) -> None:
    """The Load-session prompt read "MSE 76 mm" for a design the Metrics panel put at 7.46 mm (rehearsal 4): the
    summary took the error with the curve's first point at t = 0, the panel the best phase's."""
    from studio.metrics import shape_error
    from studio.target import Curve

    session.set_curve(Curve.from_csv(OVAL, "oval.csv"))
    ev = session.view.evaluation
    assert abs(float(ev.mse[0]) - float(ev.mse_phase[0])) > 1.0  # the two differ for this curve
    row = next(r for r in session.view.rows if r.key == "mse")
    assert f"MSE {row.value:.3g} mm" in session.summary() and row.value == shape_error(ev)


def test_a_design_file_gets_a_target_of_its_own_whatever_the_editor_showed_before() -> None:
    # Review of session 29: a Jansen leg scaled x0.4 read MSE 58.6 mm loaded over the Jansen preset (the preset's
    # fitted target) and 0.99 mm loaded over X3 (one fitted to it); the same file, two answers.
    small = presets.get("jansen").design().scaled(0.4)
    over_jansen = Session.default()
    over_jansen.load_preset("jansen")
    a = over_jansen.set_design(small, by_hand=True, cause="design j04.json", refit=True)
    over_x3 = Session.default()
    b = over_x3.set_design(small, by_hand=True, cause="design j04.json", refit=True)
    assert a.target == b.target and a.target.origin.startswith("scaled to the design j04.json path")
    assert shape_error(a.evaluation) == pytest.approx(shape_error(b.evaluation), abs=1e-9)
    assert shape_error(a.evaluation) < 2.0
    # A pick of a run (no refit) keeps the target the run was made against, and so does the paper's cycloid.
    kept = Session.default()
    kept.load_preset("jansen")
    before = kept.view.target
    assert kept.set_design(small, cause="subtask1's pick").target == before
    x3 = Session.default()
    paper = x3.view.target
    assert x3.set_design(presets.get("stephenson1/X3").design().scaled(0.5), refit=True).target == paper


def test_a_design_file_whose_path_does_not_close_keeps_the_target_and_later_files_are_refitted() -> None:
    # Review of session 30: such a file put the paper's cycloid in place of the fitted target ("the preset's path
    # does not close"), and every later file of that mechanism was measured against it (MSE 171.68 mm, not 0.99).
    s = Session.default()
    s.load_preset("jansen")
    before = s.view.target
    broken = presets.get("jansen").design().replace(j=5.0)
    bad = s.set_design(broken, by_hand=True, cause="design broken.json", refit=True)
    assert not bad.assembles and bad.target == before
    small = presets.get("jansen").design().scaled(0.4)
    good = s.set_design(small, by_hand=True, cause="design j04.json", refit=True)
    assert good.target.origin.startswith("scaled to the design j04.json path") and shape_error(good.evaluation) < 2.0
    # The same with the broken file of another mechanism than the editor's (review of session 31).
    other = Session.default()  # Stephenson-I X3
    bad = other.set_design(broken, by_hand=True, cause="design broken.json", refit=True)
    assert not bad.assembles and bad.target.origin.startswith("scaled to the")  # the Jansen preset's, refittable
    good = other.set_design(small, by_hand=True, cause="design j04.json", refit=True)
    assert good.target.origin.startswith("scaled to the design j04.json path") and shape_error(good.evaluation) < 2.0


def test_the_pin_holes_travel_with_the_session_and_a_bad_one_is_refused() -> None:
    # Review of session 29: the Pin hole Ø lived on the panel; a reload put 5 mm holes back in the DXF unsaid.
    from core.formats.drawing import Plates
    from studio.state import Session as S

    s = S.default()
    assert "plates" not in s.to_dict()  # the default is not written: older sessions read the same
    s.set_plates(Plates(3.0))
    data = json.loads(json.dumps(s.to_dict()))
    assert data["plates"] == {"hole": 3.0, "width": None}
    back = S.from_dict(data)
    assert back.plates == Plates(3.0)
    fresh = S.default()
    fresh.restore(back)
    assert fresh.plates == Plates(3.0)
    for bad, said in (({"hole": -1.0}, "plates: the hole diameter must be a positive number"),
                      ({"hole": 5.0, "width": 4.0}, "plates: the plate width must be more than the hole"),
                      ({"hole": 5.0, "depth": 1}, "depth")):
        with pytest.raises(ValueError, match=said):
            S.from_dict(dict(data, plates=bad))


def test_a_design_whose_path_is_past_the_target_limit_loads_with_its_mechanisms_target() -> None:
    # Review of session 31: a Jansen leg x15000 (every parameter under 1e6 mm, its path wider) was refused with
    # "target length must be at most 1e+06 mm", a target the designer never gave.
    from core.kinematics.presets import get

    big = get("jansen").design().scaled(15000)
    assert float(np.abs(big.params).max()) < 1e6
    jansen = Session.default()
    jansen.load_preset("jansen")
    for s in (Session.default(), jansen):
        v = s.set_design(big, by_hand=True, cause="design big.json", refit=True)
        assert v.design is not None and np.array_equal(v.design.params, big.params)
        assert v.target.length is not None and v.target.length <= 1e6
