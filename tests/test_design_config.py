"""Design configurations: strict validation (errors name the key), and the shipped examples parse."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from core.cli import main
from core.formats.config import load_config, parse_config
from core.kinematics.mechanisms import MECHANISMS

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "configs"


def base() -> dict:  # type: ignore[type-arg]
    return {
        "name": "t",
        "mechanism": "stephenson1",
        "seed": 1,
        "n_samples": 72,
        "algorithm": {"name": "nsga2", "pop_size": 10},
        "stages": [
            {"name": "predesign", "box": "global", "n_gen": 2, "pick": "best:f1"},
            {"name": "subtask1", "box": "subtask1", "n_gen": 2},
            {"name": "subtask2", "box": "subtask2", "n_gen": 2, "options": {"f1_max": "start+0.5"}},
        ],
    }


def with_(path: str, value: object) -> dict:  # type: ignore[type-arg]
    d = base()
    cur = d
    keys = path.split(".")
    for k in keys[:-1]:
        cur = cur[int(k)] if k.isdigit() else cur.setdefault(k, {})
    if value is KeyError:
        del cur[keys[-1]]
    else:
        cur[keys[-1]] = value
    return d


BAD = [
    ("colour", "red", "colour: unknown key"),
    ("mechanism", "hoeken", "mechanism: unknown mechanism"),
    ("mechanism", KeyError, "mechanism: missing"),
    ("preset", "stephenson3/paper", "preset: preset is a stephenson3 design"),
    ("seed", -1, "seed: must be >= 0"),
    ("seed", 1.5, "seed: expected an integer"),
    ("n_samples", 73, "n_samples: must be even"),
    ("backend", "gpu", "backend: 'gpu' is not one of"),
    ("method", "annealing", "method: 'annealing' is not one of"),
    ("output.k", 0.0, "output.k: must be non-zero"),
    ("output.z", 1.0, "output.z: unknown key"),
    ("target.curve", "missing.csv", "target.curve: file"),
    ("target.L", -300.0, "target.L: must be > 0"),
    ("target.H", "tall", "target.H: expected a number"),
    ("bounds.r1", [200.0, 100.0], "bounds.r1: impossible bounds"),
    ("bounds.r1", [-5.0, 100.0], "bounds.r1: a length must stay > 0"),
    ("bounds.r1", [0.0, 100.0], "bounds.r1: a length must stay > 0"),
    ("stages.1.pick", 10, "stages[1].pick: member 10 does not exist"),  # pop 10: members 0..9
    ("bounds.r1", 5.0, "bounds.r1: expected [lower, upper]"),
    ("bounds.q7", [0.0, 1.0], "bounds.q7: unknown key"),
    ("algorithm.name", "simplex", "algorithm.name: 'simplex' is not one of"),
    ("algorithm.pop_size", 1, "algorithm.pop_size: must be >= 2"),
    ("algorithm.options.mutation_rate", 0.1, "algorithm.options.mutation_rate: unknown key"),
    ("algorithm.options.crossover_eta", "high", "algorithm.options.crossover_eta: expected a number"),
    ("algorithm.options.crossover_prob", 2.0, "algorithm.options.crossover_prob: must be <= 1"),
    ("stages", [], "stages: missing"),
    ("stages.0.n_gen", 0, "stages[0].n_gen: must be >= 1"),
    ("stages.0.n_gen", "many", "stages[0].n_gen: expected an integer"),
    ("stages.0.problem", "subtask9", "stages[0].problem: unknown problem"),
    ("stages.0.box", "local", "stages[0].box: 'local' is not"),
    ("stages.0.box", {"s": 0.1}, "stages[0].box: a box table needs both"),
    ("stages.0.box", {"s": -0.1, "d": 5.0}, "stages[0].box.s: must be > 0"),
    ("stages.0.pick", "best:speed", "stages[0].pick: 'best:speed': problem 'predesign' reports no metric 'speed'"),
    ("stages.0.pick_where", {"I_max": "low"}, "stages[0].pick_where.I_max: expected a number"),
    ("stages.0.pick_where", {"I": 1.0}, "stages[0].pick_where.I: a limit is '<metric>_max' or '<metric>_min'"),
    ("stages.0.pick_where", {"dh6_max": 1.0}, "stages[0].pick_where.dh6_max: 'dh6_max': problem 'predesign' "
     "reports no metric 'dh6'"),
    ("stages.0.pick_where", 1.0, "stages[0].pick_where: expected a table"),
    ("stages.0.starts", 3, "stages[0].starts: expected a table"),
    ("stages.0.starts", {"until": "subtask1", "select": "best:S"}, "stages[0].starts.n: missing"),
    ("stages.0.starts", {"n": 0, "select": "best:S"}, "stages[0].starts.n: must be >= 1"),
    ("stages.0.starts", {"n": True, "select": "best:S"}, "stages[0].starts.n: expected an integer"),
    ("stages.0.starts", {"n": 2, "select": "best:S", "seeds": 3}, "stages[0].starts.seeds: unknown key"),
    ("stages.0.starts", {"n": 2}, "stages[0].starts.select: missing"),
    ("stages.0.starts", {"n": 2, "select": "knee"}, "stages[0].starts.select: 'knee': use 'best:<metric>'"),
    ("stages.1.starts", {"n": 2, "until": "predesign", "select": "best:S"},
     "stages[1].starts.until: 'predesign' is not this stage or a later one"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:fd"},
     "stages[0].starts.select: 'best:fd': problem 'subtask2' reports no metric 'fd'"),
    ("stages.0.starts", {"n": 2, "until": "subtask1", "select": "best:S", "where": {"I_top": 1.0}},
     "stages[0].starts.where.I_top: a limit is"),
    ("stages.0.starts", {"n": 2, "until": "subtask1", "select": "best:S", "where": {"I_max": [1.0]}},
     "stages[0].starts.where.I_max: expected a number"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask2", "keep": 1,
                                                                                    "by": "best:f1"}},
     "stages[0].starts.screen.after: 'subtask2' is not a stage of the block before its last one"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask1", "keep": 3,
                                                                                    "by": "best:f1"}},
     "stages[0].starts.screen.keep: keeps 3 of only 2 chains"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask1", "keep": 1,
                                                                                    "by": "best:h_s2"}},
     "stages[0].starts.screen.by: 'best:h_s2': problem 'subtask1' reports no metric 'h_s2'"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask1", "keep": 1}},
     "stages[0].starts.screen.by: missing"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask1", "keep": 1,
                         "by": "best:f1", "where": {"h_s2_max": 1.0}}},
     "stages[0].starts.screen.where.h_s2_max: 'h_s2_max': problem 'subtask1' reports no metric 'h_s2'"),
    ("stages.0.starts", {"n": 2, "until": "subtask2", "select": "best:S", "screen": {"after": "subtask1", "keep": 1,
                                                                                    "by": "best:f1", "top": 1}},
     "stages[0].starts.screen.top: unknown key"),
    ("stages.0.pick", "random", "stages[0].pick: unknown pick rule"),
    # A member past the population was found only after the stages before it ran, and nothing was written.
    ("stages.1.pick", 10**6, "stages[1].pick: member 1000000 does not exist: the stage keeps"),
    ("stages.0.stop_below", [1.0], "stages[0].stop_below: expected 2 numbers"),
    ("stages.0.fixed", ["x_z"], "stages[0].fixed[0]: stephenson1 has no parameter 'x_z'"),
    # Nothing left to search: mutation divided by zero free variables after the earlier stages had run.
    ("stages.1.fixed", list(MECHANISMS["stephenson1"].param_names),
     "stages[1].fixed: every parameter of stephenson1 is fixed: leave at least one free"),
    # A population of 10**8 filled the machine's memory before any message.
    ("algorithm.pop_size", 10**8, "algorithm.pop_size: must be <= 100000"),
    ("stages.0.algorithm.pop_size", 100_001, "stages[0].algorithm.pop_size: must be <= 100000"),
    ("stages.0.n_gen", 10**23, "stages[0].n_gen: must be <= 1000000"),
    ("stages.0.speed", 3, "stages[0].speed: unknown key"),
    ("rtclm", {"h6": 90.0}, "rtclm: the h6/h4 targets are for the reconfigurable leg (mechanism rtclm), not "
     "stephenson1"),
    ("stages.1.name", "predesign", "stages[1].name: duplicate stage name"),
    ("stages.2.options.f1_max", "start-1", "stages[2].options.f1_max: 'start-1' is not a relative limit"),
    ("stages.2.options.f1_max", -2.0, "stages[2].options.f1_max: must be >= 0"),
    ("stages.2.options.f9_max", 1.0, "stages[2].options.f9_max: unknown key"),
    ("stages.2.options.place", "somewhere", "stages[2].options: place must be"),
    ("stages.2.options.eq30", 1, "stages[2].options.eq30: expected true or false"),
    ("seed", 10**30, "seed: must be <= 4294967295"),
    ("n_samples", 100_000_000, "n_samples: must be <= 100000"),
    ("target.L", float("inf"), "target.L: must be finite"),
    # Past the analysis' domain the first stage failed (exit 1, a failed result written) or "completed" on overflowed
    # numbers (rehearsal 8).
    ("target.T", 1e-300, "target.T: must be >= 1e-06"),
    ("target.T", 1e7, "target.T: must be <= 1e+06, got 10000000.0"),
    ("target.L", 1e300, "target.L: must be <= 1e+06"),
    ("bounds.r1", [1e-300, 1e300], "bounds.r1: bounds must lie within +-1e+06 (mm or rad), got [1e-300, 1e+300]"),
    ("stages.0.n_gen", 0, "stages[0].n_gen: must be >= 1, got 0"),
    # Bounds in degrees or metres (lab rehearsal: angles of 349 "rad", a 0.17 mm crank).
    ("bounds.b", [0.0, 360.0], "bounds.b: angles are in rad and one turn is enough: [0, 360] goes beyond +-2 pi "
     "(degrees? [0, 360] deg is [0, 6.283] rad)"),
    ("bounds.r1", [0.03, 0.5], "bounds.r1: [0.03, 0.5] mm: a link under 1 mm long (metres? lengths are in mm)"),
    ("stages.0.box", 5, "stages[0].box: expected a string or a table, got an integer"),
    ("workers", "many", "workers: 'many' is not one of auto"),
    ("stages.0.algorithm.pop_size", 0, "stages[0].algorithm.pop_size: must be >= 2"),
    ("baseline.n_gen", 5, "baseline: only for the DP methods"),
    # What only the algorithm refuses is refused at load, before the first stage runs (it used to surface when
    # its stage started, after the earlier stages' work, and nothing was written).
    ("stages.2.algorithm", {"name": "cmoemt", "pop_size": 5},
     "stages[2].algorithm: cmoemt needs a population of at least 10, got 5"),
    ("stages.1.algorithm", {"name": "cmoemt", "options": {"variant": "nope"}},
     "stages[1].algorithm: cmoemt variant must be one of"),
    ("algorithm", {"name": "imtcmo", "pop_size": 11}, "algorithm: imtcmo needs an even population"),
    # A population set twice (pop_size, and n_partitions's reference directions) that disagrees: it silently took
    # the directions' count.
    ("stages.2.algorithm", {"name": "ctaea", "pop_size": 20, "options": {"n_partitions": 30}},
     "stages[2].algorithm: ctaea: n_partitions = 30 gives 31 reference directions for 2 objectives, so the "
     "population would be 31, not pop_size = 20; set pop_size = 31"),
]


@pytest.mark.parametrize(("path", "value", "message"), BAD, ids=[b[0] for b in BAD])
def test_invalid_entries_are_named_in_the_error(path: str, value: object, message: str) -> None:
    with pytest.raises(ValueError) as e:
        parse_config(with_(path, value))
    assert str(e.value).startswith(message), str(e.value)


def test_an_algorithm_name_is_read_in_any_case_as_clm_moea_reads_it() -> None:
    # review of session 33: `clm moea --algorithm CMOES` was taken, a config's name = "CMOES" refused
    c = parse_config(with_("algorithm.name", "CMOES"))
    assert {s.algorithm.name for s in c.stages} == {"cmoes"}
    c = parse_config(with_("stages.1.algorithm", {"name": "MOEAD_CMT", "pop_size": 20}))
    assert c.stages[1].algorithm.name == "moead_cmt"
    with pytest.raises(ValueError, match="algorithm.name: 'MOEA/D-CMT' is not one of .* did you mean 'moead_cmt'"):
        parse_config(with_("algorithm.name", "MOEA/D-CMT"))


def test_a_valid_config_keeps_relative_limits_for_run_time() -> None:
    c = parse_config(base())
    assert [s.name for s in c.stages] == ["predesign", "subtask1", "subtask2"]
    assert c.stages[2].options["f1_max"] == "start+0.5"
    assert (c.stages[0].s, c.stages[1].s, c.stages[1].d) == (None, 0.2, 20.0)
    assert c.start.output.k == -1.0  # the paper's pantograph by default for shape targets
    np.testing.assert_allclose(c.start.params[0], 0.5 * (c.mechanism.lower + c.mechanism.upper))


def test_overlapping_multi_start_blocks_are_refused() -> None:
    d = with_("stages.0.starts", {"n": 2, "until": "subtask1", "select": "best:S"})
    d["stages"][1]["starts"] = {"n": 2, "select": "best:S"}
    with pytest.raises(ValueError, match=r"^stages\[1\]\.starts: stage 'subtask1' is already inside"):
        parse_config(d)


def test_picks_and_starts_take_any_reported_metric() -> None:
    d = with_("stages.0.starts", {"n": 3, "until": "subtask2", "select": "best:S", "where": {"I_max": 1.0}})
    d["stages"][1]["pick"] = "best:h_s"
    d["stages"][1]["pick_where"] = {"f1_max": 4.0, "S_min": 0.5}
    c = parse_config(d)
    st = c.stages[0].starts
    assert st is not None and (st.n, st.until, st.select) == (3, "subtask2", "best:S")
    assert [(w.metric, w.upper) for w in st.where] == [("I", 1.0)]
    assert c.stages[1].pick == "best:h_s"
    assert [(w.metric, w.upper, w.lower) for w in c.stages[1].pick_where] == [("f1", 4.0, None), ("S", None, 0.5)]
    assert c.stages[1].starts is None and c.stages[2].pick_where == ()


def test_fixed_parameters_reach_the_stage() -> None:
    cfg = parse_config(with_("stages.1.fixed", ["x_a", "r4"]))
    assert cfg.stages[1].fixed == ("x_a", "r4") and cfg.stages[0].fixed == ()


def test_bounds_narrow_the_mechanism() -> None:
    c = parse_config(with_("bounds.r1", [40.0, 60.0]))
    i = c.mechanism.param_names.index("r1")
    assert (c.mechanism.lower[i], c.mechanism.upper[i]) == (40.0, 60.0)


def test_predesign_needs_a_placeable_mechanism() -> None:
    d = with_("mechanism", "rtclm_primary")
    with pytest.raises(ValueError, match=r"^stages\[0\]\.problem: problem 'predesign' does not fit the RTCLM, primary "
                                         r"mode .*: it places every design on the target analytically"):
        parse_config(d)


def test_a_csv_target_is_resolved_against_the_config_directory(tmp_path: Path) -> None:
    (tmp_path / "c.csv").write_text("x,y\n0,0\n100,0\n100,50\n0,50\n")
    c = parse_config(with_("target.curve", "c.csv"), tmp_path)
    assert c.stages[0].options["target"] == str((tmp_path / "c.csv").resolve())


@pytest.mark.parametrize("name", sorted(p.name for p in ASSETS.glob("*.toml")))
def test_shipped_configs_parse(name: str) -> None:
    mech = "watt1" if name.startswith("watt1") else None
    if mech is not None and mech not in MECHANISMS:
        with pytest.raises(ValueError, match="^mechanism: unknown mechanism 'watt1'"):
            load_config(ASSETS / name)
        return
    c = load_config(ASSETS / name)
    assert c.stages or c.method.startswith("dp_")


def test_cli_reports_a_bad_config_in_one_line_with_exit_2(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "bad.toml"
    f.write_text('mechanism = "stephenson1"\n[[stages]]\nname = "subtask1"\nn_gen = "lots"\n')
    assert main(["design", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["clm: error: stages[0].n_gen: expected an integer, got a string"]
    f.write_text("mechanism = [\n")
    assert main(["design", str(f), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.startswith("clm: error: ")
    assert not (tmp_path / "out").exists()


def test_an_integer_pick_is_checked_against_the_members_a_weight_based_algorithm_keeps() -> None:
    # CMOEMT keeps one member per Das-Dennis weight: 10 of pop 12 at subtask 1's three objectives. Checked against
    # pop_size, pick 11 passed the load and failed after the stage ran, and nothing was written.
    d = base()
    d["stages"][1].update(pick=11, algorithm={"name": "cmoemt", "pop_size": 12})
    with pytest.raises(ValueError, match=r"stages\[1\]\.pick: member 11 does not exist: the stage keeps 10 members"):
        parse_config(d)
    d["stages"][1]["pick"] = 9
    parse_config(d)


def test_a_missing_config_and_a_folder_are_told_apart(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"cannot read config '.*nope\.toml': no such file$"):
        load_config(tmp_path / "nope.toml")
    with pytest.raises(ValueError, match=r"cannot read config '.*': not a regular file$"):
        load_config(tmp_path)


def test_a_config_saved_with_a_byte_order_mark_loads(tmp_path: Path) -> None:
    # Rehearsal 8: a BOM (Windows editors) read as "not valid TOML: Invalid statement (at line 1, column 1)".
    text = (ASSETS / "stephenson1_cycloid.toml").read_text(encoding="utf-8")
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    bom, plain = load_config(tmp_path / "bom.toml"), load_config(ASSETS / "stephenson1_cycloid.toml")
    assert bom.name == plain.name and bom.source == plain.source and bom.stages == plain.stages
    from core.study.cell import read_config  # a study's cells read their case's config themselves

    assert read_config(str(tmp_path / "bom.toml")) == read_config(str(ASSETS / "stephenson1_cycloid.toml"))


@pytest.mark.parametrize(("key", "value", "message"), [("h6", 1e300, "rtclm.h6: must be <= 1e+06"),
                                                       ("h4", 0.0, "rtclm.h4: must be > 0"),
                                                       ("h4", float("nan"), "rtclm.h4: must be")])
def test_the_rtclm_heights_are_held_to_the_limits_of_every_other_length(key: str, value: float,
                                                                          message: str) -> None:
    # Review of session 31: [rtclm] h6 = 1e300 ran and "completed" with dh6 1e+300 (the studio refuses it).
    text = (ASSETS / "rtclm_case1.toml").read_text()
    data = tomllib.loads(text)
    data.setdefault("rtclm", {})[key] = value
    with pytest.raises(ValueError) as e:
        parse_config(data, ASSETS)
    assert str(e.value).startswith(message), str(e.value)


def test_slips_a_student_makes_get_the_name_they_meant(tmp_path: Path) -> None:
    # Lab rehearsal: "best:MSE" listed the metrics without the one meant, a design JSON given as the config read
    # only "not valid TOML", and the paper's row name alone got no suggestion.
    from core.kinematics import presets

    with pytest.raises(ValueError, match=r"reports no metric 'MSE'; did you mean 'mse'\?; known: "):
        parse_config(with_("stages.1.pick", "best:MSE"))
    (tmp_path / "x3.json").write_text('{"mechanism": "stephenson1", "params": {}}')
    with pytest.raises(ValueError, match=r"not valid TOML: .*\(this is a design JSON; clm design takes a TOML "):
        load_config(tmp_path / "x3.json")
    # review of session 32: a run's result.json and a studio session were called "a design JSON" too
    for text, what in (('{"format": "clm-design", "stages": [{"mechanism": "stephenson1"}]}', "a run's result.json"),
                       ('{"format":"clm-studio-session","design":{"mechanism":"fourbar"}}', "a studio session"),
                       # review of session 34: a pipeline record (stage results inside) read "a stage result"
                       ('{"stages": [{"format": "clm-stage-result"}], "format": "clm-pipeline"}',
                        "a pipeline record"),
                       ('{"format": "clm-stage-result", "X": [[1.0, 2', "a stage result")):
        (tmp_path / "r.json").write_text(text)
        with pytest.raises(ValueError, match=rf"not valid TOML: .*\(this is {what}; clm design takes a TOML "):
            load_config(tmp_path / "r.json")
    with pytest.raises(ValueError, match=r"^unknown preset 'X3'; did you mean stephenson1/X3\? "):
        presets.get("X3")
    # review of session 32: a full name's last part named three other cases' auxiliary presets
    with pytest.raises(ValueError, match=r"did you mean rtclm/case1-CMOES/auxiliary\? "):
        presets.get("rtclm/case1-cmoes/auxiliary")
    with pytest.raises(ValueError, match=r"did you mean rtclm/case1-CMOES/auxiliary, "):
        presets.get("rtclm/case1-CMOES/auxillary")


def test_a_windows_path_in_a_config_is_named_as_what_toml_made_of_it(tmp_path: Path) -> None:
    # Lab rehearsal: curve = "data\target.csv" became a TAB, and the error's repr printed it back as typed.
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "target.csv").write_text("x,y\n0,0\n100,0\n100,50\n0,50\n")
    cfg = tmp_path / "c.toml"
    text = (ASSETS / "stephenson1_cycloid.toml").read_text()
    block = 'curve = "cycloid"\nL = 300.0\nH = 100.0\nT = 2.0'
    assert block in text
    cfg.write_text(text.replace(block, 'curve = "data\\target.csv"'))
    with pytest.raises(ValueError, match=r"starts an escape: \\t is a tab; write the path with '/'\)"):
        load_config(cfg)  # not "or in '...' quotes" here: those keep a backslash, no folder separator here
    cfg.write_text(cfg.read_text().replace('"data\\target.csv"', "'data\\target.csv'"))
    with pytest.raises(ValueError, match=r"not found \('\\' is not a folder separator here: use '/'\)"):
        load_config(cfg)
    cfg.write_text(cfg.read_text().replace("'data\\target.csv'", '"data/target.csv"'))
    assert load_config(cfg).stages
