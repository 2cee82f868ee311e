"""Walking view geometry, uploaded target curves and the export files, without a browser."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from core.analysis.targets import parse_target
from core.formats.design import design_from_dict
from core.kinematics import presets
from studio.exports import design_json, figure_html, parse_trajectories_csv, trajectories_csv
from studio.figures import make_pareto_figure
from studio.state import Session, build_view
from studio.target import Curve, TargetSpec, curve_file
from studio.walking import WalkSpec, build_walk

PLACES = np.linspace(0.0, 1.0, 201)[:-1]


@pytest.fixture(scope="module")
def x3() -> Session:
    return Session.default()


def walk(view, **kw):
    return build_walk(view.solution.leg[0], view.solution.dleg[0], view.target.period, WalkSpec(**kw))


# Walking view ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("layout", ["biped", "quadruped"])
@pytest.mark.parametrize(("a", "b"), [(25.0, 25.0), (60.0, 40.0), (5.0, 70.0), (0.0, 10.0)])
def test_the_share_of_obstacle_places_that_are_crossed_is_psi(x3: Session, layout: str, a: float, b: float) -> None:
    view = x3.view
    clear = np.mean([not walk(view, layout=layout, a=a, b=b, place=p).hit for p in PLACES])
    ev = build_view(view.design, None, view.target, walk=WalkSpec(layout, a, b)).evaluation
    psi = float(ev.psi2[0] if layout == "biped" else ev.psi4[0])
    # 200 places sample a union of intervals: each interval end can be off by one place.
    assert abs(clear - psi) <= 6.0 / len(PLACES)


def test_psi4_is_measured_on_the_trunk_the_walking_view_draws(x3: Session) -> None:
    # QA (session 38): the view drew the trunk set (a Jansen leg's 102 mm) while psi4 was the 450 mm trunk's
    # (41.3 % shown for 10.0 %); on X3 a 300 mm trunk turned the obstacle to "hit" and psi4 stayed 16.6 %.
    from core.analysis.evaluate import evaluate

    view = x3.view
    spec = WalkSpec("quadruped", 25.0, 25.0, trunk=300.0)
    ev = build_view(view.design, None, view.target, walk=spec).evaluation
    clear = np.mean([not walk(view, layout="quadruped", trunk=300.0, place=p).hit for p in PLACES])
    assert abs(clear - float(ev.psi4[0])) <= 6.0 / len(PLACES)
    core = evaluate(view.design, view.n_samples, target=view.target.target(), period=view.target.period,
                    trunk=300.0)
    assert float(ev.psi4[0]) == pytest.approx(float(core.psi4[0]), abs=1e-12)
    at_450 = build_view(view.design, None, view.target, walk=WalkSpec("quadruped", 25.0, 25.0)).evaluation
    assert abs(float(at_450.psi4[0]) - float(ev.psi4[0])) > 0.1  # the trunk matters here
    with pytest.raises(ValueError, match=r"trunk \(the quadruped's hip distance\) must be a number > 0"):
        WalkSpec("quadruped", trunk=0.0)


@pytest.mark.parametrize("layout", ["biped", "quadruped"])
def test_a_clear_obstacle_has_no_foot_inside_and_a_foot_deep_inside_means_blocked(x3: Session, layout: str) -> None:
    for p in PLACES[::10]:
        w = walk(x3.view, layout=layout, a=30.0, b=30.0, place=p)
        (x0, _), (x1, y1) = w.obstacle[0], w.obstacle[2]
        # Every foot sample of one stride, repeated a stride earlier and later (the pattern is periodic).
        feet = np.concatenate([w.trails.reshape(-1, 2) + [k * w.stride, 0.0] for k in (-1, 0, 1)])
        inside = (feet[:, 0] > x0 + 1.0) & (feet[:, 0] < x1 - 1.0) & (feet[:, 1] < y1 - 1.0)
        if inside.any():
            assert w.hit
        loose = (feet[:, 0] >= x0 - 0.5) & (feet[:, 0] <= x1 + 0.5) & (feet[:, 1] <= y1 + 0.5)
        if not w.hit:
            assert not loose.any()


def test_the_trunk_rises_and_falls_by_the_stance_fluctuation_h_s(x3: Session) -> None:
    w = walk(x3.view)
    h_s = float(x3.view.evaluation.h_s[0])
    assert np.ptp(w.hip[:, 1]) == pytest.approx(h_s, rel=0.02, abs=0.05)
    # One stride per crank revolution: leg A's foot moves by the stride 2 l_s over the cycle.
    assert w.stride == pytest.approx(2.0 * float(x3.view.evaluation.l_s[0]), rel=1e-6)
    assert w.trunk.shape == (360, 2, 2) and w.legs.shape == (360, 2, 2, 2)
    np.testing.assert_allclose(w.legs[:, :, 1], w.feet)


def test_a_quadruped_has_four_legs_on_a_trunk_of_the_given_length(x3: Session) -> None:
    w = walk(x3.view, layout="quadruped", trunk=400.0)
    assert w.feet.shape == (360, 4, 2)
    hips = w.legs[:, :, 0]
    np.testing.assert_allclose(hips[:, 0] - hips[:, 2], np.broadcast_to([400.0, 0.0], (360, 2)), atol=1e-9)


def test_no_walking_view_without_a_well_defined_bench_trajectory() -> None:
    view = build_view(presets.get("stephenson1/X3").design().replace(r4=500.0), None, TargetSpec())
    assert view.walking is None


@pytest.mark.parametrize(("kw", "message"), [({"layout": "hexapod"}, "layout"), ({"a": -1.0}, "obstacle a"),
                                             ({"b": math.nan}, "obstacle b"), ({"place": 1.5}, "place"),
                                             ({"a": 2e6}, "obstacle a"), ({"trunk": -3.0}, "trunk"),
                                             ({"trunk": math.inf}, "trunk")])
def test_walk_settings_are_validated(kw: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        WalkSpec(**kw)


def test_the_obstacle_moves_forward_one_stride_as_place_goes_from_0_to_1(x3: Session) -> None:
    at = {p: walk(x3.view, place=p) for p in (0.0, 0.5, 1.0)}
    x0 = {p: float(w.obstacle[0, 0]) for p, w in at.items()}
    stride = at[0.5].stride
    assert x0[1.0] - x0[0.0] == pytest.approx(stride) and x0[0.5] - x0[0.0] == pytest.approx(stride / 2)
    centre = 0.5 * (at[0.5].trails[..., 0].min() + at[0.5].trails[..., 0].max())
    assert x0[0.5] + 12.5 == pytest.approx(centre)  # place 0.5: the 25 mm obstacle centred on the feet's range


def test_the_obstacle_size_is_psis(x3: Session) -> None:
    s = Session.from_dict(x3.to_dict())
    view = s.set_walk(a=60.0, b=40.0)
    row = {r.key: r for r in view.rows}["psi2"]
    assert row.label == "ψ₂(60, 40)"
    ev = build_view(view.design, None, view.target, walk=WalkSpec(a=60.0, b=40.0)).evaluation
    assert row.value == pytest.approx(100.0 * float(ev.psi2[0]))


def test_the_obstacle_and_trunk_go_with_the_leg_s_size_unless_the_designer_set_them() -> None:
    # QA walk (session 36): a Theo Jansen leg (68 x 22 mm step) faced the paper's 25 x 25 mm obstacle, as tall as
    # its step: ψ2 = ψ4 = 0 % read as a property of the leg.
    s = Session.default()
    assert (s.view.walk.a, s.view.walk.b, s.view.walk.trunk) == (25.0, 25.0, 450.0)  # the paper's, at 300 x 100 mm
    s.select_mechanism("jansen")
    t, w = s.view.target, s.view.walk
    assert (w.a, w.b, w.trunk) == (round(25.0 * t.length / 300.0, 1), round(25.0 * t.height / 100.0, 1),
                                   round(450.0 * t.length / 300.0, 1))
    assert w.b < 0.5 * t.height
    psi = {r.key: r for r in s.view.rows}["psi2"]
    assert psi.label == f"ψ₂({w.a:g}, {w.b:g})" and psi.value > 0.0
    from studio.walking import sizes_for

    assert sizes_for((0.01, 0.01))[2] == 0.1  # a tiny step keeps the hips apart: psi4 is measured on the trunk
    s.select_mechanism("rtclm_primary")  # the paper's leg for crossing heights: the paper's obstacle
    assert (s.view.walk.a, s.view.walk.b, s.view.walk.trunk) == (25.0, 25.0, 450.0)
    # A target edited since the leg came keeps the walk it came with, which still goes with the next leg (review of
    # session 36: after L = 250 the Jansen leg faced 25 x 25 mm again).
    s.select_mechanism("stephenson1")
    s.set_target(length=250.0)
    s.select_mechanism("jansen")
    assert (s.view.walk.a, s.view.walk.b) == (w.a, w.b)
    s.set_target(height=25.0)
    s.select_mechanism("stephenson1")
    assert (s.view.walk.a, s.view.walk.b, s.view.walk.trunk) == (25.0, 25.0, 450.0)
    s.select_mechanism("klann")
    mine = s.set_walk(b=30.0).walk  # the designer's obstacle stays as set on the next switch
    s.select_mechanism("stephenson1")
    assert s.view.walk == mine
    s.undo()
    assert s.view.design.mechanism.name == "klann" and s.view.walk == mine


# Target curves ----------------------------------------------------------------------------------------


def ellipse_csv(n: int = 60, times: bool = False, close: bool = False) -> bytes:
    t = np.arange(n + (1 if close else 0)) / n
    x, y = 150.0 + 150.0 * np.cos(2 * np.pi * t), -50.0 + 50.0 * np.sin(2 * np.pi * t)
    rows = ["x,y,t" if times else "x,y"] + [
        ",".join(f"{v:.6f}" for v in ((xi, yi, 2.0 * ti) if times else (xi, yi))) for xi, yi, ti in zip(x, y, t,
                                                                                                         strict=True)]
    return ("\n".join(rows) + "\n").encode()


@pytest.mark.parametrize("times", [False, True])
@pytest.mark.parametrize("close", [False, True])
def test_an_uploaded_curve_round_trips_through_its_csv_file_exactly(tmp_path, times: bool, close: bool) -> None:
    curve = Curve.from_csv(ellipse_csv(times=times, close=close), "ellipse.csv")
    assert curve.period == pytest.approx(2.0)
    path = curve_file(curve, tmp_path)
    again = Curve.from_target(parse_target(str(path)))
    assert again.points == curve.points and again.times == curve.times and again.period == curve.period
    assert curve_file(curve, tmp_path) == path  # content-addressed
    assert Curve.from_dict(json.loads(json.dumps(curve.to_dict()))) == curve


@pytest.mark.parametrize(("content", "message"), [
    (b"x,y\n1,2\n3,4\n", "at least 4"),
    (b"x,y\n0,0\n1,oops\n2,0\n0,1\n", "'oops' is not a number"),
    (b"\xff\xfe\x00garbage", "not a text file"),
    (b"0,0\n100,0\n200,0\n300,0\n400,0\n500,0\n", "open curve"),
])
def test_a_malformed_curve_upload_is_refused_naming_the_file_and_the_problem(content: bytes, message: str) -> None:
    with pytest.raises(ValueError, match=message) as info:
        Curve.from_csv(content, "mine.csv")
    assert "mine.csv" in str(info.value)


def test_a_curve_uploaded_in_the_leg_frame_is_the_design_frame_curve_the_output_stage_maps_to_it(x3: Session) -> None:
    out = x3.view.design.output
    assert out.k == -1.0  # the paper's pantograph: a leg-frame upload must not be taken as it is
    leg = Curve.from_csv(ellipse_csv(), "ellipse.csv", leg=out)
    plain = Curve.from_csv(ellipse_csv(), "ellipse.csv")
    np.testing.assert_allclose(out.apply(np.array(leg.points)), np.array(plain.points), atol=1e-9)
    assert leg.name == plain.name and leg.times == plain.times and leg.period == plain.period
    # the bench view draws the target in the leg frame: there it is the uploaded curve
    s = Session.from_dict(x3.to_dict())
    view = s.set_curve(leg)
    drawn = out.apply(view.target.points(240))
    up = np.array(plain.points)
    gap = np.min(np.linalg.norm(drawn[:, None, :] - up[None, :, :], axis=-1), axis=1)
    assert gap.max() < 0.05 * np.ptp(up[:, 0])  # every drawn sample is near an uploaded point


def test_an_uploaded_curve_stays_the_target_on_another_topology_even_from_a_file_without_its_origin(
        x3: Session) -> None:
    curve = Curve.from_csv(ellipse_csv(), "ellipse.csv")
    data = {"L": 300.0, "H": 100.0, "T": 2.0, "curve": curve.to_dict()}  # as an older session wrote it
    assert TargetSpec.from_dict(data).origin == "uploaded"
    s = Session.from_dict({**x3.to_dict(), "target": data})
    view = s.select_mechanism("stephenson3")
    assert view.target.curve == curve


def test_a_curve_target_is_evaluated_and_saved_with_the_session(x3: Session) -> None:
    s = Session.from_dict(x3.to_dict())
    view = s.set_curve(Curve.from_csv(ellipse_csv(), "ellipse.csv"))
    assert view.target.is_curve and not view.target.has_time
    mse = {r.key: r for r in view.rows}["mse"].value
    assert mse == pytest.approx(float(view.evaluation.mse_phase[0]))  # no time law: best cyclic shift
    back = Session.from_dict(json.loads(json.dumps(s.to_dict())))
    assert back.view.target == view.target
    assert s.set_target(length=300.0).target.curve is None  # editing the cycloid returns to it


# Exports ---------------------------------------------------------------------------------------------


def test_the_design_export_is_the_design_json_clm_simulate_reads(x3: Session) -> None:
    s = Session.from_dict(x3.to_dict())
    view = s.set_param("r4", 129.0)
    back = design_from_dict(json.loads(design_json(view)))
    np.testing.assert_array_equal(back.params, view.design.params)
    assert back.output == view.design.output and back.mechanism is view.design.mechanism


def test_the_trajectories_export_has_every_sample_in_both_frames_and_the_target(x3: Session) -> None:
    view = x3.view
    cols = parse_trajectories_csv(trajectories_csv(view))
    np.testing.assert_array_equal(cols["x_leg_mm"], view.solution.leg[0, :, 0])
    np.testing.assert_array_equal(cols["y_design_mm"], view.solution.point[0, :, 1])
    np.testing.assert_array_equal(cols["theta_rad"], view.solution.theta)
    np.testing.assert_array_equal(cols["stance"].astype(bool), view.stance)
    np.testing.assert_array_equal(cols["y_target_mm"], view.target_design[:, 1])
    assert cols["t_s"][-1] == pytest.approx(view.target.period * (1 - 1 / view.n_samples))


def test_a_target_without_times_is_exported_at_the_phase_the_mse_compares() -> None:
    """Rehearsal 4: each row paired the foot with the file's first point onward (~100 mm apart) beside an MSE of
    2.2 mm at the best cyclic shift; the rows now hold the target point each sample is compared with."""
    view = Session.default().set_curve(Curve.from_csv(ellipse_csv(), "ellipse.csv"))
    cols = parse_trajectories_csv(trajectories_csv(view))
    foot = np.stack([cols["x_design_mm"], cols["y_design_mm"]], axis=1)
    target = np.stack([cols["x_target_mm"], cols["y_target_mm"]], axis=1)
    mse = float(np.hypot(*(foot - target).T).mean())
    assert mse == pytest.approx(float(view.evaluation.mse_phase[0]), rel=1e-9)
    assert float(view.evaluation.mse[0]) > mse + 1.0  # the unshifted pairing was another, larger number
    leg = np.stack([cols["x_target_leg_mm"], cols["y_target_leg_mm"]], axis=1)
    np.testing.assert_allclose(leg, view.design.output.apply(target), atol=1e-9)  # both frames shifted alike


def test_the_pareto_html_is_self_contained() -> None:
    fig = make_pareto_figure(np.array([[1.0, 2.0], [2.0, 1.0]]), np.zeros(2), objectives=("f1", "f2"), front=(0, 1))
    page = figure_html(fig, "t").decode()
    assert "<title>t</title>" in page and "Plotly.newPlot" in page
    assert not re.search(r"<script[^>]+src=", page)  # plotly.js is inlined, nothing is fetched


def recorded(page: str) -> list[dict]:
    """The scene messages a viser HTML export embeds (base64 of a length and a zstd frame holding a length, the
    msgpack of the messages and their binary buffers)."""
    import base64

    import msgspec
    import zstandard

    data = base64.b64decode(re.search(r'__VISER_EMBED_DATA__="([^"]+)"', page).group(1))
    raw = zstandard.ZstdDecompressor().decompress(data[8:], max_output_size=1 << 28)
    n = int.from_bytes(raw[:8], "little")
    return [m for _, m in msgspec.msgpack.decode(raw[8 : 8 + n])["messages"]]


def label_text(messages: list[dict], name: str) -> str:
    """A label's text once the recording's messages are played: its creation's, then its updates'."""
    text = ""
    for m in messages:
        if m.get("name") == name:
            text = m.get("props", {}).get("text", text) if m["type"] == "LabelMessage" else text
            text = m.get("updates", {}).get("text", text)
    return text


def test_the_scene_export_is_a_self_contained_viser_page_of_the_animation() -> None:
    from studio.app import Studio

    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        name, content = studio.scene_file()
        page = content.decode()
        assert name.endswith("-scene.html")
        assert "window.__VISER_EMBED_DATA__=" in page
        assert not re.search(r"<script[^>]+src=[\"']https?:", page)
        # Nothing can be picked in the recording: its inset is not titled "(click to pick)"; the live one still is.
        messages = recorded(page)
        assert label_text(messages, "/candidates/title") == "Candidates"
        assert label_text(messages, "/texts/design_title").startswith("Mechanism")  # the reading itself is right
        assert studio.inset.title.text == "Candidates (click to pick)"
    finally:
        studio.close()
