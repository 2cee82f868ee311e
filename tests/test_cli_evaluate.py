"""`clm evaluate`: a table, a JSON object with every metric, and one error line for a bad curve."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from core.analysis.evaluate import evaluate
from core.analysis.targets import compound_cycloid
from core.cli import main
from core.kinematics.presets import get

REQUIRED = ("feasible", "violation", "l_s", "h_s", "S", "I", "theta1", "theta2", "width", "y_min", "step_length",
            "h_m", "h_bar", "psi2", "psi4", "mse", "feature_points")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_has_every_metric_of_the_library(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--json", "--obstacle", "30", "20")
    assert code == 0 and err == ""
    data = json.loads(out)
    for k in REQUIRED:
        assert k in data, k
    ev = evaluate(get("stephenson1/X3").design(), 360, obstacle=(30.0, 20.0), backend="numpy")
    for k in ("l_s", "h_s", "S", "I", "psi2", "psi4", "mse", "h_m", "h_bar"):
        assert data[k] == pytest.approx(float(getattr(ev, k)[0]), rel=1e-12), k
    assert data["obstacle"] == [30.0, 20.0]
    assert set(data["feature_points"]) == {f"t{i}" for i in range(1, 9)}
    assert data["feature_points"]["t1"]["t"] == pytest.approx(float(ev.times[0, 0]))


def test_table_names_the_design_and_the_metrics(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X0")
    assert code == 0
    assert out.startswith("stephenson1/X0: feasible")
    assert "straightness" in out and "psi2(25, 25)" in out and "t8:" in out


def test_a_timed_curve_csv_is_evaluated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p, _ = compound_cycloid(360)
    t = np.arange(360) * (2.0 / 360)
    f = tmp_path / "target.csv"
    f.write_text("x,y,t\n" + "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for (a, b), c in zip(p, t, strict=True)))
    code, out, err = run(capsys, "evaluate", "--curve", str(f), "--json")
    assert code == 0, err
    data = json.loads(out)
    # the target against itself: the closed forms of tests/test_cycloid_target_closed_forms.py
    assert data["mse"] == pytest.approx(0.0, abs=1e-9)
    assert data["l_s"] == pytest.approx(300.0, rel=1e-9)
    assert data["h_m"] == pytest.approx(100.0, rel=1e-6)
    assert data["S"] == pytest.approx(0.0, abs=1e-6)


def test_a_curve_without_times_says_what_its_constant_speed_makes_up(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    p, _ = compound_cycloid(360)
    f = tmp_path / "xy.csv"
    f.write_text("x,y\n" + "\n".join(f"{a:.17g},{b:.17g}" for a, b in p))
    code, out, err = run(capsys, "evaluate", "--curve", str(f))
    assert code == 0, err
    lines = out.splitlines()
    assert lines[1].startswith("  the curve has no times: the foot is taken to move at constant speed along it")
    assert "(I, theta1, theta2, the feature points, the stance, MSE)" in lines[2]
    cons = next(ln for ln in lines if ln.startswith("  constraints (<= 0 satisfied)"))
    assert cons.endswith(" psi2 " + cons.rsplit(" psi2 ", 1)[1]) and not cons.endswith(" 1")
    f.write_text("x,y,t\n" + "\n".join(f"{a:.17g},{b:.17g},{k / 180:.17g}" for k, (a, b) in enumerate(p)))
    code, out, err = run(capsys, "evaluate", "--curve", str(f))
    assert code == 0 and "no times" not in out


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("0,0\n1,0\n", "at least 4"),
        ("0,0\n1,x\n1,1\n0,1\n", "not a number"),
        ("0,0\n1,0\n2,0\n3,0\n40,0\n", "open curve"),
        ("0,0\n1,0\nnan,1\n0,1\n", "NaN"),
        ("0;0\n1;0\n1;1\n0;1\n", "got 1 (the columns must be separated by commas)"),
        # A spreadsheet in a European locale (lab rehearsal: "'9002;1' is not a number").
        ("x;y\n1,9002;1,4698\n0;0\n1;1\n0;1\n", "data row 1 '1,9002;1,4698' has ';' between columns and ',' as the "
         "decimal point: save the CSV with ',' between columns and '.' as the decimal point"),
    ],
)
def test_bad_csv_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, fragment: str
) -> None:
    f = tmp_path / "bad.csv"
    f.write_text(text)
    code, out, err = run(capsys, "evaluate", "--curve", str(f))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("clm: error: ") and fragment in err


def test_a_cycloid_parameter_given_twice_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    # The last one won silently, though a design JSON with a key twice is refused.
    code, _, err = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--target", "cycloid:L=300,H=90,L=200")
    assert code == 2 and err == "clm: error: cycloid parameter L is given twice in 'cycloid:L=300,H=90,L=200'\n"


def test_a_huge_value_is_printed_in_a_few_digits(capsys: pytest.CaptureFixture[str]) -> None:
    from core.cli.evaluate import _fmt

    # A 1e300 mm target printed 300 digits; such a target is refused now (session 31: L, H <= 1e6 mm, as a config's),
    # but a value past 1e9 (a speed over a tiny period) still prints in a few digits.
    assert _fmt(5e299) == "5e+299" and _fmt(1234.5678) == "1234.568"
    code, _, err = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--target", "cycloid:L=1e300")
    assert code == 2 and err.count("\n") == 1 and "must be at most 1e+06 mm" in err


def test_bad_options_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["--obstacle", "-1", "5"], ["--period", "0"], ["--target", "cycloid:L=x"], ["--samples", "3"]):
        code, _, err = run(capsys, "evaluate", "--preset", "stephenson1/X3", *argv)
        assert code == 2 and err.count("\n") == 1, argv


def test_an_unassemblable_design_is_a_result(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = get("stephenson1/X3").design()
    params = d.named(0) | {"r2": 5.0}
    f = tmp_path / "d.json"
    f.write_text(json.dumps({"mechanism": "stephenson1", "params": params, "output": d.output.to_dict()}))
    code, out, _ = run(capsys, "evaluate", "--design", str(f), "--json")
    data = json.loads(out)
    assert code == 0 and data["feasible"] is False and data["violation"] > 0
    assert data["S"] is None and data["mse"] is None  # NaN -> null
    assert not any(isinstance(v, float) and math.isnan(v) for v in data.values())
    # The table says why (it said "INFEASIBLE (violation 1)" and the reason was only in the JSON's components).
    _, out, _ = run(capsys, "evaluate", "--design", str(f))
    assert out.startswith(f"{f}: INFEASIBLE (violation {data['violation']:.4g}: does not assemble over the whole "
                          f"cycle (shortfall {data['kinematic_violation']:.3g} mm))")


def test_the_period_is_the_time_law_s_unless_given(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # cycloid:T=4 was printed in the header but the crank period stayed 2 s: the optimizer, which takes the
    # target's T as the crank period, had reported another impact I for the same design.
    from core.optimize.objectives import shape_metrics

    design = get("stephenson1/X3").design()
    code, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--target", "cycloid:T=4", "--json")
    slow = json.loads(out)
    assert code == 0 and slow["period"] == 4.0
    assert slow["I"] == pytest.approx(float(shape_metrics(design, "cycloid:L=300,H=100,T=4")["I"][0]), rel=1e-6)
    _, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--json")
    assert slow["I"] == pytest.approx(json.loads(out)["I"] / 2, rel=1e-9)  # velocities at half the crank speed
    _, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X3", "--target", "cycloid:T=4", "--period", "2",
                    "--json")
    assert json.loads(out)["period"] == 2.0  # given: it wins
    # A curve's own times set its period: the same points over 4 s move at half the speed.
    p, _ = compound_cycloid(360)
    for span in (2.0, 4.0):
        t = np.arange(360) * (span / 360)
        (tmp_path / f"c{span:g}.csv").write_text(
            "x,y,t\n" + "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for (a, b), c in zip(p, t, strict=True)))
    _, out2, _ = run(capsys, "evaluate", "--curve", str(tmp_path / "c2.csv"), "--json")
    _, out4, _ = run(capsys, "evaluate", "--curve", str(tmp_path / "c4.csv"), "--json")
    assert json.loads(out4)["period"] == 4.0 and json.loads(out2)["period"] == 2.0


def ellipse_csv(path, rx: float, ry: float, cy: float):
    """An x,y CSV (no times) of an ellipse with half-axes rx, ry about (0, cy); the path."""
    t = np.linspace(0.0, 2.0 * np.pi, 60, endpoint=False)
    path.write_text("\n".join(f"{rx * np.cos(a):.6f},{cy + ry * np.sin(a):.6f}" for a in t) + "\n")
    return path


def test_a_target_curve_in_metres_is_evaluated_with_a_warning(tmp_path, capsys):
    # Read as mm, a 0.18 m path became a 0.18 mm target: the studio said so, the CLI went on without a word.
    from core.cli import main
    from core.cli.design import _warn_target
    from core.kinematics.presets.preset import PAPER_PANTOGRAPH

    path = ellipse_csv(tmp_path / "foot_m.csv", 0.09, 0.03, 0.0)
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(path)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("clm: warning: target foot_m.csv: it spans 0.18 mm") and err.count("\n") == 1
    _warn_target(str(path), PAPER_PANTOGRAPH)  # what clm design says of its config's target
    assert "need scaling" in capsys.readouterr().err
    _warn_target("cycloid:L=300.0,H=100.0,T=2.0", PAPER_PANTOGRAPH)
    assert capsys.readouterr().err == ""
    _warn_target("cycloid:L=300.0,H=100.0,T=2000.0", PAPER_PANTOGRAPH)  # a config's T in ms (lab rehearsal)
    assert capsys.readouterr().err.startswith("clm: warning: target cycloid:L=300.0,H=100.0,T=2000.0: its times make "
                                              "one cycle 2000 s long")


def test_a_target_with_times_in_ms_is_evaluated_with_a_warning_and_one_beyond_any_crank_is_refused(tmp_path, capsys):
    # Rehearsal 8: times in ms made T = 2000 s and I a thousandth of itself, without a word; times in us failed
    # clm design's first stage (exit 1) where clm evaluate refused them.
    from core.analysis.targets import compound_cycloid
    from core.cli import main

    pts = compound_cycloid(120)[0]
    for unit, factor in (("ms", 1e3), ("us", 1e6)):
        t = np.arange(120) * (2.0 / 120) * factor
        (tmp_path / f"c_{unit}.csv").write_text("x,y,t\n" + "".join(f"{x},{y},{ti}\n" for (x, y), ti in zip(pts, t,
                                                                                                    strict=True)))
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(tmp_path / "c_ms.csv")]) == 0
    err = capsys.readouterr().err
    assert err.startswith("clm: warning: target c_ms.csv: its times make one cycle 2000 s long") and "in ms" in err
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(tmp_path / "c_us.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its times span 2e+06 s, where a crank period must be 1e-06 to 1e+06 s" in err


def test_a_target_that_would_walk_wrongly_in_the_leg_frame_gets_a_warning(tmp_path, capsys):
    # A path drawn clockwise, or a cycloid without the pantograph that puts its flat part at the bottom, was
    # optimized as given: the leg then pushes backward on the ground, or stands on its swing.
    from core.cli import main
    from core.cli.design import _warn_target
    from core.kinematics.model import IDENTITY

    cw = tmp_path / "cw.csv"
    lines = ellipse_csv(tmp_path / "ccw.csv", 150.0, 40.0, -150.0).read_text().splitlines()
    cw.write_text("\n".join(lines[::-1]) + "\n")
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(tmp_path / "ccw.csv")]) == 0
    assert capsys.readouterr().err == ""
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(cw)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("clm: warning: target cw.csv in the design's leg frame: it runs clockwise") \
        and err.count("\n") == 1
    _warn_target("cycloid", IDENTITY)
    assert "its flat part is at the top in the leg frame" in capsys.readouterr().err


def test_a_target_without_times_gets_the_optimizers_shape_error_and_only_the_papers_stride_its_s(tmp_path, capsys):
    # The optimizer's f1 for a target without times is the error at the best cyclic shift: without that row a run's
    # pick read 10.21 mm here against the run's 8.29. And "h_s / 300 mm, the paper's S" was printed for any target.
    from core.cli import main

    path = ellipse_csv(tmp_path / "foot.csv", 150.0, 40.0, -150.0)
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(path)]) == 0
    out = capsys.readouterr().out
    assert "the paper's S" not in out
    # The headline is the best phase's (the optimizer's f1); the error with the file's first point at t = 0 second,
    # said to mean nothing (rehearsal 4: a right target read 76.7 mm there, the same one upside down 24 mm).
    lines = [ln.split() for ln in out.splitlines() if "shape error" in ln]
    assert [" ".join(w[:5]) for w in lines] == ["shape error MSE, best phase", "shape error, its first point"]
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(path), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert float(lines[0][5]) == pytest.approx(rec["mse_phase"], abs=1e-3)
    assert float(lines[1][9]) == pytest.approx(rec["mse"], abs=1e-3)
    assert main(["evaluate", "--preset", "stephenson1/X3"]) == 0  # the paper's cycloid: times, the paper's S
    out = capsys.readouterr().out
    assert "best phase" not in out and "the paper's S" in out
    # The paper's stride is read from the target's parameters, not its name: a CSV named like the cycloid is not it,
    # and the cycloid written out with L = 300.0 is.
    named = ellipse_csv(tmp_path / "compound cycloid L=300 H=100 T=2.csv", 150.0, 40.0, -150.0)
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", str(named)]) == 0
    assert "the paper's S" not in capsys.readouterr().out
    for spec, papers in (("cycloid:L=300.0,H=80", True), ("cycloid:L=250", False), ("cycloid:H=100", True)):
        assert main(["evaluate", "--preset", "stephenson1/X3", "--target", spec]) == 0
        assert ("the paper's S" in capsys.readouterr().out) == papers


def test_an_rtclm_mode_names_its_height_and_target_and_the_gait_verdict_is_one_line(
        capsys: pytest.CaptureFixture[str]) -> None:
    """Rehearsal 3: `--mode auxiliary` printed "None: feasible", an RTCLM's h_m was not called h6 or h4, its S was
    printed as "the paper's S" of a 300 mm stride, and "feasible" stood above violated gait constraints without a
    word."""
    code, out, _ = run(capsys, "evaluate", "--preset", "rtclm/clm-case1", "--mode", "auxiliary")
    assert code == 0 and out.startswith("rtclm/clm-case1 (auxiliary mode): ")
    assert "h_m = h4" in out and "target 220 mm (case 1)" in out and "the paper's S" not in out
    code, out, _ = run(capsys, "evaluate", "--preset", "rtclm/clm-case1")
    assert "h_m = h6" in out and "target 50 mm" in out
    code, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X3")
    verdict = [ln for ln in out.splitlines() if ln.strip().startswith("gait constraints")]
    assert len(verdict) == 1 and verdict[0].endswith("1 unmet: landing angle theta1 >= 15 deg")  # 3.2 deg
    assert "h_m = " not in out and "the paper's S" in out
    code, out, _ = run(capsys, "evaluate", "--preset", "stephenson1/X0")
    assert [ln for ln in out.splitlines() if "gait constraints" in ln][0].endswith(": all met")
    code, out, _ = run(capsys, "simulate", "--preset", "rtclm/clm-case1", "--mode", "auxiliary")
    assert out.startswith("rtclm/clm-case1 (auxiliary mode): ")
    # Review of session 28: a design that does not assemble read "5 unmet", as if each had been measured and missed.
    code, out, _ = run(capsys, "evaluate", "--preset", "rtclm/case3")
    assert [ln for ln in out.splitlines() if "gait constraints" in ln][0].endswith(
        ": 5 not defined (order, theta1, theta2, h_bar, psi2: no well-defined bench trajectory)")
    # Its transmission angle is no number either (it read 0.0 deg, like a measured dead point; rehearsal 5).
    assert [ln.split()[3:5] for ln in out.splitlines() if "worst transmission angle" in ln] == [["n/a", "deg"]]


def test_an_rtclm_design_file_gets_the_five_cases_h4_whatever_its_path_says(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The case was read off the label with a regex: runs/showcase2/leg.json was given case 2's h4 (review)."""
    import json

    from core.formats.design import design_to_dict
    from core.kinematics.presets import get

    folder = tmp_path / "showcase2"
    folder.mkdir()
    (folder / "leg.json").write_text(json.dumps(design_to_dict(get("rtclm/clm-case1/auxiliary").design())))
    code, out, _ = run(capsys, "evaluate", "--design", str(folder / "leg.json"))
    assert code == 0 and "target 220 / 240 / 260 / 280 / 300 mm (cases 1-5)" in out
    code, out, _ = run(capsys, "evaluate", "--preset", "rtclm/case2", "--mode", "auxiliary")
    assert "target 240 mm (case 2)" in out


