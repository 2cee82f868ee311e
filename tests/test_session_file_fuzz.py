"""A session file is loaded or refused with one message, whatever it holds: mutations of a real session
(wrong types, non-finite and huge numbers, deep nesting, repeated branch labels, dropped keys, paths to files)
never raise anything but ValueError, the refusal is one line (an upload: one notification, the session untouched;
at startup: one ``clm-studio: error:`` line, exit 2), and no file the session names is ever opened."""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
import random
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from core.analysis.targets import load_curve
from core.formats.session import MAX_SESSION_BYTES, check_session, parse_json
from studio.chains import RunSettings, chain_for, find
from studio.runner import Runner
from studio.session_file import load_session
from studio.state import Session

N_MUTATIONS = int(os.environ.get("CLM_FUZZ_SESSIONS", "400"))
N_UPLOADS = max(N_MUTATIONS // 8, 10)  # through the running studio (each accepted upload redraws it)
DEEP: Any = 0
for _ in range(40):
    DEEP = [DEEP]
POISON: list[Any] = [-math.inf, math.inf, math.nan, 1e308, -1, 10**30, "x", "", None, True, [], {}, [[[[1]]]],
                     {"a": {"b": {"c": 1}}}, "../../etc/passwd", "/dev/zero", "/etc/shadow", "/proc/self/environ",
                     -0.0, 2**63, DEEP, "cycloid:L=-1", "cycloid:L=nan,H=1,T=1", "cycloid"]
FORBIDDEN = ("/etc/", "/dev/", "/proc/")  # no session has a reason to make the studio open these


class Opens:
    """Every file the process opens while armed (an audit hook sees builtins.open, io.open, os.open and
    pathlib alike). An open of a sentinel or a system path is recorded and aborted before it happens, so a
    FIFO cannot hang the test and /dev/zero cannot fill memory."""

    def __init__(self) -> None:
        self.armed = False
        self.sentinels: list[str] = []
        self.bad: list[str] = []
        sys.addaudithook(self._hook)  # hooks cannot be removed: it stays, disarmed, for the session

    def _hook(self, event: str, args: tuple) -> None:
        if not self.armed or event != "open" or not isinstance(args[0], str | bytes | os.PathLike):
            return
        path = os.path.abspath(os.fsdecode(args[0]))
        if path.startswith(FORBIDDEN) or any(path == s or path.startswith(s + os.sep) for s in self.sentinels):
            self.bad.append(path)
            raise PermissionError(f"the test forbids opening {path}")

    @contextlib.contextmanager
    def watching(self, *sentinels: Path) -> Iterator[list[str]]:
        self.sentinels, self.bad, self.armed = [os.path.abspath(p) for p in sentinels], [], True
        try:
            yield self.bad
        finally:
            self.armed = False


OPENS = Opens()


@pytest.fixture(scope="module")
def real_session() -> dict[str, Any]:
    """A session with a finished stage and two branches, as JSON data."""
    s = Session.default()
    s.study.settings["subtask1"] = RunSettings("subtask1", pop_size=8, n_gen=2, seed=3)
    done = threading.Event()
    runner = Runner(s.lock, lambda: s.study, lambda p: None, done.set)
    chain = chain_for(s.view.design.mechanism)
    stage = find(chain, "subtask1")
    view = s.view
    runner.start(lambda st: st.plan(stage, s.study.settings_for(stage), view.design, view.target, False, chain))
    assert done.wait(60)
    runner.join(10)
    data = json.loads(json.dumps(s.to_dict()))
    pipe = data["study"]["pipeline"]
    data["study"]["branches"] = [{"label": "first", "pipeline": pipe}, {"label": "second", "pipeline": pipe}]
    return data


@pytest.fixture
def sentinels(tmp_path: Path) -> list[Path]:
    """Files a hostile session might name: a valid curve CSV, one named like a stored curve, and a FIFO."""
    secret = tmp_path / "secret.csv"
    secret.write_text("x,y\n0,0\n100,0\n100,50\n0,50\n")
    stored_lookalike = tmp_path / "target-0123456789abcdef0123.csv"
    stored_lookalike.write_text(secret.read_text())
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    return [tmp_path, secret, stored_lookalike, fifo]


def paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node[:3]):
            out += paths(v, (*prefix, i))
    return out


