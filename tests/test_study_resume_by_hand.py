"""Resuming a study: which cells an invocation sends out, what it counts, with a stand-in for the Dask client
(the real cluster is in tests/test_study.py)."""

from __future__ import annotations

import io
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import distributed
import pytest

from core.formats.study import load_study
from core.study import runner
from core.study.store import Store
from tests.test_study import TINY

ROOT = Path(__file__).resolve().parents[1]
STUDY = TINY.replace('name = "tiny"', 'name = "resume"', 1)


class _Future:
    def __init__(self, key: str, value: dict[str, Any]) -> None:
        self.key, self.value, self.status = key, value, "finished"

    def result(self) -> dict[str, Any]:
        return self.value

    def release(self) -> None:
        pass


class _Client:
    """Runs each task at once, in the calling process, and remembers which cells it was given."""

    def __init__(self) -> None:
        self.sent: list[str] = []

    def map(self, fn: Any, cells: list[dict[str, Any]], pure: bool, key: list[str]) -> list[_Future]:
        self.sent += [c["key"] for c in cells]
        return [_Future(k, fn(c)) for k, c in zip(key, cells, strict=True)]


def fake_task(cell: dict[str, Any]) -> dict[str, Any]:
    # spea2 with seed 2 fails, every other cell succeeds.
    failed = cell["algorithm"]["name"] == "spea2" and cell["seed"] == 2
    return {"key": cell["key"], "case": cell["case"]["name"], "algorithm": cell["algorithm"]["name"],
            "seed": cell["seed"], "status": "failed" if failed else "done", "result": "{}", "metrics": {},
            "task_time": 0.0, **({"error": "boom"} if failed else {})}


@pytest.fixture
def client(monkeypatch: pytest.MonkeyPatch) -> _Client:
    c = _Client()

    @contextmanager
    def client_for(scheduler: str | None, workers: int | None) -> Any:
        yield c

    monkeypatch.setattr(runner, "client_for", client_for)
    monkeypatch.setattr(distributed, "as_completed", iter)
    return c


def test_a_resumed_study_runs_only_what_is_not_done_and_counts_it(tmp_path: Path, client: _Client) -> None:
    (tmp_path / "s.toml").write_text(STUDY)
    study = load_study(tmp_path / "s.toml")
    out = str(tmp_path / "out")
    # First invocation, capped at 4 cells: the first 4 in the study's order run, one of them fails.
    s = runner.run_study(study, out, stream=None, task=fake_task, limit=4)
    assert client.sent == ["subtask2/nsga2/1", "subtask2/nsga2/2", "subtask2/nsga2/3", "subtask2/spea2/1"]
    assert (s.total, s.skipped, s.ran, s.failed) == (6, 0, 4, 0)
    # Second: the two cells not yet run; spea2/2 fails.
    client.sent.clear()
    progress = io.StringIO()
    s = runner.run_study(study, out, stream=progress, task=fake_task)
    assert client.sent == ["subtask2/spea2/2", "subtask2/spea2/3"]
    assert (s.total, s.skipped, s.ran, s.failed) == (6, 4, 2, 1)
    # The progress line counts the finished cells too.
    assert [ln.split(", ETA")[0] for ln in progress.getvalue().splitlines()] == ["cells 5/6, 1 failed",
                                                                                 "cells 6/6, 1 failed"]
    # Third: only the failed cell runs again (and fails again, its attempts counted).
    client.sent.clear()
    s = runner.run_study(study, out, stream=None, task=fake_task)
    assert client.sent == ["subtask2/spea2/2"]
    assert (s.total, s.skipped, s.ran, s.failed) == (6, 5, 1, 1)
    store = Store(out)
    try:
        assert {r["key"]: r["attempts"] for r in store.rows()}["subtask2/spea2/2"] == 2
    finally:
        store.close()


def metric_task(cell: dict[str, Any]) -> dict[str, Any]:
    """A finished cell whose evaluations are its budget (what the report would pool)."""
    budget = int(cell["case"]["budget"])
    return {"key": cell["key"], "case": cell["case"]["name"], "algorithm": cell["algorithm"]["name"],
            "seed": cell["seed"], "status": "done", "result": "{}", "task_time": 0.0,
            "metrics": {"front": [[0.0, 1.0], [1.0, 0.0]], "objectives": ["f1", "f2"], "feasible_ratio": 1.0,
                        "pick": {"mse": float(cell["seed"])}, "pick_feasible": True, "params": {},
                        "wall_time": 1.0, "n_eval": budget}}


