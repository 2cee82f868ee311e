"""The `clm` command line: presets, simulate, the design JSON format, and one-line input errors."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.cli import jsonable, main
from core.formats.design import check_params, design_from_dict
from core.kinematics import presets
from core.kinematics.mechanisms.stephenson import STEPHENSON1

ROOT = Path(__file__).resolve().parents[1]
X3 = presets.get("stephenson1/X3")


def clm(*argv: str) -> subprocess.CompletedProcess[str]:
    """`clm` in a fresh interpreter, as a user runs it."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "core.cli", *argv], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120
    )


def run_in_process(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def strict_json(text: str) -> object:
    """Parse JSON and fail on NaN/Infinity, which are not JSON."""

    def refuse(name: str) -> None:
        raise AssertionError(f"non-JSON constant {name} in output")

    return json.loads(text, parse_constant=refuse)


def x3_file(tmp_path: Path, **changes: object) -> Path:
    d = {"mechanism": "stephenson1", "params": dict(zip(STEPHENSON1.param_names, X3.values, strict=True))}
    d.update(changes)
    path = tmp_path / "design.json"
    path.write_text(json.dumps(d))
    return path


# --- presets -----------------------------------------------------------------------------------


def test_presets_table_lists_every_preset_with_its_mechanism(capsys):
    code, out, _ = run_in_process(capsys, "presets")
    assert code == 0
    rows = {line.split()[0]: line.split()[1] for line in out.splitlines()[1:]}
    assert rows == {name: p.mechanism.name for name, p in presets.PRESETS.items()}


def test_in_a_terminal_the_presets_table_fits_its_width(capsys):
    """Rehearsal 3: the paper's RTCLM rows (300-character sources) wrapped the table unreadably in a terminal.
    Cut to the width there, with a line saying how to see them whole; piped (above), nothing is cut."""
    from core.cli.presets import listing

    items = sorted(presets.PRESETS.values(), key=lambda p: p.name)
    text = listing(items, 100)
    lines = text.splitlines()
    assert all(len(line) <= 100 for line in lines) and any(line.endswith("…") for line in lines)
    assert lines[-1] == "(sources cut to the terminal's width: 'clm presets --wide' prints them whole)"
    assert {line.split()[0] for line in lines[1:-1]} == set(presets.PRESETS)
    whole = listing(items)
    assert max(len(line) for line in whole.splitlines()) > 200 and "…" not in whole


def test_presets_json_lists_every_preset_as_a_loadable_design(capsys):
    code, out, _ = run_in_process(capsys, "presets", "--json")
    assert code == 0
    # The flag before or after "list" alike (before it, the table used to print).
    for argv in (("presets", "--json", "list"), ("presets", "list", "--json")):
        assert run_in_process(capsys, *argv)[1] == out
    items = strict_json(out)
    assert isinstance(items, list)
    assert sorted(d["name"] for d in items) == sorted(presets.PRESETS)
    for d in items:
        p = presets.get(d["name"])
        design = design_from_dict(d)
        assert design.mechanism is p.mechanism
        np.testing.assert_array_equal(design.params[0], p.values)
        assert design.output == p.output


def test_presets_show_gives_names_units_output_and_source(capsys):
    code, out, _ = run_in_process(capsys, "presets", "show", "stephenson1/X3")
    assert code == 0
    d = strict_json(out)
    assert isinstance(d, dict)
    assert d["mechanism"] == "stephenson1"
    assert list(d["params"]) == list(STEPHENSON1.param_names)
    assert d["units"]["r1"] == "mm" and d["units"]["b"] == "rad"
    assert d["output"] == {"k": -1.0, "ox": 150.0, "oy": 0.0}
    assert "B-1" in d["source"]


def test_a_preset_name_alone_shows_it_and_a_wrong_one_suggests_the_nearest(capsys):
    # "clm presets stephenson1/X3" answered "invalid choice (choose from 'list', 'show')", and an unknown name
    # listed all ~150 presets on one line.
    code, out, _ = run_in_process(capsys, "presets", "stephenson1/X3")
    assert code == 0 and strict_json(out)["name"] == "stephenson1/X3"
    code, _, err = run_in_process(capsys, "presets", "show", "stephenson1/X9")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("clm: error: unknown preset 'stephenson1/X9'; did you mean stephenson1/X3, ")
    assert err.rstrip().endswith(f"('clm presets' lists all {len(presets.PRESETS)})") and "rtclm" not in err
    code, _, err = run_in_process(capsys, "presets", "zzz")  # nothing near: the count alone
    assert code == 2 and "did you mean" not in err and "lists all" in err
    code, out, _ = run_in_process(capsys, "presets", "list")  # the actions still work
    assert code == 0 and out.startswith("NAME")


# --- simulate ----------------------------------------------------------------------------------


def test_simulate_x3_reproduces_the_paper_path_extent():
    """Issue 2's fidelity numbers, through the whole CLI in a fresh interpreter."""
    r = clm("simulate", "--preset", "stephenson1/X3", "--json")
    assert r.returncode == 0, r.stderr
    d = strict_json(r.stdout)
    assert isinstance(d, dict)
    p = np.array(d["point_design"], dtype=float)
    assert p.shape == (360, 2)
    assert abs(np.ptp(p[:, 0]) - 298.94) <= 0.05
    assert abs(p[:, 1].min() - (-101.04)) <= 0.05
    assert d["feasible"] is True and d["violation"] == 0.0 and all(d["valid"])


def test_simulate_json_shapes_angles_and_leg_frame(capsys):
    code, out, _ = run_in_process(capsys, "simulate", "--preset", "stephenson1/X3", "--json", "--samples", "12")
    assert code == 0
    d = strict_json(out)
    assert isinstance(d, dict)
    np.testing.assert_allclose(d["theta"], 2 * np.pi * np.arange(12) / 12)
    joints = np.array(d["joints"], dtype=float)
    assert joints.shape == (12, len(d["joint_names"]), 2)
    # The tracked point is the last joint here (P); the leg frame is the pantograph k = -1 about (150, 0).
    p, leg = np.array(d["point_design"]), np.array(d["point_leg"])
    np.testing.assert_allclose(joints[:, d["joint_names"].index("P")], p)
    np.testing.assert_allclose(leg, np.array([300.0, 0.0]) - p, atol=1e-12)
    np.testing.assert_allclose(d["dpoint_leg"], -np.array(d["dpoint_design"]), atol=1e-12)
    # Ground pivot A sits at (x_a, y_a) for every sample.
    np.testing.assert_allclose(joints[:, 0], np.tile([d["params"]["x_a"], d["params"]["y_a"]], (12, 1)))


def test_design_file_by_name_by_list_and_shown_preset_all_agree(tmp_path, capsys):
    runs = []
    shown = tmp_path / "shown.json"
    main(["presets", "show", "stephenson1/X3"])
    shown.write_text(capsys.readouterr().out)
    by_list = tmp_path / "list.json"
    # Partial output: oy takes the identity's 0.
    by_list.write_text(json.dumps({"mechanism": S1, "params": list(X3.values), "output": {"k": -1, "ox": 150}}))
    by_name = x3_file(tmp_path, output={"k": -1.0, "ox": 150, "oy": 0})
    for argv in (["--preset", "stephenson1/X3"], ["--design", str(shown)], ["--design", str(by_list)],
                 ["--design", str(by_name)]):
        code, out, err = run_in_process(capsys, "simulate", "--json", "--samples", "24", *argv)
        assert code == 0, err
        d = strict_json(out)
        assert isinstance(d, dict)
        runs.append(d)
    for d in runs[1:]:
        assert d["params"] == runs[0]["params"] and d["output"] == runs[0]["output"]
        assert d["joints"] == runs[0]["joints"] and d["point_leg"] == runs[0]["point_leg"]


def test_design_without_output_uses_the_identity(tmp_path, capsys):
    code, out, _ = run_in_process(capsys, "simulate", "--json", "--samples", "8", "--design", str(x3_file(tmp_path)))
    assert code == 0
    d = strict_json(out)
    assert isinstance(d, dict)
    assert d["output"] == {"k": 1.0, "ox": 0.0, "oy": 0.0}
    assert d["point_leg"] == d["point_design"]


def test_unassemblable_design_prints_null_not_nan_and_says_why(tmp_path, capsys):
    # A crank longer than the loop allows: C cannot close for part of the revolution.
    path = x3_file(tmp_path, params=dict(zip(STEPHENSON1.param_names, X3.values, strict=True)) | {"r1": 80.0})
    code, out, _ = run_in_process(capsys, "simulate", "--json", "--samples", "36", "--design", str(path))
    assert code == 0
    d = strict_json(out)
    assert isinstance(d, dict)
    assert d["feasible"] is False and d["violation"] > 0
    assert not all(d["valid"]) and any(d["valid"])
    for ok, point in zip(d["valid"], d["point_design"], strict=True):
        assert (point[0] is not None) == ok
    code, out, _ = run_in_process(capsys, "simulate", "--samples", "36", "--design", str(path))
    assert code == 0
    assert "does not assemble" in out and "dyad C cannot close" in out


def test_an_rtclm_without_a_switching_state_says_which_loop_cannot_close(capsys):
    from core.kinematics.mechanisms.rtclm import first_loop_shortfall

    design = presets.get("rtclm/case2-CMOES").design()  # the paper's printed values: loop A-B-C-D is short
    short = first_loop_shortfall(design.params)[0]
    code, out, _ = run_in_process(capsys, "simulate", "--preset", "rtclm/case2-CMOES")
    assert code == 0
    assert (f"does not assemble: loop A-B-C-D cannot close over a whole turn of crank AB, so the legs have no "
            f"switching state (short by {short:.3g} mm)") in out and short > 1.0


def test_summary_of_an_assembling_preset(capsys):
    code, out, _ = run_in_process(capsys, "simulate", "--preset", "stephenson1/X3")
    assert code == 0
    assert "assembles over the whole revolution" in out
    assert "width 298.94 mm" in out


def test_jsonable_maps_nan_and_inf_to_null():
    arr = np.array([[1.5, np.nan], [np.inf, -np.inf]])
    assert jsonable({"a": arr, "b": np.float64("nan"), "c": (np.int64(3), True)}) == {
        "a": [[1.5, None], [None, None]],
        "b": None,
        "c": [3, True],
    }


# --- errors: one line on stderr, exit code 2, never a traceback --------------------------------

GOOD = dict(zip(STEPHENSON1.param_names, X3.values, strict=True))


def _file(content: object) -> str:
    return content if isinstance(content, str) else json.dumps(content)


S1 = "stephenson1"
FILE = ["simulate", "--design", "DESIGN"]  # DESIGN is replaced by the path of the case's file content
NAN_R3 = '{"mechanism": "stephenson1", "params": ' + json.dumps(GOOD).replace('"r3": 99.62', '"r3": NaN') + "}"

ERRORS: list[tuple[str, list[str], object | None, str]] = [
    # (case, argv, file content or None, expected fragment of the message)
    ("unknown preset", ["simulate", "--preset", "stephenson1/X99"], None, "unknown preset 'stephenson1/X99'"),
    ("unknown preset shown", ["presets", "show", "nope"], None, "unknown preset 'nope'"),
    ("unknown mechanism", FILE, {"mechanism": "hexapod", "params": []}, "unknown mechanism 'hexapod'"),
    ("too few params", FILE, {"mechanism": S1, "params": list(X3.values[:15])}, "stephenson1 takes 16 parameters"),
    ("too many params", FILE, {"mechanism": S1, "params": [*X3.values, 1.0]}, "got 17"),
    ("unknown name", FILE, {"mechanism": S1, "params": GOOD | {"r13": 1.0}}, "unknown parameter 'r13'"),
    ("missing name", FILE, {"mechanism": S1, "params": {k: v for k, v in GOOD.items() if k != "r7"}},
     "missing parameter 'r7' (mm)"),
    ("nan", FILE, NAN_R3, "r3 (mm) must be finite"),
    ("infinite angle", FILE, {"mechanism": S1, "params": GOOD | {"b": 1e999}}, "b (rad) must be finite"),
    ("astronomic length", FILE, {"mechanism": S1, "params": GOOD | {"r1": 1e300}}, "r1 must be within +-1e+06 mm"),
    ("astronomic angle", FILE, {"mechanism": S1, "params": GOOD | {"g": -2e6}}, "g must be within +-1e+06 rad"),
    ("negative length", FILE, {"mechanism": S1, "params": GOOD | {"r1": -5}}, "must be > 0 mm, got -5"),
    ("zero length", FILE, {"mechanism": S1, "params": GOOD | {"r9": 0}}, "r9 is a length and must be > 0 mm"),
    ("string value", FILE, {"mechanism": S1, "params": GOOD | {"r2": "88"}}, "r2 must be a number (mm)"),
    ("params not a list", FILE, {"mechanism": S1, "params": 3}, "params must be an object"),
    ("malformed json", FILE, '{"mechanism": "stephenson1", "params": [1, 2,', "not valid JSON"),
    ("not an object", FILE, [1, 2, 3], "a design must be a JSON object"),
    ("no params", FILE, {"mechanism": S1}, "design has no 'params'"),
    ("unknown key", FILE, {"mechanism": S1, "params": GOOD, "parms": 1}, "unknown design key 'parms'"),
    ("wrong unit", FILE, {"mechanism": S1, "params": GOOD, "units": {"r1": "cm"}}, "r1 is given in 'cm'"),
    ("unit of no parameter", FILE, {"mechanism": S1, "params": GOOD, "units": {"r1": "mm", "zz": "mm"}},
     "units names 'zz', which stephenson1 does not have"),
    ("zero ratio", FILE, {"mechanism": S1, "params": GOOD, "output": {"k": 0}}, "output k (ratio) must be non-zero"),
    ("unknown output key", FILE, {"mechanism": S1, "params": GOOD, "output": {"kk": 1}}, "unknown output key 'kk'"),
    ("mirror not a bool", FILE, {"mechanism": S1, "params": GOOD, "output": {"mirror": "yes"}},
     "output mirror must be true or false, got 'yes'"),
    ("missing file", ["simulate", "--design", "no/such/file.json"], None, "not found"),
    ("no source", ["simulate"], None, "one of the arguments --preset --design is required"),
    ("bad samples", ["simulate", "--preset", "stephenson1/X3", "--samples", "0"], None, "--samples must be between"),
    ("one sample is no revolution", ["simulate", "--preset", "stephenson1/X3", "--samples", "1"], None,
     "--samples must be between 8 and"),
    ("odd samples for evaluate", ["evaluate", "--preset", "stephenson1/X3", "--samples", "9"], None,
     "--samples must be an even number between 8 and 100000"),
    ("unknown command", ["fly"], None, "invalid choice: 'fly'"),
]


def _argv(argv: list[str], content: object | None, tmp_path: Path) -> list[str]:
    if content is None:
        return argv
    path = tmp_path / "design.json"
    path.write_text(_file(content))
    return [str(path) if a == "DESIGN" else a for a in argv]


def _assert_one_line_error(code: int, out: str, err: str, fragment: str) -> None:
    assert code == 2
    assert out == ""
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("clm: error: ")
    assert fragment in lines[0]


@pytest.mark.parametrize(("case", "argv", "content", "fragment"), ERRORS, ids=[e[0] for e in ERRORS])
def test_input_error_in_process(case, argv, content, fragment, tmp_path, capsys):
    code, out, err = run_in_process(capsys, *_argv(argv, content, tmp_path))
    _assert_one_line_error(code, out, err, fragment)


@pytest.mark.parametrize(("case", "argv", "content", "fragment"), ERRORS, ids=[e[0] for e in ERRORS])
def test_input_error_in_a_fresh_interpreter(case, argv, content, fragment, tmp_path):
    r = clm(*_argv(argv, content, tmp_path))
    _assert_one_line_error(r.returncode, r.stdout, r.stderr, fragment)


def test_help_exits_zero(capsys):
    assert main(["--help"]) == 0
    assert "simulate" in capsys.readouterr().out


def test_installed_console_script_runs():
    """The `clm` entry point of pyproject.toml, where the package is installed (the project venv)."""
    exe = Path(sys.executable).with_name("clm")
    if not exe.exists():
        pytest.skip("clm is not installed next to this interpreter")
    r = subprocess.run([str(exe), "presets"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "stephenson1/X3" in r.stdout


# --- core.formats.design directly --------------------------------------------------------------------


def test_every_preset_passes_validation():
    for p in presets.PRESETS.values():
        check_params(p.mechanism, p.values)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, STEPHENSON1.n_params - 1), st.sampled_from([0.0, -1e-9, -3.0, math.nan, math.inf, 1e300, -2e6]))
def test_a_bad_entry_is_named_with_its_unit(j, bad):
    spec = STEPHENSON1.params[j]
    row = np.array(X3.values)
    row[j] = bad
    if spec.kind != "length" and abs(bad) <= 1e6:
        check_params(STEPHENSON1, row)  # signed offsets, positions and angles may be <= 0
        return
    with pytest.raises(ValueError, match=rf"^{spec.name} .*{spec.unit}"):
        check_params(STEPHENSON1, row)


def test_population_errors_name_the_member():
    pop = np.tile(X3.values, (3, 1))
    pop[2, 4] = -1.0
    with pytest.raises(ValueError, match="r1 of design 2 is a length"):
        check_params(STEPHENSON1, pop)


def test_a_design_file_with_a_key_twice_is_refused_not_read_as_its_last_value(capsys, tmp_path):
    code, out, _ = run_in_process(capsys, "presets", "show", "stephenson1/X3")
    assert code == 0 and '"r1": ' in out
    text = out.replace('"r1": ', '"r1": 999.0, "r1": ', 1)  # a valid design either way
    (tmp_path / "d.json").write_text(text)
    code, _, err = run_in_process(capsys, "simulate", "--design", str(tmp_path / "d.json"))
    assert code == 2 and err.strip().endswith("key 'r1' appears twice in one object")


def test_simulate_says_a_dyad_that_never_closes_has_no_transmission_angle(tmp_path: Path, capsys):
    d = presets.get("stephenson1/X3").design()
    f = tmp_path / "d.json"
    f.write_text(json.dumps({"mechanism": "stephenson1", "params": d.named(0) | {"r4": 400.0},
                             "output": d.output.to_dict()}))
    assert main(["simulate", "--design", str(f)]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("dyad C:"))
    assert line.endswith("never closes (no transmission angle)") and "deg" not in line
    assert main(["simulate", "--preset", "stephenson1/X3"]) == 0
    assert "dyad C: margin 3.24 mm, transmission angle 44.7..158.6 deg" in capsys.readouterr().out


def test_version_names_the_package_and_the_code_digest(capsys):
    # Rehearsal 8: a CI log could not say which CLM had run (clm --version: "the following arguments are required").
    from core import CODE_DIGEST

    assert main(["--version"]) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("clm ") and out.endswith(f"(code {CODE_DIGEST})")


def test_a_design_file_with_a_null_output_reads_as_one_without(tmp_path, capsys):
    # Rehearsal 8: the published schema allows "output": null, which the loader refused.
    assert main(["presets", "show", "jansen"]) == 0
    data = json.loads(capsys.readouterr().out)
    data["output"] = None
    (tmp_path / "null.json").write_text(json.dumps(data))
    del data["output"]
    (tmp_path / "none.json").write_text(json.dumps(data))
    outs = []
    for name in ("null.json", "none.json"):
        assert main(["evaluate", "--design", str(tmp_path / name), "--json"]) == 0
        outs.append({k: v for k, v in json.loads(capsys.readouterr().out).items() if k != "params"})
    assert outs[0] == outs[1] and outs[0]["output"]["k"] == 1.0


def test_presets_show_takes_json_after_its_name_as_the_other_commands_do(capsys):
    assert main(["presets", "show", "stephenson1/X3", "--json"]) == 0
    after = json.loads(capsys.readouterr().out)
    assert main(["presets", "show", "stephenson1/X3"]) == 0
    assert after == json.loads(capsys.readouterr().out)
