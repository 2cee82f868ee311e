"""The exported files' contents, column by column (a mutation audit of studio/exports.py found the time, leg-frame,
target and stance columns and the design file's source line unchecked)."""

from __future__ import annotations

import json
import math

import numpy as np
import plotly.graph_objects as go
import pytest

from core.kinematics import presets
from studio.exports import (
    CSV_COLUMNS,
    design_json,
    drawing_export,
    figure_html,
    parse_trajectories_csv,
    trajectories_csv,
)
from studio.state import Session, build_view
from studio.target import TargetSpec


@pytest.fixture(scope="module")
def x3() -> Session:
    return Session.default()


def rows(data: bytes) -> list[list[str]]:
    lines = data.decode().splitlines()
    assert lines[0].split(",") == list(CSV_COLUMNS)
    return [line.split(",") for line in lines[1:]]


def test_the_design_file_names_its_preset_and_says_when_it_was_edited():
    from core.cli.presets import preset_dict

    s = Session.default("stephenson1/IMTCMO-X3")
    p = presets.get("stephenson1/IMTCMO-X3")
    assert json.loads(design_json(s.view)) == json.loads(json.dumps(preset_dict(p)))  # as `clm presets show`
    name = s.view.design.mechanism.params[0].name
    s.set_param(name, float(s.view.values[name]) * 1.001)
    edited = json.loads(design_json(s.view))
    assert "name" not in edited and edited["title"] == p.mechanism.title
    assert edited["source"] == f"clm-studio, edited from preset stephenson1/IMTCMO-X3 ({p.source})"
    assert "b printed 047, read 0.47" in edited["source"]  # the paper row's misprint, read as the spec says


def test_each_row_is_one_crank_sample_at_its_time_in_the_period(x3: Session):
    view = x3.view
    cols = parse_trajectories_csv(trajectories_csv(view))
    n, period = view.n_samples, view.target.period
    np.testing.assert_array_equal(cols["sample"], np.arange(n))
    # One revolution in T: sample i at i T / n (the next revolution's first sample would be at T).
    assert cols["t_s"][0] == 0.0 and cols["t_s"][n // 2] == pytest.approx(period / 2, abs=1e-12)
    assert cols["t_s"][-1] == pytest.approx(period * (n - 1) / n, abs=1e-12)
    np.testing.assert_allclose(cols["theta_rad"], view.solution.theta)


def test_the_columns_hold_the_path_in_each_frame_and_the_target_in_each_frame(x3: Session):
    view = x3.view
    cols = parse_trajectories_csv(trajectories_csv(view))
    np.testing.assert_array_equal(cols["x_design_mm"], view.solution.point[0, :, 0])
    np.testing.assert_array_equal(cols["y_design_mm"], view.solution.point[0, :, 1])
    np.testing.assert_array_equal(cols["x_leg_mm"], view.solution.leg[0, :, 0])
    np.testing.assert_array_equal(cols["y_leg_mm"], view.solution.leg[0, :, 1])
    np.testing.assert_array_equal(cols["x_target_mm"], view.target_design[:, 0])
    np.testing.assert_array_equal(cols["y_target_mm"], view.target_design[:, 1])
    np.testing.assert_array_equal(cols["x_target_leg_mm"], view.target_leg[:, 0])
    np.testing.assert_array_equal(cols["y_target_leg_mm"], view.target_leg[:, 1])
    # The two frames differ for X3 (its output stage is a pantograph, k = -1): a swap would show.
    assert np.abs(cols["x_leg_mm"] - cols["x_design_mm"]).max() > 10.0
    assert np.abs(cols["x_target_leg_mm"] - cols["x_target_mm"]).max() > 10.0
    # No "-0.0" cell (rehearsal 3: the cycloid's first y_target_mm read -0.0), and nothing else changed by it.
    text = trajectories_csv(view).decode()
    assert view.target_design[0, 1] == 0.0 and ",-0.0," not in text and not text.replace("\n", ",").count(",-0.0,")


def test_stance_is_one_from_landing_to_take_off_and_zero_in_the_swing(x3: Session):
    view = x3.view
    stance = parse_trajectories_csv(trajectories_csv(view))["stance"]
    t1, t2 = view.evaluation.times[0, 0], view.evaluation.times[0, 1]
    period, n = view.evaluation.period, view.n_samples
    t = np.arange(n) * period / n
    inside = (t - t1) % period <= (t2 - t1) % period
    sure = np.abs(((t - t1 + period / 2) % period) - period / 2) > period / n  # not the sample at either end
    sure &= np.abs(((t - t2 + period / 2) % period) - period / 2) > period / n
    np.testing.assert_array_equal(stance[sure], inside[sure].astype(float))
    assert 0 < stance.sum() < n


def test_a_sample_where_the_mechanism_does_not_assemble_has_empty_cells_not_nan():
    s = Session.default()
    view = build_view(s.view.design.replace(r4=500.0), None, TargetSpec())
    broken = ~np.isfinite(view.solution.point[0]).all(axis=1)
    assert broken.any()
    table = rows(trajectories_csv(view))
    for i in np.flatnonzero(broken)[:5]:
        assert table[i][3:7] == ["", "", "", ""]
    assert "nan" not in trajectories_csv(view).decode().lower()


def test_a_chart_page_carries_its_title():
    page = figure_html(go.Figure(), "CLM Studio: subtask2").decode()
    head = page[page.index("<head>"):page.index("</head>")]
    assert "<title>CLM Studio: subtask2</title>" in head


def test_a_drawing_is_svg_or_dxf_as_asked(x3: Session):
    name, svg = drawing_export(x3.view, 0.0, "svg")
    assert name == "stephenson1-X3-drawing-0deg.svg"
    assert b"<svg" in svg[:400] and b"SECTION" not in svg
    name, dxf = drawing_export(x3.view, 0.0, "dxf")
    assert name == "stephenson1-X3-drawing-0deg.dxf" and b"SECTION" in dxf and b"<svg" not in dxf
    # The angle drawn is in the name and on the drawing (rehearsal 3: the DXF did not say it, the SVG did).
    name, dxf = drawing_export(x3.view, math.radians(82.8), "dxf")
    assert name == "stephenson1-X3-drawing-83deg.dxf" and b"stephenson1 at crank angle 82.8 deg" in dxf