def test_the_report_covers_the_study_as_it_stands_not_seeds_or_budgets_it_dropped(tmp_path: Path,
                                                                                  client: _Client) -> None:
    from core.study.report import write_report

    out = str(tmp_path / "out")
    (tmp_path / "s.toml").write_text(STUDY.replace('seeds = "1..3"', 'seeds = "1..5"'))
    runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=metric_task)
    # Fewer seeds and a larger budget, the changed cells run again: seeds 4 and 5 stay in the store at budget 100.
    (tmp_path / "s.toml").write_text(STUDY.replace("budget = 100", "budget = 150"))
    s = runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=metric_task, rerun_changed=True)
    assert (s.total, s.ran) == (6, 6)
    md = write_report(out)[0].read_text()
    assert "Runs: nsga2 3, spea2 3" in md
    assert "| evaluations | 150 [0] | 150 [0] |" in md  # not 150 pooled with the dropped seeds' 100
    assert "Left out: 4 run(s)" in md
    # The studio's Studies panel shows what the report counts (its box plots pooled all ten runs).
    from studio.studies import finished_runs, study_rows

    runs = finished_runs(study_rows(Path(out))[1])
    assert sorted((r.algorithm, r.seed) for r in runs) == [(a, s) for a in ("nsga2", "spea2") for s in (1, 2, 3)]
    assert {r.metrics["n_eval"] for r in runs} == {150}


def test_a_second_study_into_the_same_directory_is_refused_while_the_first_runs(tmp_path: Path,
                                                                                 client: _Client) -> None:
    from core.study.store import study_lock

    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    with study_lock(out):  # the first clm study, still running
        with pytest.raises(ValueError, match="another clm study is writing into it"):
            runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    assert client.sent == []
    runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)  # once it has ended
    assert len(client.sent) == 6
    # the message names the holder, not the command refused (review of session 32: "another clm study" for a
    # clm design still writing there)
    from core.formats.files import dir_lock

    with dir_lock(out, "clm design"), pytest.raises(ValueError, match=r"another clm design is writing into it "
                                                                       rf"\(process {os.getpid()}\)"):
        runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)


@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_a_damaged_study_database_is_one_line_and_exit_2(tmp_path: Path, client: _Client, damage: str,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    from core.cli import main

    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    db = out / "study.sqlite"
    db.write_bytes(db.read_bytes()[:3000] if damage == "truncate" else bytes(range(256)) * 64)
    for argv in (["study", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"], ["study", "report", str(out)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "study.sqlite: not a usable study database" in err, err


def test_cells_lost_with_the_scheduler_are_not_failures_and_the_study_says_so(tmp_path: Path,
                                                                              client: _Client) -> None:
    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    real_map = client.map

    def map_losing_half(fn: Any, cells: list[dict[str, Any]], pure: bool, key: list[str]) -> list[_Future]:
        futures = real_map(fn, cells, pure, key)
        for f in futures[3:]:  # the scheduler died: these never ran (distributed: cancelled, no exception)
            f.status = "cancelled"
        return futures

    client.map = map_losing_half  # type: ignore[method-assign]
    with pytest.raises(ValueError, match=r"the Dask cluster went away: 3 cell\(s\) did not run"):
        runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    store = Store(out)
    try:
        assert len(store.rows()) == 3  # no row for a cell that never ran (it read failed, "NoneType: None")
    finally:
        store.close()
    client.map = real_map  # type: ignore[method-assign]
    s = runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    assert (s.skipped, s.ran) == (3, 3)


def test_a_population_written_out_equal_to_the_configs_is_no_change(tmp_path: Path, client: _Client) -> None:
    import tomllib

    from tests.test_study import CONFIG

    pop = tomllib.loads(Path(CONFIG).read_text())["algorithm"]["pop_size"]
    unset = STUDY.replace("pop_size = 20\n", "")
    (tmp_path / "s.toml").write_text(unset)
    out = str(tmp_path / "out")
    runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)
    client.sent.clear()
    # The same runs: refused before ("algorithm.pop_size (none) -> 200"), and --rerun-changed recomputed them.
    (tmp_path / "s.toml").write_text(unset.replace('name = "spea2"\n', f'name = "spea2"\npop_size = {pop}\n'))
    s = runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)
    assert client.sent == ["subtask2/spea2/2"]  # only the cell that failed runs again
    # Another population is a change.
    (tmp_path / "s.toml").write_text(unset.replace('name = "spea2"\n', f'name = "spea2"\npop_size = {pop + 2}\n'))
    with pytest.raises(runner.StudyChanged, match=f"algorithm.pop_size {pop} -> {pop + 2}"):
        runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)
    assert s.total == 6


