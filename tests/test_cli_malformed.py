"""Every malformed command line, file or config ends in exactly one stderr line ``clm: error: ...`` and exit 2."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from core.cli import main

S1 = "stephenson1/X3"
GOOD_CFG = """
mechanism = "stephenson1"
n_samples = 72
[algorithm]
name = "nsga2"
pop_size = 8
[[stages]]
name = "subtask1"
n_gen = 1
"""


def files(tmp: Path) -> dict[str, str]:
    """Named hostile inputs, written once per test."""
    deep = "[" * 50_000 + "]" * 50_000
    made = {
        "deep.json": deep,
        "deep2.json": '{"mechanism": "stephenson1", "params": ' + "[" * 5000 + "]" * 5000 + "}",
        "list.json": "[1, 2, 3]",
        "text.json": "hello",
        "binary.json": "\udcff",
        "empty.json": "",
        "nan.json": json.dumps({"mechanism": "stephenson1", "params": [float("nan")] * 16}),
        # An integer past 1e308: float() raised OverflowError, a traceback (QA, session 36)
        "bigint.json": json.dumps({"mechanism": "stephenson1", "params": [10**400] + [1.0] * 15}),
        "bad.toml": "mechanism = [\n",
        "deep.toml": "a = " + "[" * 3000 + "]" * 3000 + "\n",
        "good.toml": GOOD_CFG,
        "rows.json": json.dumps({"format": "clm-design", "status": "complete", "rows": {"a": 1}}),
        "rows2.json": json.dumps({"format": "clm-design", "status": "complete",
                                  "rows": [{"label": "x", "mse": "lots"}]}),
        "bare.json": json.dumps({"format": "clm-design"}),  # was printed as a row "no result (None)"
        "other.json": json.dumps({"format": "something"}),
        "curve_bad.csv": "x,y\n1,2\n",
        "curve_text.csv": "hello world\n",
        "curve_good.csv": "x,y\n0,0\n100,0\n100,50\n0,50\n",
        "study_bad.toml": "seeds = '1..0'\n",
    }
    out = {}
    for name, text in made.items():
        p = tmp / name
        if name == "binary.json":
            p.write_bytes(b"\xff\xfe\x00garbage")
        else:
            p.write_text(text)
        out[name] = str(p)
    fifo = tmp / "fifo.csv"
    os.mkfifo(fifo)
    out["fifo"] = str(fifo)
    (tmp / "dir").mkdir()
    out["dir"] = str(tmp / "dir")
    out["missing"] = str(tmp / "missing.json")
    out["tmp"] = str(tmp)
    return out


CASES: list[list[str]] = [
    # simulate
    ["simulate"], ["simulate", "--preset", "nope"], ["simulate", "--preset", S1, "--samples", "0"],
    ["simulate", "--preset", S1, "--samples", "-360"], ["simulate", "--preset", S1, "--samples", "1e9"],
    ["simulate", "--preset", S1, "--samples", "abc"], ["simulate", "--preset", S1, "--backend", "gpu"],
    ["simulate", "--design", "{missing}"], ["simulate", "--design", "{dir}"], ["simulate", "--design", "{fifo}"],
    ["simulate", "--design", "/dev/zero"], ["simulate", "--design", "{deep.json}"],
    ["simulate", "--design", "{deep2.json}"], ["simulate", "--design", "{list.json}"],
    ["simulate", "--design", "{text.json}"], ["simulate", "--design", "{binary.json}"],
    ["simulate", "--design", "{empty.json}"], ["simulate", "--design", "{nan.json}"],
    ["simulate", "--preset", S1, "--design", "{list.json}"],
    ["simulate", "--design", "{bigint.json}"], ["evaluate", "--design", "{bigint.json}"],
    ["export", "--preset", S1, "--svg", ""], ["export", "--preset", S1, "--dxf", " "], ["simulate", "--design", ""],
    ["study", "{good.toml}", "--out", "{tmp}/st"],
    ["scale", "--design", "{bigint.json}", "--factor", "2", "--out", "-"],
    ["export", "--design", "{bigint.json}", "--svg", "{tmp}/a.svg"],
    # evaluate
    ["evaluate"], ["evaluate", "--preset", "nope"], ["evaluate", "--preset", S1, "--samples", "0"],
    ["evaluate", "--preset", S1, "--samples", "1"], ["evaluate", "--preset", S1, "--samples", "-4"],
    ["evaluate", "--preset", S1, "--period", "nan"], ["evaluate", "--preset", S1, "--period", "-2"],
    ["evaluate", "--preset", S1, "--period", "inf"], ["evaluate", "--preset", S1, "--obstacle", "nan", "25"],
    ["evaluate", "--preset", S1, "--obstacle", "-1", "25"], ["evaluate", "--preset", S1, "--target", "cycloid:L=-3"],
    ["evaluate", "--preset", S1, "--target", "cycloid:Q=3"], ["evaluate", "--preset", S1, "--target", "{fifo}"],
    ["evaluate", "--preset", S1, "--target", "/dev/zero"], ["evaluate", "--preset", S1, "--target", "{missing}"],
    ["evaluate", "--curve", "{fifo}"], ["evaluate", "--curve", "{dir}"], ["evaluate", "--curve", "{curve_bad.csv}"],
    ["evaluate", "--curve", "{curve_text.csv}"], ["evaluate", "--design", "{deep.json}"],
    ["evaluate", "--preset", S1, "--trunk", "-5"],
    ["evaluate", "--curve", "{curve_good.csv}", "--mode", "auxiliary"],  # rehearsal 8: the mode was ignored unsaid
    # presets
    ["presets", "show", "nope"], ["presets", "frobnicate"],
    # design
    ["design"], ["design", "{missing}", "--out", "{tmp}/o"], ["design", "{bad.toml}", "--out", "{tmp}/o"],
    ["design", "{deep.toml}", "--out", "{tmp}/o"], ["design", "{dir}", "--out", "{tmp}/o"],
    ["design", "{fifo}", "--out", "{tmp}/o"], ["design", "{good.toml}"], ["design", "{good.toml}", "--out", ""],
    ["design", "{good.toml}", "--out", "{list.json}/o"], ["design", "{good.toml}", "--out", "/proc/nope"],
    ["design", "{good.toml}", "--out", "{tmp}/o", "--seed", "-1"],
    ["design", "{good.toml}", "--out", "{tmp}/o", "--seed", str(10**30)],
    ["design", "{good.toml}", "--out", "{tmp}/o", "--workers", "0"],
    ["design", "{good.toml}", "--out", "{tmp}/o", "--workers", "many"],
    # compare
    ["compare"], ["compare", "{missing}"], ["compare", "{rows.json}"], ["compare", "{rows2.json}"],
    ["compare", "{other.json}"], ["compare", "{bare.json}"],
    ["compare", "{deep.json}"], ["compare", "{fifo}"], ["compare", "{binary.json}"],
    # study and moea
    ["study", "{study_bad.toml}", "--out", "{tmp}/s"], ["study", "{missing}", "--out", "{tmp}/s"],
    ["study", "report", "{tmp}"], ["moea", "--problem", "mw99"], ["moea", "--problem", "mw1", "--evals", "0"],
    # export where nothing can be written: the file asked for is named, not its temporary twin
    ["export", "--preset", "stephenson1/X3", "--dxf", "{tmp}/no/such/x.dxf"],
    ["export", "--preset", "stephenson1/X3", "--svg", "/proc/x.svg"],
    ["export", "--preset", "stephenson1/X3", "--dxf", "/proc/x.dxf"],
    ["export", "--preset", "stephenson1/X3", "--dxf", "{tmp}/x.dxf", "--hole", "1e300"],  # rehearsal 8: it wrote one
    ["export", "--preset", "stephenson1/X3", "--dxf", "{tmp}/x.dxf", "--width", "2e4"],
    ["evaluate", "--preset", S1, "--target", "cycloid:L=1e300"],  # review of session 31: MSE 5e+299 mm, exit 0
    # scale: a bad design file, no size, nowhere to write
    ["scale", "--design", "{missing}", "--factor", "2"], ["scale", "--design", "{list.json}", "--factor", "2"],
    ["scale", "--preset", "stephenson1/X3", "--factor", "inf"],
    ["scale", "--preset", "stephenson1/X3", "--factor", "2", "--out", "{tmp}/no/such/x.json"],
    ["scale", "--preset", "stephenson1/X3", "--factor", "2", "--out", "{tmp}"],
    # anything else
    ["fly"], ["--nonsense"],
]


def test_there_are_at_least_sixty_cases():
    assert len(CASES) >= 60


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(c)[:60] for c in CASES])
def test_malformed_invocation_is_one_line_and_exit_2(argv, tmp_path, capsys):
    f = files(tmp_path)
    args = []
    for a in argv:
        for k, v in f.items():
            a = a.replace("{" + k + "}", v)
        args.append(a)
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, (args, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("clm: error: "), err


def test_an_unreachable_dask_scheduler_is_one_line_naming_it():
    from core.optimize.workers import connect

    with pytest.raises(ValueError, match=r"no Dask scheduler answers at tcp://127\.0\.0\.1:1 "):
        connect("tcp://127.0.0.1:1", timeout="1s")


def test_the_file_asked_for_is_named_when_the_disk_refuses_it(tmp_path, capsys, monkeypatch):
    import errno
    import tempfile

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tempfile, "mkstemp", full)  # whoever runs the tests, root or not
    assert main(["export", "--preset", "stephenson1/X3", "--svg", str(tmp_path / "x.svg")]) == 2
    assert capsys.readouterr().err.strip() == f"clm: error: No space left on device: {tmp_path / 'x.svg'}"


def test_a_run_that_outgrows_the_memory_is_one_line(capsys, monkeypatch):
    import core.cli.moea

    def huge(args):
        raise MemoryError("Unable to allocate 7.28 TiB for an array with shape (1000001, 1000001)")

    # Sizes inside the checked ranges can still outgrow a machine; a real allocation of that size is refused or
    # granted depending on the kernel's overcommit setting, so the command is made to fail as numpy does.
    monkeypatch.setattr(core.cli.moea, "run", huge)
    assert main(["moea", "--problem", "mw3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("clm: error: not enough memory for this run (Unable to allocate")


@pytest.mark.parametrize(("text", "said"), [
    ('{"mechanism": "stephenson1", "params": {"r1": 128,33}}',
     "Expecting property name enclosed in double quotes at line 1 column 51 (a decimal comma? JSON numbers take '.': "
     "128.33)"),
    ('{"mechanism": "stephenson1", "params": {"r1": "12', "Unterminated string starting at line 1 column 47"),
    # A trailing comma read "(a decimal comma? ...)" after a number; after a string or a list it had no word.
    ('{"mechanism": "stephenson1", "params": {"r1": 128,}}',
     "Expecting property name enclosed in double quotes at line 1 column 51 (a trailing comma? JSON takes none after "
     "the last item)"),
    ('{"mechanism": "stephenson1",\n}', "Expecting property name enclosed in double quotes at line 2 column 1 (a "
     "trailing comma? JSON takes none after the last item)"),
    ('{"mechanism": "stephenson1", "params": [1, 2,]}',
     "Expecting value at line 1 column 46 (a trailing comma? JSON takes none after the last item)"),
])
def test_a_broken_design_json_is_said_in_plain_words(tmp_path, capsys, text, said):
    # Lab rehearsal: "Unterminated string starting at at line 17", Python's words for a decimal comma.
    (tmp_path / "d.json").write_text(text)
    assert main(["simulate", "--design", str(tmp_path / "d.json")]) == 2
    assert capsys.readouterr().err == f"clm: error: {tmp_path / 'd.json'}: not valid JSON: {said}\n"


def test_a_windows_path_is_shown_as_typed_with_a_word_on_its_separator(capsys):
    # Lab rehearsal: 'C:\\Users\\student\\x3.json' came back with its backslashes doubled (a repr).
    assert main(["simulate", "--design", "C:\\Users\\student\\x3.json"]) == 2
    assert capsys.readouterr().err == ("clm: error: design file C:\\Users\\student\\x3.json not found ('\\' is not a "
                                       "folder separator here: use '/')\n")


@pytest.mark.parametrize("command", [["presets", "show", S1], ["scale", "--preset", S1, "--factor", "2"]])
def test_an_empty_out_or_a_lone_overwrite_is_one_line_and_out_dash_prints(tmp_path, capsys, monkeypatch, command):
    # '--out ""' read as the folder '.', '--out -' wrote a file named '-', and '--overwrite' alone was ignored.
    monkeypatch.chdir(tmp_path)
    for extra, said in ((["--out", ""], "--out is empty; name the output file, or leave --out out to print"),
                        (["--overwrite"], "--overwrite replaces an existing --out FILE; without --out FILE the JSON "
                                          "is printed"),
                        (["--out", "-", "--overwrite"], "--overwrite replaces")):
        assert main([*command, *extra]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"clm: error: {said}") and err.count("\n") == 1
    assert main([*command, "--out", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["mechanism"] == "stephenson1"
    assert list(tmp_path.iterdir()) == []


def test_the_docs_write_a_preset_with_out_not_a_redirect():
    # 'presets show NAME > my.json' empties my.json before the name is read; --out writes only a name it knows.
    root = Path(__file__).resolve().parents[1]
    for doc in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        assert not re.search(r"presets show [^`\n]*> ", doc.read_text()), doc.name


def test_presets_show_writes_a_file_only_for_a_name_it_knows_and_keeps_an_existing_one(tmp_path, capsys):
    # Lab rehearsal: 'clm presets show stephenson1/x3 > mine.json' emptied the student's edited design (the shell
    # truncates before the name is read), and the empty file then read "Expecting value at line 1 column 1".
    mine = tmp_path / "mine.json"
    assert main(["presets", "show", "stephenson1/X3", "--out", str(mine)]) == 0
    assert capsys.readouterr().out == f"wrote {mine}\n"
    edited = mine.read_text().replace('"r1": ', '"r1": 1 + ', 0)
    assert main(["presets", "show", "stephenson1/x3", "--out", str(mine)]) == 2  # a typo: the file is untouched
    assert "did you mean stephenson1/X3" in capsys.readouterr().err and mine.read_text() == edited
    assert main(["presets", "show", "stephenson1/X2", "--out", str(mine)]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err and mine.read_text() == edited
    assert main(["presets", "show", "stephenson1/X2", "--out", str(mine), "--overwrite"]) == 0
    assert main(["simulate", "--design", str(mine)]) == 0
    capsys.readouterr()
    empty = tmp_path / "empty.json"
    empty.write_text("")
    assert main(["simulate", "--design", str(empty)]) == 2
    assert capsys.readouterr().err == f"clm: error: {empty} is empty: not a design JSON\n"


@pytest.mark.parametrize(("argv", "said"), [
    # QA (session 36): "'.' is a folder" for an empty name; the factor twice; a design config given to clm study read
    # "mechanism: unknown key"; "a design file file".
    (["export", "--preset", S1, "--svg", ""], "argument --svg: is empty; name a file (see 'clm export --help')"),
    (["scale", "--preset", S1, "--factor", "0"], "--factor: a scale factor must be a positive number, got 0.0"),
    (["study", "{good.toml}", "--out", "{tmp}/st"], "this is a design configuration ([[stages]]), not a study: run it "
     "with clm design, or name it in a study's [[cases]] config"),
    (["simulate", "--design", "{huge.json}"], "cannot read design file '{huge.json}': 1.0 MB is more than the 1 MB "
     "such a file may have"),
    # An argument a subcommand does not know points to that subcommand's help, not clm's (QA, session 36).
    (["presets", "show", "a", "b"], "unrecognized arguments: b (see 'clm presets show --help')"),
    (["presets", "list", "--x"], "unrecognized arguments: --x (see 'clm presets list --help')"),
    (["simulate", "--preset", S1, "y"], "unrecognized arguments: y (see 'clm simulate --help')"),
    (["--bogus", "presets", "list"], "unrecognized arguments: --bogus (see 'clm --help')"),  # clm's own option
])
def test_refusals_read_plainly(tmp_path, capsys, argv, said):
    names = files(tmp_path)
    (tmp_path / "huge.json").write_bytes(b" " * (2**20 + 10))
    names["huge.json"] = str(tmp_path / "huge.json")

    def filled(text: str) -> str:
        for k, v in names.items():
            text = text.replace("{" + k + "}", v)
        return text

    assert main([filled(a) for a in argv]) == 2
    assert capsys.readouterr().err == f"clm: error: {filled(said)}\n"
