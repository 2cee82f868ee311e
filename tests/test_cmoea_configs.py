"""Each constrained MOEA runs the paper's subtasks and an RTCLM case end to end from a config (tiny budgets)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from core.formats.config import load_config
from core.optimize.algorithms import AlgorithmSpec
from core.optimize.run import run_design

CONFIGS = Path(__file__).resolve().parents[1] / "assets" / "configs"
CMOEAS = ["cmoemt", "cmoes", "drlos_emcmo", "imtcmo", "mccmo", "moead_cmt"]


@pytest.mark.parametrize("algorithm", CMOEAS)
@pytest.mark.parametrize("config", ["stephenson1_cycloid.toml", "rtclm_case1.toml"])
def test_the_algorithm_runs_every_stage_of_a_paper_design(algorithm, config):
    c = load_config(CONFIGS / config)
    stages = tuple(replace(s, n_gen=2, starts=None, algorithm=AlgorithmSpec(algorithm, 20)) for s in c.stages)
    run = run_design(replace(c, stages=stages, workers=1))
    assert [r.name for r in run.results] == [s.name for s in stages]
    for r in run.results:
        assert r.n_evals > 0 and r.picked is not None and r.pop > 0


@pytest.mark.parametrize("algorithm", CMOEAS)
def test_each_cmoea_config_ships_and_names_its_algorithm(algorithm):
    c = load_config(CONFIGS / f"stephenson1_cycloid_{algorithm}.toml")
    assert {s.algorithm.name for s in c.stages} == {algorithm}
    base = load_config(CONFIGS / "stephenson1_cycloid.toml")
    assert [s.name for s in c.stages] == [s.name for s in base.stages]