def test_a_finished_cell_whose_result_file_was_deleted_runs_again(tmp_path: Path, client: _Client) -> None:
    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    (out / "runs" / "subtask2" / "nsga2" / "3.json").unlink()  # by hand: the row alone was trusted
    client.sent.clear()
    runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    assert client.sent == ["subtask2/nsga2/3", "subtask2/spea2/2"]  # it, and the cell that failed
    assert (out / "runs" / "subtask2" / "nsga2" / "3.json").is_file()


def test_an_edit_of_a_stage_the_case_does_not_run_is_no_change(tmp_path: Path, client: _Client) -> None:
    from tests.test_study import CONFIG

    text = Path(CONFIG).read_text()
    config = tmp_path / "c.toml"
    config.write_text(text)
    (tmp_path / "s.toml").write_text(STUDY.replace(str(CONFIG), str(config)))
    out = str(tmp_path / "out")
    runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)
    client.sent.clear()
    # The case runs subtask2 alone: the multi-start block, the predesign's generations and the seed do not
    # reach its cells (session 24 changed the block, and every subtask cell of an existing study was left out).
    block = next(line for line in text.splitlines() if line.startswith("starts = "))
    edited = (text.replace(block, 'starts = {n = 3, until = "probe", select = "best:S"}')
              .replace("n_gen = 60", "n_gen = 7").replace("seed = 1", "seed = 9"))
    assert edited != text
    config.write_text(edited)
    s = runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)
    assert client.sent == ["subtask2/spea2/2"]  # only the cell that failed runs again
    assert s.total == 6
    # An edit of the stage it runs is a change.
    head, sep, tail = edited.partition('name = "subtask2"')
    config.write_text(head + sep + tail.replace('f1_max = [4.0, "start+0.05"]', 'f1_max = [4.5, "start+0.05"]', 1))
    with pytest.raises(runner.StudyChanged, match="case.config.stages"):
        runner.run_study(load_study(tmp_path / "s.toml"), out, stream=None, task=fake_task)


def test_a_study_written_before_the_narrowed_settings_keeps_its_rows(tmp_path: Path, client: _Client) -> None:
    # Its meta holds digests of the settings as compared then; read with today's digest, every row was dropped from
    # the report ("NSGA-II 0, SPEA2 0", "Left out: 6 runs") though no cell had changed.
    from core.study.store import current_rows, settings_digest

    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    runner.run_study(load_study(tmp_path / "s.toml"), str(out), stream=None, task=fake_task)
    store = Store(out)
    try:
        meta = store.meta("study")
        rows = store.rows()
        assert meta["digest"] == 2 and len(current_rows(meta, rows)) == 6
        old = {k: v for k, v in meta.items() if k != "digest"}
        old["cells"] = {r["key"]: settings_digest(r["settings"], 1) for r in rows}
        assert old["cells"] != meta["cells"]  # the two schemes differ on this config (it has stages the case skips)
        assert len(current_rows(old, rows)) == 6
        assert current_rows({**old, "digest": 2}, rows) == []  # read as today's digests, none would match
    finally:
        store.close()