def test_a_folder_that_is_no_run_is_named_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Rehearsal 3: a folder without result.json read "cannot read result file '.../result.json'"."""
    code, _, err = run(capsys, "evaluate", "--design", str(tmp_path))
    assert code == 2 and err.strip() == (f"clm: error: {tmp_path} is a folder without a result.json: not a 'clm "
                                         "design --out' run; give a design JSON or a run's folder")


def test_a_target_csv_in_the_leg_frame_is_mapped_back_by_the_designs_output_stage(tmp_path, capsys):
    """--leg-frame applied to --curve only and was ignored with --target without a word (rehearsal 4): a foot path
    drawn as the bench view shows it is now mapped to the design frame by the design's own output stage."""
    from core.cli import main
    from core.kinematics.presets import get

    design = ellipse_csv(tmp_path / "d.csv", 150.0, 40.0, -60.0)
    pts = np.loadtxt(design, delimiter=",") + [150.0, 0.0]
    np.savetxt(design, pts, delimiter=",", fmt="%.9f")
    leg = tmp_path / "leg.csv"
    np.savetxt(leg, get("stephenson1/X3").design().output.apply(pts), delimiter=",", fmt="%.9f")
    got = {}
    for name, args in (("design", [str(design)]), ("leg", [str(leg), "--leg-frame"]), ("raw", [str(leg)])):
        assert main(["evaluate", "--preset", "stephenson1/X3", "--json", "--target", *args]) == 0
        got[name] = json.loads(capsys.readouterr().out)["mse_phase"]
    assert got["leg"] == pytest.approx(got["design"], abs=1e-6) and abs(got["raw"] - got["design"]) > 1.0
    assert main(["evaluate", "--preset", "stephenson1/X3", "--leg-frame"]) == 2  # the cycloid has no frame to map
    assert "--leg-frame applies to a --curve or a --target CSV" in capsys.readouterr().err


