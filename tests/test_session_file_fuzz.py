"""A session file is loaded or refused with one message, whatever it holds: mutations of a real session
(wrong types, non-finite and huge numbers, deep nesting, repeated branch labels, dropped keys) never raise
anything but ValueError, and the refusal is one line."""

from __future__ import annotations

import copy
import json
import math
import os
import random
import threading
from pathlib import Path
from typing import Any

import pytest

from core.formats.session import MAX_SESSION_BYTES, check_session, parse_json
from studio.chains import RunSettings, chain_for, find
from studio.runner import Runner
from studio.session_file import load_session
from studio.state import Session

N_MUTATIONS = int(os.environ.get("CLM_FUZZ_SESSIONS", "400"))
POISON: list[Any] = [-math.inf, math.inf, math.nan, 1e308, -1, 10**30, "x", "", None, True, [], {}, [[[[1]]]],
                     {"a": {"b": {"c": 1}}}, "../../etc/passwd", "/dev/zero", -0.0, 2**63]


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


def paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node[:3]):
            out += paths(v, (*prefix, i))
    return out


def mutate(data: dict[str, Any], rng: random.Random) -> dict[str, Any]:
    d = copy.deepcopy(data)
    for _ in range(rng.randint(1, 3)):
        path = rng.choice(paths(d)[1:])
        parent = d
        for k in path[:-1]:
            parent = parent[k]
        key = path[-1]
        if isinstance(parent, dict) and rng.random() < 0.2:
            del parent[key]
        else:
            parent[key] = copy.deepcopy(rng.choice(POISON))
    return d


def test_the_real_session_loads(real_session):
    s = Session.from_dict(copy.deepcopy(real_session))
    assert len(s.study.branches) == 2


def test_every_mutation_is_loaded_or_refused_with_one_line(real_session):
    rng = random.Random(20261124)
    refused = 0
    for _ in range(N_MUTATIONS):
        d = mutate(real_session, rng)
        try:
            Session.from_dict(d)
        except ValueError as exc:
            refused += 1
            assert "\n" not in str(exc) and str(exc)
    assert 0 < refused < N_MUTATIONS  # the mutations do reach both outcomes


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
def test_a_session_never_makes_the_studio_open_a_path(real_session, tmp_path, monkeypatch, branch):
    sentinel = tmp_path / "secret.csv"
    sentinel.write_text("x,y\n0,0\n100,0\n100,50\n0,50\n")
    opened: list[str] = []
    real_open, real_os_open = open, os.open

    def spy_open(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    def spy_os_open(path, *args, **kwargs):
        opened.append(str(path))
        return real_os_open(path, *args, **kwargs)

    monkeypatch.setattr("builtins.open", spy_open)
    monkeypatch.setattr(os, "open", spy_os_open)
    for value in (str(sentinel), "../../etc/passwd", "/dev/zero", "/etc/shadow",
                  str(tmp_path / "target-0123456789abcdef0123.csv")):
        with pytest.raises(ValueError, match="target"):
            Session.from_dict(with_stage_target(real_session, value, branch))
    assert not [p for p in opened if "secret" in p or "passwd" in p or "zero" in p or "shadow" in p]


def test_cli_curves_must_be_regular_files_of_bounded_size(tmp_path: Path):
    from core.analysis.targets import load_curve

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