def test_cells_run_by_other_code_are_refused_kept_or_run_again_but_never_pooled_unsaid(
        tmp_path: Path, client: _Client) -> None:
    # Rehearsal 6: a resumed study reused four seeds of the old NSGA-II and ran the fifth with a changed one.
    from core.study.provenance import code_digest
    from core.study.report import write_report

    (tmp_path / "s.toml").write_text(STUDY)
    study = load_study(tmp_path / "s.toml")
    out = str(tmp_path / "out")
    runner.run_study(study, out, stream=None, task=fake_task)
    store = Store(out)
    assert set(store.codes().values()) == {code_digest()}  # each finished cell keeps its code's digest
    store.db.execute("UPDATE runs SET code = 'feedfacecafe' WHERE key = 'subtask2/nsga2/1'")
    store.close()
    client.sent.clear()
    with pytest.raises(runner.StudyChanged, match=r"1 finished cell\(s\) run with other code \(core digest "
                                                  r"feedfacecafe; this code: " + code_digest()):
        runner.run_study(study, out, stream=None, task=fake_task)
    assert client.sent == []
    runner.run_study(study, out, stream=None, task=fake_task, mixed_code=True)  # kept: the report says so
    assert client.sent == ["subtask2/spea2/2"]  # the failed one only
    md = write_report(out)[0].read_text()
    assert "Code: **2 versions** among the runs" in md and "1 run(s) by core digest feedfacecafe" in md
    client.sent.clear()
    runner.run_study(study, out, stream=None, task=fake_task, rerun_changed=True)  # run again with this code
    assert "subtask2/nsga2/1" in client.sent
    assert set(Store(out).codes().values()) == {code_digest()}
    md = write_report(out)[0].read_text()
    assert f"Code: core digest {code_digest()}" in md and "for every run" in md


def test_a_directory_of_another_study_is_refused(tmp_path: Path, client: _Client) -> None:
    # Rehearsal 6: --out into another study's directory took it over and overwrote its report.
    (tmp_path / "a.toml").write_text(STUDY)
    (tmp_path / "b.toml").write_text(STUDY.replace('name = "resume"', 'name = "other"', 1))
    out = str(tmp_path / "out")
    runner.run_study(load_study(tmp_path / "a.toml"), out, stream=None, task=fake_task)
    with pytest.raises(runner.StudyChanged, match="holds the study 'resume', not 'other'"):
        runner.run_study(load_study(tmp_path / "b.toml"), out, stream=None, task=fake_task)


def test_the_commit_is_named_only_when_the_checkout_holds_the_code(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # Review of session 30: core installed, git-ignored, inside another repository reported that repository's
    # commit as clean.
    import subprocess

    from core.study import provenance

    repo = tmp_path / "host"
    pkg = repo / "venv" / "core"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (repo / ".gitignore").write_text("venv/\n")
    git = ["git", "-C", str(repo), "-c", "user.email=t@t", "-c", "user.name=t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", ".gitignore"], check=True)
    subprocess.run([*git, "commit", "-q", "-m", "host"], check=True)
    monkeypatch.setattr(provenance, "ROOT", pkg)
    provenance.git_commit.cache_clear()
    try:
        assert provenance.git_commit() is None  # not this repository's code
        (repo / ".gitignore").write_text("")
        subprocess.run([*git, "add", "."], check=True)
        subprocess.run([*git, "commit", "-q", "-m", "core"], check=True)
        provenance.git_commit.cache_clear()
        head = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout
        assert provenance.git_commit() == head.strip()[:12]
        (pkg / "__init__.py").write_text("x = 1\n")
        provenance.git_commit.cache_clear()
        assert provenance.git_commit() == head.strip()[:12] + "+dirty"
    finally:
        provenance.git_commit.cache_clear()


def test_workers_running_other_code_are_refused_before_any_cell(tmp_path: Path, client: _Client) -> None:
    # Review of session 30: a long-lived worker started before an edit ran the old modules; nothing compared them.
    from core.study.cell import run_cell

    client.run = lambda fn, *args: {"tcp://w1": "deadbeef0000"}  # type: ignore[attr-defined]
    (tmp_path / "s.toml").write_text(STUDY)
    with pytest.raises(runner.StudyChanged, match=r"the cluster's workers run other code \(core digest "
                                                  r"deadbeef0000; this code: "):
        runner.run_study(load_study(tmp_path / "s.toml"), str(tmp_path / "out"), stream=None, task=run_cell)
    assert client.sent == []