def test_a_design_whose_foot_stands_on_its_swing_is_evaluated_with_a_warning(tmp_path, capsys):
    # Rehearsal 8: the paper's X3 in a design file without "output" is read with the identity (k = 1): clm evaluate
    # printed h_s 101 mm, S 35 % and "feasible" without a word, where clm design warns of the same upside-down leg.
    from core.cli import main

    assert main(["presets", "show", "stephenson1/X3"]) == 0
    data = json.loads(capsys.readouterr().out)
    del data["output"]
    (tmp_path / "noout.json").write_text(json.dumps(data))
    assert main(["evaluate", "--design", str(tmp_path / "noout.json")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "noout.json: its foot path: its flat part is at the top in the leg frame" in err
    assert "without \"output\" is read with the identity" in err
    assert main(["evaluate", "--preset", "stephenson1/X3"]) == 0  # with its pantograph: nothing to say
    assert capsys.readouterr().err == ""


def test_a_design_can_be_piped_in():
    # Rehearsal 8: jq ... | clm evaluate --design - was refused ("design file '-' not found").
    import subprocess
    import sys

    def clm(*args, stdin=None):
        return subprocess.run([sys.executable, "-m", "core.cli", *args], input=stdin, capture_output=True, text=True,
                              timeout=300)

    design = clm("presets", "show", "stephenson1/X3").stdout
    piped = clm("evaluate", "--design", "-", "--json", stdin=design)
    named = clm("evaluate", "--preset", "stephenson1/X3", "--json")
    assert piped.returncode == 0, piped.stderr
    a, b = json.loads(piped.stdout), json.loads(named.stdout)
    assert a["h_s"] == b["h_s"] and a["params"] == b["params"]
    empty = clm("evaluate", "--design", "-", stdin="")  # nothing piped: one line, exit 2
    assert empty.returncode == 2 and empty.stderr.count("\n") == 1 and empty.stderr.startswith("clm: error: <stdin>")
    bad = clm("evaluate", "--design", "-", stdin="{nope")
    assert bad.returncode == 2 and bad.stderr.startswith("clm: error: <stdin>: not valid JSON")


def test_a_design_piped_in_never_reads_a_run_named_dash(tmp_path, monkeypatch):
    # Review of session 31: with --design -, run_h4 read a folder literally named "-" in the working directory and
    # called its h4 target "the run's".
    import core.formats.files as files
    from core.cli.simulate import run_h4, run_target

    run = tmp_path / "-"
    run.mkdir()
    (run / "result.json").write_text("{}")
    fake = {"pipeline": {"stages": [{"problem": {"name": "rtclm2", "options": {"h4_target": 333.0}}}]}}
    monkeypatch.setattr(files, "read_design_result", lambda path: fake)
    monkeypatch.chdir(tmp_path)
    assert run_h4(run) == 333.0  # a real path to that folder is a run
    assert run_h4(Path("-")) is None and run_target(Path("-")) is None


def test_unit_slips_in_a_cycloid_a_curve_or_an_obstacle_are_warned_of(tmp_path, capsys):
    # Lab rehearsal: cycloid:L=0.3,H=0.1 (m), T=2000 (ms) and --obstacle 0.025 0.025 (m) were evaluated without a
    # word, where the same slips in a CSV are warned of; a --curve in m or ms too (review of session 31).
    from core.analysis.targets import compound_cycloid
    from core.cli import main

    for spec, said in (("cycloid:L=0.3,H=0.1,T=2", "it spans 0.3 mm"),
                       ("cycloid:L=300,H=100,T=2000", "its times make one cycle 2000 s long")):
        assert main(["evaluate", "--preset", "stephenson1/X3", "--target", spec]) == 0
        err = capsys.readouterr().err
        assert err.startswith(f"clm: warning: target {spec}: {said}") and err.count("\n") == 1, err
    assert main(["evaluate", "--preset", "stephenson1/X3", "--target", "cycloid:L=250,H=80,T=1.5"]) == 0
    assert capsys.readouterr().err == ""
    t = np.linspace(0.0, 2.0, 120, endpoint=False)
    pts = compound_cycloid(120)[0]
    for name, scale, said in (("ms.csv", (1.0, 1000.0), "its times make one cycle 2000 s long"),
                              ("m.csv", (0.001, 1.0), "it spans 0.3 mm")):
        rows = "\n".join(f"{x * scale[0]:.9f},{y * scale[0]:.9f},{k * scale[1]:.6f}"
                         for k, (x, y) in zip(t, pts, strict=True))
        (tmp_path / name).write_text("x,y,t\n" + rows + "\n")
        assert main(["evaluate", "--curve", str(tmp_path / name)]) == 0
        err = capsys.readouterr().err
        assert err.startswith(f"clm: warning: curve {name}: {said}"), err
    assert main(["evaluate", "--preset", "stephenson1/X3", "--obstacle", "0.025", "0.025"]) == 0
    assert capsys.readouterr().err.startswith("clm: warning: --obstacle 0.025 0.025: an obstacle under 1 mm")


def test_a_design_in_metres_or_degrees_is_warned_of_where_it_is_read(tmp_path, capsys):
    # Lab rehearsal: a design file in metres read "feasible" with a 0.3 mm stride, and one with angles in degrees
    # (b = 29.8 "rad") was another leg, both without a word; clm export then advised smaller pins.
    from core.cli import main
    from core.formats.design import design_from_dict, design_to_dict, unit_note
    from core.kinematics.presets import get

    x3 = get("stephenson1/X3").design()
    d = design_to_dict(x3)
    kinds = {p.name: p.kind for p in x3.mechanism.params}
    metres = dict(d, params={k: v / 1000.0 if kinds[k] != "angle" else v for k, v in d["params"].items()},
                  output=dict(d["output"], **{k: d["output"][k] / 1000.0 for k in ("cx", "cy") if k in d["output"]}))
    degrees = dict(d, params={k: math.degrees(v) if kinds[k] == "angle" else v for k, v in d["params"].items()})
    (tmp_path / "metres.json").write_text(json.dumps(metres))
    (tmp_path / "degrees.json").write_text(json.dumps(degrees))
    for cmd in (["simulate"], ["evaluate"], ["export", "--svg", str(tmp_path / "x.svg")]):
        assert main([*cmd, "--design", str(tmp_path / "metres.json")]) in (0, 2)
        err = capsys.readouterr().err
        assert err.startswith(f"clm: warning: {tmp_path / 'metres.json'}: its foot path: it spans 0.3"), (cmd, err)
        main([*cmd, "--design", str(tmp_path / "degrees.json")])
        err = capsys.readouterr().err
        assert err.startswith(f"clm: warning: {tmp_path / 'degrees.json'}: ") and "probably degrees" in err, (cmd, err)
        assert main([*cmd, "--preset", "stephenson1/X3"]) == 0
        assert "stephenson1/X3:" not in capsys.readouterr().err  # (export's hole advice is its own)
    assert unit_note(design_from_dict(degrees)).startswith("b = ")  # the first angle beyond one turn is named