def mutate(data: dict[str, Any], rng: random.Random, files: list[Path]) -> dict[str, Any]:
    """1 to 3 edits: a value replaced by poison (or a key dropped); often a path where a name or target is."""
    d = copy.deepcopy(data)
    poison = POISON + [str(f) for f in files[1:]] + [f"{files[0]}/../{files[0].name}/secret.csv"]
    for _ in range(rng.randint(1, 3)):
        candidates = paths(d)[1:]
        named = [p for p in candidates if p and p[-1] in ("target", "name", "curve", "preset", "label")]
        path = rng.choice(named if named and rng.random() < 0.3 else candidates)
        parent = d
        for k in path[:-1]:
            parent = parent[k]
        key = path[-1]
        if isinstance(parent, dict) and rng.random() < 0.2:
            del parent[key]
        else:
            parent[key] = copy.deepcopy(rng.choice(poison))
    return d


def test_the_real_session_loads(real_session):
    s = Session.from_dict(copy.deepcopy(real_session))
    assert len(s.study.branches) == 2


def test_every_mutation_is_loaded_or_refused_with_one_line_and_opens_no_named_file(real_session, sentinels):
    rng = random.Random(20261124)
    refused = 0
    with OPENS.watching(*sentinels) as bad:
        for _ in range(N_MUTATIONS):
            d = mutate(real_session, rng, sentinels)
            try:
                Session.from_dict(d)
            except ValueError as exc:
                refused += 1
                assert "\n" not in str(exc) and str(exc)
    assert not bad, f"a session made the studio open {bad[:3]}"
    assert 0 < refused < N_MUTATIONS  # the mutations do reach both outcomes


def test_the_watch_can_fail(sentinels):
    with OPENS.watching(*sentinels) as bad:
        with pytest.raises(PermissionError):
            open(sentinels[1]).close()  # noqa: SIM115
        with pytest.raises(ValueError):
            load_curve(sentinels[1])  # os.open inside, reported as unreadable
    assert bad == [str(sentinels[1])] * 2


class FakeClient:
    """What the studio tells a browser tab: its notifications."""

    def __init__(self) -> None:
        self.notes: list[tuple[str, str]] = []

    def add_notification(self, title: str, body: str, **kwargs: Any) -> None:
        self.notes.append((title, body))


def test_an_upload_is_loaded_or_refused_with_one_notification_and_nothing_half_applied(real_session, sentinels):
    from studio.app import Studio

    rng = random.Random(7)
    studio = Studio(Session.from_dict(copy.deepcopy(real_session)), host="127.0.0.1", port=0)
    studio.animator.stop()  # the crank angle stays put: any change below is the upload's
    outcomes = set()
    try:
        with OPENS.watching(*sentinels) as bad:
            for i in range(N_UPLOADS):
                d = mutate(real_session, rng, sentinels)
                before = json.dumps(studio.session.to_dict())
                client = FakeClient()
                ok = studio.load_session_bytes(f"u{i}.json", json.dumps(d).encode(), client)  # NaN/Infinity too
                outcomes.add(ok)
                if ok:  # one note that it loaded (viser's own said nothing of the session)
                    assert [t for t, _ in client.notes] == ["Session loaded"], client.notes
                    assert client.notes[0][1].startswith(f"u{i}.json: ")
                    continue
                assert len(client.notes) == 1, client.notes
                title, body = client.notes[0]
                assert title == "Session not loaded" and "\n" not in body and body.startswith(f"u{i}.json: ")
                assert json.dumps(studio.session.to_dict()) == before  # the current session is untouched
        assert not bad, f"an upload made the studio open {bad[:3]}"
    finally:
        studio.close()
    assert outcomes == {True, False}


@pytest.mark.parametrize("algorithm", ["nsga2", [], None, 3, {"name": ["x"]}])
def test_free_form_stage_settings_load_and_draw(real_session, algorithm):
    """A stage result's settings are free-form: whatever they hold, an upload loads and the charts draw
    (found by this fuzz test: a list there made the Pareto panel raise after the session was applied)."""
    from studio.app import Studio

    d = copy.deepcopy(real_session)
    assert d["study"]["results"], "the session stores its stage results by hash (version 3)"
    for r in d["study"]["results"].values():
        r["settings"]["algorithm"] = algorithm
    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        client = FakeClient()
        assert studio.load_session_bytes("s.json", json.dumps(d).encode(), client), client.notes
        assert studio.session.study.pipeline is not None
    finally:
        studio.close()