def test_the_digest_is_the_code_imported_not_the_files_edited_since(tmp_path: Path) -> None:
    import shutil
    import subprocess
    import sys

    import core
    from core.study.provenance import code_digest

    assert code_digest() == core.CODE_DIGEST
    # A copy of core imported, then edited: the process still names the code it imported.
    shutil.copytree(ROOT / "core", tmp_path / "core", ignore=shutil.ignore_patterns("__pycache__"))
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import core\n"
              "from pathlib import Path; p = Path(sys.argv[1]) / 'core' / 'cli' / '__init__.py'\n"
              "p.write_text(p.read_text() + '# edited\\n')\n"
              "from core.study.provenance import code_digest; print(code_digest(), core.__file__)")
    out = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, timeout=120)
    digest, where = out.stdout.split()
    assert where.startswith(str(tmp_path)) and digest == core.CODE_DIGEST
    edited = subprocess.run([sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); import core; "
                             "print(core.CODE_DIGEST)", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert edited.stdout.strip() != core.CODE_DIGEST


def test_a_study_refused_at_its_start_leaves_no_directory_behind(tmp_path: Path, client: _Client,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    # Rehearsal 8: a refused study left --out behind with a lock and an empty database; a directory that was
    # already there is left as it was, and one that holds runs is never touched.
    from core.cli import main

    client.run = lambda fn, *args: {"tcp://w1": "deadbeef0000"}  # type: ignore[attr-defined]
    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "new"
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"]) == 2
    assert "the cluster's workers run other code" in capsys.readouterr().err
    assert not out.exists()
    deep = tmp_path / "new2" / "a" / "b"  # the folders made above it go too
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(deep), "--quiet"]) == 2
    assert not (tmp_path / "new2").exists()
    there = tmp_path / "there"
    there.mkdir()
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(there), "--quiet"]) == 2
    assert there.is_dir()


def test_a_refused_study_leaves_the_folder_to_a_command_that_took_it_since(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # Review of session 33: the cleanup of a refused start ran after the folder's lock was let go, so a clm design
    # that took the folder in between lost it to the removal.
    import contextlib

    import core.study.runner as study_runner
    from core.cli import main
    from core.formats.files import dir_lock

    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "new"
    other = contextlib.ExitStack()

    def refused(study, directory, **kwargs):
        with dir_lock(directory, "clm study"):
            pass
        other.enter_context(dir_lock(directory, "clm design"))  # the next command, as soon as the lock is free,
        raise ValueError("refused")  # before it has written anything

    monkeypatch.setattr(study_runner, "run_study", refused)
    with other:
        assert main(["study", str(tmp_path / "s.toml"), "--out", str(out), "--quiet"]) == 2
        assert "refused" in capsys.readouterr().err
        assert (out / ".lock").read_text().endswith(" clm design")  # the folder is the other command's
    monkeypatch.setattr(study_runner, "run_study", lambda study, directory, **kw: (_ for _ in ()).throw(
        ValueError("refused")))
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "fresh"), "--quiet"]) == 2
    assert not (tmp_path / "fresh").exists()  # nobody else there: removed, lock and all


def test_an_unreachable_scheduler_is_refused_before_the_study_directory_is_made(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import core.optimize.workers as workers
    from core.cli import main

    patient = workers.connect
    monkeypatch.setattr(workers, "connect", lambda address: patient(address, timeout="1s"))  # not 20 s in a test
    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "o"
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("clm: error: no Dask scheduler answers at tcp://127.0.0.1:1 ")
    assert not out.exists()


@pytest.mark.parametrize(("address", "said"), [
    # Dask's "missing port number in address ''" (as clm design's before it was checked), and for "foo" alone
    ("", "--scheduler is empty; give a Dask scheduler address such as tcp://127.0.0.1:8786"),
    ("  ", "--scheduler is empty; give a Dask scheduler address such as tcp://127.0.0.1:8786"),
    ("foo", "'foo' is not a Dask scheduler address (missing port number in address 'foo'); one reads like "
            "tcp://127.0.0.1:8786"),
    ("tcp://localhost", "'tcp://localhost' is not a Dask scheduler address (missing port number in address "
                        "'localhost'); one reads like tcp://127.0.0.1:8786"),
])
def test_a_scheduler_that_is_no_address_is_one_plain_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          address: str, said: str) -> None:
    from core.cli import main

    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "o"
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(out), "--scheduler", address]) == 2
    assert capsys.readouterr().err == f"clm: error: {said}\n"
    assert not out.exists()
