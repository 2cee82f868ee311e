"""Legs of other sizes than the paper's 300 mm stride (core.optimize.scale, docs/optimization.md "Legs of other
sizes"): the built-in millimetre figures follow the target's width, typed ones are kept, and a leg half the paper's
size gets the paper's search at half the size, bit for bit where no mixed-unit violation sum is involved."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from core.cli.design import notes
from core.formats.config import parse_config
from core.kinematics.mechanisms.stephenson import STEPHENSON1
from core.kinematics.presets import PRESETS
from core.optimize.box import global_box, search_box
from core.optimize.objectives import target_scale
from core.optimize.problem import make_problem
from core.optimize.run import DesignRun, run_design
from core.optimize.scale import entry_bounds, scaled_limit, sized_bounds, stride_scale
from core.optimize.stage import StageSpec

ROOT = Path(__file__).resolve().parents[1]
X2 = np.array(PRESETS["stephenson1/X2"].values)
IDX = {n: i for i, n in enumerate(STEPHENSON1.param_names)}
HALF = "cycloid:L=150.0,H=50.0,T=2.0"


def limits(spec: object) -> dict[str, float]:
    return {c.metric: c.upper for c in spec.constraints if c.upper is not None and c.metric != "violation"}  # type: ignore[attr-defined]


def test_the_scale_is_the_target_width_over_the_papers_300_mm() -> None:
    assert target_scale("cycloid", 360) == 1.0  # exactly: the paper's own runs do not move
    assert target_scale(HALF, 360) == 0.5
    assert target_scale("cycloid:L=1200,H=400", 360) == 4.0
    assert stride_scale(0.0) == stride_scale(float("nan")) == 1.0  # a degenerate target: the paper's figures
    # A CSV export of the paper's cycloid reads 299.999 mm: the paper's size, not every figure moved by a millionth.
    assert stride_scale(299.999) == stride_scale(300.2) == 1.0 and stride_scale(299.6) == 299.6 / 300.0


def test_an_rtclm_config_with_a_target_table_is_not_sized(tmp_path: Path) -> None:
    # The RTCLM's targets are heights: a [target] table (a curve it does not optimize) halved its start design.
    data = tomllib.loads((ROOT / "assets/configs/rtclm_case1.toml").read_text())
    base = parse_config(data)
    data["target"] = {"curve": "cycloid", "L": 150.0, "H": 50.0}
    sized = parse_config(data)
    np.testing.assert_array_equal(sized.start.params, base.start.params)
    assert [s.d for s in sized.stages] == [s.d for s in base.stages]


def test_the_dp_baselines_search_the_sized_bounds() -> None:
    from core.optimize.baselines import BaselineSettings, _bounds

    lo, hi = _bounds(STEPHENSON1, BaselineSettings(target=HALF))
    assert (lo[IDX["r1"]], hi[IDX["r1"]]) == (15.0, 250.0)
    assert make_problem("dp", target=HALF).scale == 0.5


def test_limits_left_out_are_the_papers_sized_mm_by_k_and_mm2_by_k_squared() -> None:
    paper = make_problem("subtask3")
    assert limits(paper) == {"f1": 6.0, "f2": 5.0, "f3": 5.0, "h_s": 6.5, "I": 20.0}
    half = make_problem("subtask3", target=HALF)
    assert limits(half) == {"f1": 3.0, "f2": 1.25, "f3": 1.25, "h_s": 3.25, "I": 10.0}
    assert half.options["f2_max"] == 1.25  # recorded as the number taken: a result file says what bound
    typed = make_problem("subtask2", target=HALF, f1_max=4.0)
    assert limits(typed) == {"f1": 4.0, "f2": 1.25, "f3": 1.25}  # typed: kept as typed
    assert scaled_limit("S", 2.0, 0.5) == 2.0  # a ratio does not scale


def test_a_problem_rebuilt_from_its_recorded_options_is_the_same() -> None:
    half = make_problem("subtask2", target=HALF)
    again = make_problem("subtask2", **half.options)
    assert limits(again) == limits(half) and again.scale == half.scale == 0.5


def test_global_bounds_of_lengths_positions_and_offsets_scale_angles_and_typed_bounds_do_not() -> None:
    lo, hi = sized_bounds(STEPHENSON1, 0.5)
    assert (lo[IDX["r1"]], hi[IDX["r1"]]) == (15.0, 250.0)
    assert (lo[IDX["x_a"]], hi[IDX["x_a"]]) == (-250.0, 250.0)
    assert (lo[IDX["r6"]], hi[IDX["r6"]]) == (-250.0, 250.0)  # an offset
    assert (lo[IDX["b"]], hi[IDX["b"]]) == (-np.pi, np.pi)
    config = parse_config({"mechanism": "stephenson1", "bounds": {"r1": [40.0, 90.0]},
                           "target": {"curve": "cycloid", "L": 150.0, "H": 50.0},
                           "stages": [{"name": "predesign", "box": "global"}]})
    mech = config.start.mechanism
    lo, hi = sized_bounds(mech, 0.5)
    assert (lo[IDX["r1"]], hi[IDX["r1"]]) == (40.0, 90.0)  # typed
    assert (lo[IDX["r2"]], hi[IDX["r2"]]) == (15.0, 250.0)


def test_a_stage_box_takes_its_problems_scale() -> None:
    spec = StageSpec("predesign", make_problem("predesign", target=HALF))
    box = spec.box(PRESETS["stephenson1/X2"].design())
    assert (box.bound_lo[IDX["r1"]], box.bound_hi[IDX["r1"]]) == (15.0, 250.0)
    assert box.lower[IDX["r1"]] == 15.0
    # A 20 mm crank is inside a half-size leg's bounds but clipped to 30 mm on the paper's.
    center = X2.copy()
    center[IDX["r1"]] = 20.0
    assert global_box(STEPHENSON1, center, scale=0.5).center[IDX["r1"]] == 20.0
    assert global_box(STEPHENSON1, center).center[IDX["r1"]] == 30.0
    assert search_box(STEPHENSON1, center, 0.1, 5.0, scale=0.5).lower[IDX["r1"]] == 15.0


def test_entry_bounds_reach_the_sized_and_the_papers_bounds() -> None:
    r1 = STEPHENSON1.params[IDX["r1"]]
    assert entry_bounds(r1, 0.5) == (15.0, 500.0)
    assert entry_bounds(r1, 4.0) == (30.0, 2000.0)
    assert entry_bounds(STEPHENSON1.params[IDX["b"]], 4.0) == (-np.pi, np.pi)


def config(k: float, n_gen: int, with_steps: bool = True) -> dict[str, object]:
    data = tomllib.loads((ROOT / "assets/configs/stephenson1_cycloid.toml").read_text())
    data["target"] = {"curve": "cycloid", "L": 300.0 * k, "H": 100.0 * k, "T": 2.0}
    data.pop("output")  # the pantograph's default centre, (150, 0) mm on the paper's leg
    stages = [dict(s) for s in data["stages"]][:2 if with_steps else 1]  # type: ignore[index]
    stages[0].pop("starts")
    for s in stages:
        s["n_gen"] = n_gen
    data["stages"] = stages
    data["algorithm"] = {"name": "nsga2", "pop_size": 24}
    return data


def test_the_shipped_config_at_half_the_size_sizes_its_steps_and_pantograph() -> None:
    paper, half = parse_config(config(1.0, 2)), parse_config(config(0.5, 2))
    assert [s.d for s in paper.stages] == [0.0, 20.0] and [s.d for s in half.stages] == [0.0, 10.0]
    assert (paper.start.output.ox, half.start.output.ox) == (150.0, 75.0)
    typed = config(0.5, 2)
    typed["stages"][1]["box"] = {"s": 0.2, "d": 20.0}  # type: ignore[index]
    assert parse_config(typed).stages[1].d == 20.0


@pytest.fixture(scope="module")
def runs() -> list[DesignRun]:
    return [run_design(parse_config(config(k, 4))) for k in (1.0, 0.5)]


def test_a_leg_half_the_papers_size_runs_the_papers_search_at_half_the_size(runs: list[DesignRun]) -> None:
    # Predesign and subtask 1 constrain assembly only, a shortfall in mm: with every built-in figure halved
    # (bounds, steps, band, pantograph) and the target halved, every number is halved exactly (x 0.5 is exact in
    # binary), so both runs take the same decisions (the variables bit for bit). An unsized figure parts them.
    for a, b in zip(runs[0].results, runs[1].results, strict=True):
        sized = np.array([p.kind != "angle" for p in a.mechanism.params])
        assert a.picked == b.picked
        np.testing.assert_array_equal(b.X, a.X * np.where(sized, 0.5, 1.0))
        # Metrics are rounded to 10 significant digits (objectives.quantize), a halved one on other digits.
        np.testing.assert_allclose(b.metrics["f1"], a.metrics["f1"] * 0.5, rtol=1e-9)
        np.testing.assert_allclose(b.metrics["f2"], a.metrics["f2"] * 0.25, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(b.metrics["S"], a.metrics["S"], rtol=1e-9)


def test_clm_design_says_when_it_sized_a_leg(runs: list[DesignRun]) -> None:
    assert not [line for line in notes(runs[0]) if "wide" in line]
    assert [line for line in notes(runs[1]) if "the target is 150 mm wide" in line and "x 0.5 " in line]


@pytest.mark.parametrize("k", [1.0, 0.5])
def test_the_half_size_run_parts_if_a_built_in_figure_stays_at_the_papers_size(k: float) -> None:
    # The same comparison with the subtask-1 step typed as the paper's 20 mm on both: the half-size leg's box is
    # then twice as wide as the paper's, and the runs part (at k = 1 nothing changes: the control).
    data = [config(1.0, 4), config(k, 4)]
    for d in data:
        d["stages"][1]["box"] = {"s": 0.2, "d": 20.0}  # type: ignore[index]
    a, b = (run_design(parse_config(d)).results[1] for d in data)
    sized = np.array([p.kind != "angle" for p in a.mechanism.params])
    same = np.array_equal(b.X, a.X * np.where(sized, k, 1.0))
    assert same == (k == 1.0)


def test_the_studio_takes_a_half_size_legs_crank_once_the_target_is_half_size() -> None:
    from studio.state import Session

    session = Session.default()
    with pytest.raises(ValueError, match=r"outside its bounds \[30, 500\] mm"):
        session.set_param("r1", 20.0)
    session.set_target(length=150.0, height=50.0)
    with pytest.raises(ValueError, match=r"outside its bounds \[15, 500\] mm \(the paper's 30-500 mm for a 300 mm "
                                         r"stride, sized to this target's 150 mm\)$"):
        session.set_param("r1", 14.0)
    # Within the half-size bounds: X3 (the paper's size) then refuses it only for its assembly.
    with pytest.raises(ValueError, match="does not assemble"):
        session.set_param("r1", 20.0)
    session.set_param("r1", 45.0)
    assert session.view.design.named(0)["r1"] == 45.0
    # A walker's bounds are the project's, not the paper's, and what is printed is taken (review of session 29:
    # "[1.133, 500]" refused 1.1333 for a bound of 1.13333).
    session.load_preset("jansen")
    with pytest.raises(ValueError, match=r"outside its bounds \[1.14, 500\] mm \(the global 5-500 mm for a 300 mm "):
        session.set_param("b", 1.13)
    # And for a leg of metres (review of session 30: ":.6g" printed [-10000.9, 10000.9] and refused 10000.9).
    from core.kinematics.params import Param
    from studio.state import bounds_text, check_value

    x = Param("x_a", "position", -500.0, 500.0)
    k = 10000.87 / 500.0
    text = bounds_text(x, k)
    assert text.startswith("[-10000.87, 10000.87] mm")
    assert check_value(x, 10000.87, k) == 10000.87


def test_the_studio_sizes_its_chains_steps_and_pick_limits_to_the_target() -> None:
    from studio.chains import chain_for, sized_where, stage_spec
    from studio.state import Session
    from studio.study import default_settings  # type: ignore[attr-defined]
    from studio.target import TargetSpec

    design = Session.default().view.design
    subtask3 = next(c for c in chain_for(design.mechanism) if c.name == "subtask3")
    half = stage_spec(subtask3, default_settings(subtask3), TargetSpec(150.0, 50.0, 2.0))
    assert (half.d, half.problem.scale) == (2.5, 0.5)
    assert {c.metric: c.upper for c in half.problem.constraints}["I"] == 10.0  # Eq. 23's 20 mm/s
    assert sized_where(subtask3.pick_where, 0.5)[0].upper == 0.22  # the chain's I <= 0.44 mm/s


def test_the_studio_previews_the_next_box_at_the_size_the_run_will_use() -> None:
    # After the target changed, the "from the previous pick" box was the one the earlier target's stage would get.
    from test_studio_study import run, tiny

    from studio.chains import chain_for
    from studio.state import Session
    from studio.study_view import study_view

    session = Session.default()
    tiny(session.study, "subtask1")
    run(session, "subtask1", from_pick=False)
    study, chain = session.study, chain_for(session.view.design.mechanism)
    study.use_for_next("subtask1", study.result("subtask1").picked, chain)
    session.set_target(length=150.0, height=50.0)
    with session.lock:
        sv = study_view(study, session.view.design, chain, session.view.target)
    assert sv.box is not None and sv.box.bound_lo[IDX["r1"]] == 15.0
    assert "sized for a 150 mm stride" in sv.box_note
