"""A design at another size: every path scales by the factor, the motion (angles) is the same; clm scale."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.cli import main
from core.kinematics.design import Design
from core.kinematics.presets import get

NAMES = ["stephenson1/X3", "watt1/paper", "stephenson3/paper", "fourbar/chebyshev", "jansen", "klann", "rtclm/case4",
         "rtclm/case4/auxiliary"]


@pytest.mark.parametrize("name", NAMES)
@given(factor=st.floats(0.05, 20))
@settings(max_examples=8, deadline=None)
def test_every_path_and_joint_scales_by_the_factor_and_the_angles_stay(name, factor):
    design = get(name).design()
    a, b = design.solve(180), design.scaled(factor).solve(180)
    np.testing.assert_allclose(b.point, factor * a.point, rtol=1e-9, atol=1e-9 * factor)
    np.testing.assert_allclose(b.leg, factor * a.leg, rtol=1e-9, atol=1e-9 * factor)
    np.testing.assert_allclose(b.joints, factor * a.joints, rtol=1e-9, atol=1e-9 * factor)
    assert a.violation[0] == b.violation[0] == 0.0
    for p, x, y in zip(design.mechanism.params, design.params[0], design.scaled(factor).params[0], strict=True):
        assert y == (x if p.kind == "angle" else x * factor), p.name


def test_a_population_scales_member_by_member_and_a_bad_factor_is_refused():
    one = get("stephenson1/X3").design()
    other = one.replace(r1=50.0, b=0.3)
    pop = Design(one.mechanism, np.vstack([one.params, other.params]), one.output)
    np.testing.assert_array_equal(pop.scaled(0.5).params, np.vstack([one.scaled(0.5).params, other.scaled(0.5).params]))
    assert other.scaled(0.5).named()["r1"] == 25.0 and other.scaled(0.5).named()["b"] == 0.3
    assert pop.scaled(0.5).output.ox == one.output.ox * 0.5 and pop.scaled(0.5).output.k == one.output.k
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="positive number"):
            one.scaled(bad)


def test_clm_scale_to_a_stride_writes_a_design_that_simulates_at_that_width(tmp_path, capsys):
    out = tmp_path / "leg.json"
    assert main(["scale", "--preset", "stephenson1/X3", "--stride", "120", "--out", str(out)]) == 0
    assert "leg-frame path width 298.94 -> 120.00 mm" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["mechanism"] == "stephenson1" and data["params"]["g"] == 3.26
    assert main(["simulate", "--design", str(out), "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert sim["extent_leg"]["width"] == pytest.approx(120.0, abs=1e-9)
    # Printed without --out, by factor, from a design file: the same numbers as the core's.
    assert main(["scale", "--design", str(out), "--factor", "2"]) == 0
    twice = json.loads(capsys.readouterr().out)
    assert twice["params"]["r1"] == pytest.approx(2 * data["params"]["r1"], rel=1e-12)
    assert twice["output"]["ox"] == pytest.approx(2 * data["output"]["ox"], rel=1e-12)


def test_clm_scale_keeps_an_existing_file_unless_overwrite(tmp_path, capsys):
    # As `clm presets show --out`: `--design mine.json --out mine.json` replaced the design it scaled.
    mine = tmp_path / "mine.json"
    assert main(["presets", "show", "stephenson1/X3", "--out", str(mine)]) == 0
    before = mine.read_text()
    capsys.readouterr()
    assert main(["scale", "--design", str(mine), "--factor", "2", "--out", str(mine)]) == 2
    assert capsys.readouterr().err == (f"clm: error: --out {mine} exists; pass --overwrite to replace it, or give "
                                       "another file\n")
    assert mine.read_text() == before
    assert main(["scale", "--design", str(mine), "--factor", "2", "--out", str(mine), "--overwrite"]) == 0
    assert json.loads(mine.read_text())["params"]["r1"] == pytest.approx(2 * json.loads(before)["params"]["r1"])


@pytest.mark.parametrize("args", [["--factor", "0"], ["--factor", "-2"], ["--stride", "nan"], ["--stride", "-5"],
                                  ["--factor", "2", "--stride", "3"], []])
def test_clm_scale_refuses_what_is_no_size_in_one_line(args, capsys):
    assert main(["scale", "--preset", "stephenson1/X3", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clm: error:")


def test_a_design_that_does_not_assemble_scales_by_factor_but_has_no_stride(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"mechanism": "stephenson1", "params": [1.0] * 16}))
    assert main(["scale", "--design", str(bad), "--stride", "100"]) == 2
    err = capsys.readouterr().err  # which of the two reasons (QA, session 36: it named both)
    assert "the design does not assemble over the whole crank cycle (violation " in err
    assert "so its foot path has no width to scale from: give --factor" in err and "along x" not in err
    assert main(["scale", "--design", str(bad), "--factor", "3"]) == 0
    assert json.loads(capsys.readouterr().out)["params"]["r1"] == 3.0


def test_a_size_the_solver_cannot_follow_is_refused_naming_the_option_given(tmp_path, capsys):
    # Review of session 29: --stride 1e-7 wrote a design that no longer assembles, exit 0, "298.94 -> 0.00 mm"; and a
    # factor derived from --stride was reported as a --factor error.
    out = tmp_path / "s.json"
    assert main(["scale", "--preset", "stephenson1/X3", "--stride", "1e-7", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("clm: error: --stride: scaled by 3.34516e-10 the design no longer assembles")
    assert not out.exists()
    assert main(["scale", "--preset", "stephenson1/X3", "--factor", "1e-9"]) == 2
    assert capsys.readouterr().err.startswith("clm: error: --factor: scaled by 1e-09 the design no longer assembles")
    assert main(["scale", "--preset", "stephenson1/X3", "--stride", "1e305"]) == 2
    assert capsys.readouterr().err.startswith("clm: error: --stride: output ox (mm) must be within")


def test_a_size_too_large_is_refused_with_the_right_advice_and_a_tiny_one_keeps_its_digits(capsys):
    # Review of session 30: x30000 was told to "choose a larger size", and x1e-5 printed "-> 0.00 mm".
    assert main(["scale", "--preset", "jansen", "--factor", "3e4"]) == 2
    assert capsys.readouterr().err.rstrip().endswith("choose a smaller size")
    assert main(["scale", "--preset", "jansen", "--factor", "1e-5"]) == 0
    assert "(leg-frame path width 67.91 -> 0.000679 mm)" in capsys.readouterr().out


def test_a_stride_in_metres_is_warned_of(capsys):
    # Lab rehearsal: --stride 0.3 (300 mm written in m) wrote a 0.3 mm leg without a word.
    from core.cli import main

    assert main(["scale", "--preset", "stephenson1/X3", "--stride", "0.3"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("clm: warning: stephenson1/X3 x0.001") and "its foot path: it spans 0.3" in err
    assert main(["scale", "--preset", "stephenson1/X3", "--stride", "150"]) == 0
    assert capsys.readouterr().err == ""
