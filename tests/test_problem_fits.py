"""A problem says which mechanisms it cannot optimize, and why; configs, stages and the studio refuse the pair."""

from __future__ import annotations

import re

import pytest

from core.formats.config import parse_config
from core.kinematics import presets
from core.kinematics.mechanisms import get
from core.optimize import AlgorithmSpec, StageSpec, make_problem
from core.optimize.problem import Constraint
from core.optimize.stage import Stage
from studio.chains import RunSettings, chain_for, find, problems_for
from studio.state import Session

X3 = presets.get("stephenson1/X3").design()
RTCLM = presets.get("rtclm/case1").design()


@pytest.mark.parametrize(("problem", "options", "design", "reason"), [
    ("rtclm1", {}, X3, "it measures the reconfigurable leg's two modes"),
    ("rtclm2", {}, X3, "so it optimizes the RTCLM alone"),
    ("predesign", {}, RTCLM, "places every design on the target analytically, which this mechanism does not allow"),
    ("subtask1", {}, RTCLM, "no analytic placement for a mechanism with derived values"),
])
def test_a_problem_refuses_a_mechanism_it_cannot_optimize_saying_why(problem, options, design, reason):
    spec = make_problem(problem, **options)
    title = re.escape(design.mechanism.title)
    with pytest.raises(ValueError, match=f"problem '{problem}' does not fit the {title}: .*{re.escape(reason)}"):
        spec.check_fits(design.mechanism)
    with pytest.raises(ValueError, match=f"stage 'x': problem '{problem}' does not fit"):
        Stage(StageSpec("x", spec, algorithm=AlgorithmSpec("nsga2", 8), n_gen=1), design)


@pytest.mark.parametrize(("problem", "options", "design"), [
    ("rtclm1", {}, RTCLM), ("subtask2", {}, RTCLM), ("subtask1", {"place": "none"}, RTCLM), ("predesign", {}, X3),
    ("bowl", {}, RTCLM), ("dp", {}, RTCLM),
])
def test_a_problem_that_fits_is_not_refused(problem, options, design):
    make_problem(problem, **options).check_fits(design.mechanism)  # no error


def test_a_configuration_refuses_the_pair_naming_the_stage():
    cfg = {"name": "x", "preset": "stephenson1/X3", "algorithm": {"pop_size": 8},
           "stages": [{"name": "a", "problem": "rtclm1", "n_gen": 1}]}
    with pytest.raises(ValueError, match=r"stages\[0\]\.problem: problem 'rtclm1' does not fit the Stephenson-I"):
        parse_config(cfg)
    cfg["stages"] = [{"name": "rtclm1", "n_gen": 1}]  # the problem named by the stage
    with pytest.raises(ValueError, match=r"stages\[0\]\.problem: problem 'rtclm1' does not fit the Stephenson-I"):
        parse_config(cfg)


def test_the_studio_offers_only_the_problems_that_fit_and_no_analytic_example():
    six = problems_for(get("stephenson1"))
    assert {"predesign", "subtask1", "subtask2", "subtask3"} <= set(six)
    assert not {"rtclm1", "rtclm2", "bowl", "path_box"} & set(six)
    rt = problems_for(get("rtclm_primary"))
    assert {"rtclm1", "rtclm2"} <= set(rt) and not {"predesign", "subtask1"} & set(rt)
    for mech in ("stephenson1", "rtclm_primary", "jansen"):  # every stage's own problem is offered
        assert {c.name for c in chain_for(get(mech))} <= set(problems_for(get(mech)))


def test_run_refuses_a_problem_that_does_not_fit_the_editor_with_its_reason():
    s = Session.default()
    chain = chain_for(s.view.design.mechanism)
    stage = find(chain, "subtask2")
    settings = RunSettings("rtclm1", pop_size=8, n_gen=1)  # as a session file could carry it
    with pytest.raises(ValueError, match="problem 'rtclm1' does not fit the Stephenson-I six-bar"):
        s.study.plan(stage, settings, s.view.design, s.view.target, False, chain)
    assert s.study.pipeline is None and s.study.status.state == "idle"


@pytest.mark.parametrize(("preset", "config"), [("stephenson1/X0", "stephenson1_cycloid.toml"),
                                                ("rtclm/case1", "rtclm_case1.toml")])
def test_the_studio_chain_starts_with_the_shipped_configs_budgets_and_picks(preset: str, config: str) -> None:
    # The studio's RTCLM stages ran 50 x 50 where the configs run 100 x 200 / 1500 with the same early stop, and
    # ended 2.2 mm from h6 and 34 mm from h4 while clm design met both within 0.5 mm.
    from pathlib import Path

    from core.formats.config import load_config

    cfg = load_config(Path(__file__).resolve().parents[1] / "assets" / "configs" / config)
    by_name = {s.name: s for s in cfg.stages}
    chain = chain_for(presets.get(preset).design().mechanism)
    for stage in chain:
        c = by_name[stage.name]
        assert (stage.pop_size, stage.n_gen, stage.pick) == (c.algorithm.pop_size, c.n_gen, c.pick), stage.name
        assert stage.stop_below == c.stop_below, stage.name
        if c.pick_where or stage.name != "subtask2":
            assert stage.pick_where == c.pick_where, stage.name
        else:  # the config's subtask 2 picks among the members that meet subtask 3's I_max (1 mm/s): the studio says so
            assert stage.pick_where == (Constraint("I", upper=float(by_name["subtask3"].options["I_max"][0])),)