def test_a_refused_session_at_startup_is_one_error_line_and_exit_2(real_session, sentinels, tmp_path_factory,
                                                                    capsys):
    from studio.serve import main

    folder = tmp_path_factory.mktemp("sessions")  # the session file itself is opened: not among the sentinels
    rng = random.Random(11)
    checked = 0
    with OPENS.watching(*sentinels) as bad:
        while checked < 15:
            d = mutate(real_session, rng, sentinels)
            try:
                Session.from_dict(copy.deepcopy(d))
                continue  # loaded: main would serve it until Ctrl-C
            except ValueError:
                pass
            f = folder / f"s{checked}.json"
            f.write_text(json.dumps(d))
            before = f.read_bytes()
            assert main(["--session", str(f), "--port", "0"]) == 2
            err = capsys.readouterr().err.splitlines()
            assert len(err) == 1 and err[0].startswith(f"clm-studio: error: {f}: "), err
            assert f.read_bytes() == before  # a refused session file is never overwritten
            checked += 1
    assert not bad


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["playback"].update(angle=-math.inf), "playback.angle: must be finite"),
    (lambda d: d["playback"].update(speed="fast"), "playback.speed: expected a number"),
    (lambda d: d["study"]["branches"][1].update(label="first"), "'first' is already the label of branch 1"),
    (lambda d: d["study"].update(colour=1), "study.colour: unknown key"),
    (lambda d: d.update(version=True), "unsupported session version"),
])
def test_hostile_values_are_named(real_session, edit, message):
    d = copy.deepcopy(real_session)
    edit(d)
    with pytest.raises(ValueError, match=message):
        Session.from_dict(d)


def test_a_key_given_twice_is_refused_not_read_as_its_last_value(real_session):
    # A hand-edited session with "r1" twice in the design silently took the second value.
    text = json.dumps(real_session)
    twice = text.replace('"params": {', '"params": {"r1": 1.0, ', 1)
    assert twice != text
    with pytest.raises(ValueError, match="^not a session: key 'r1' appears twice in one object$"):
        parse_json(twice)
    assert parse_json(text) == real_session


def test_deep_nesting_and_oversized_files_are_refused(tmp_path: Path):
    deep = "[" * 100_000 + "]" * 100_000
    with pytest.raises(ValueError, match="nested too deep|not JSON"):
        parse_json(deep)
    with pytest.raises(ValueError, match="nested deeper"):
        check_session({"format": "clm-studio-session", "version": 2, "design": {}, "target": {},
                       "walk": json.loads("[" * 40 + "]" * 40)})
    big = tmp_path / "big.json"
    with big.open("wb") as f:
        f.truncate(MAX_SESSION_BYTES + 1)
    with pytest.raises(ValueError, match="at most"):
        load_session(big)
    with pytest.raises(ValueError, match="not a regular file"):
        load_session(tmp_path)


def with_stage_target(data: dict[str, Any], value: str, branch: bool = False) -> dict[str, Any]:
    d = copy.deepcopy(data)
    pipe = d["study"]["branches"][0]["pipeline"] if branch else d["study"]["pipeline"]
    pipe["stages"][0]["problem"]["options"]["target"] = value
    return d


@pytest.mark.parametrize("branch", [False, True])
def test_a_session_never_makes_the_studio_open_a_path(real_session, sentinels, branch):
    tmp = sentinels[0]
    values = [*(str(f) for f in sentinels[1:]), "../../etc/passwd", "/dev/zero", "/etc/shadow", "/proc/self/environ",
              f"{tmp}/../{tmp.name}/secret.csv", "C:\\Users\\x\\target-0123456789abcdef0123.csv"]
    with OPENS.watching(*sentinels) as bad:
        for value in values:
            with pytest.raises(ValueError, match="target") as exc:
                Session.from_dict(with_stage_target(real_session, value, branch))
            assert "\n" not in str(exc.value)
    assert not bad


def test_cli_curves_must_be_regular_files_of_bounded_size(tmp_path: Path):
    fifo = tmp_path / "curve.csv"
    os.mkfifo(fifo)
    for p in (fifo, Path("/dev/zero"), tmp_path):
        with pytest.raises(ValueError, match="not a regular file"):
            load_curve(p)  # refused at once: a FIFO would otherwise block, /dev/zero never end
    big = tmp_path / "big.csv"
    with big.open("wb") as f:
        f.truncate(11 * 2**20)
    with pytest.raises(ValueError, match="MB"):
        load_curve(big)
