"""Multi-start records by hand: chain seeds as docs/optimization.md gives them, a chain's last pick."""

from __future__ import annotations

from core.formats.config import parse_config
from core.optimize.design_config import placeholder
from core.optimize.lineage import _Chain
from core.optimize.multistart import Chain
from core.optimize.pipeline import Pipeline, seeded
from core.optimize.stage import derived_seed

CFG = {"name": "x", "preset": "stephenson1/X0", "seed": 5, "n_samples": 72,
       "algorithm": {"name": "nsga2", "pop_size": 8},
       "stages": [{"name": n, "box": n, "n_gen": 1} for n in ("subtask1", "subtask2", "subtask3")]}


def test_chain_j_runs_stage_k_with_seed_plus_k_plus_1000_j() -> None:
    # docs/optimization.md, "Multi-start": chain j runs stage k with seed `seed + k + 1000 j`.
    config = parse_config(CFG)
    pipe = Pipeline([s.spec(5 + k, placeholder(s.options)) for k, s in enumerate(config.stages)], config.start)
    assert _Chain(config, pipe, 1, 2, 0).seeds == (6, 7)  # chain 0 is the single-start run: seed + k
    assert _Chain(config, pipe, 1, 2, 3).seeds == (3006, 3007)
    assert _Chain(config, pipe, 0, 2, 1).seeds == (1005, 1006, 1007)


def test_seeds_past_the_top_of_numpys_range_wrap_to_its_bottom() -> None:
    top = 2**32 - 1
    config = parse_config({**CFG, "seed": top - 1})
    pipe = Pipeline([s.spec(derived_seed(top - 1, k), placeholder(s.options)) for k, s in enumerate(config.stages)],
                    config.start)
    assert [s.seed for s in pipe.stages] == [top - 1, top, 0]
    assert _Chain(config, pipe, 0, 2, 1).seeds == (998, 999, 1000)
    assert [s.seed for s in seeded(pipe.stages, top)] == [top, 0, 1]


def test_a_chains_last_metrics_are_those_of_its_last_stage() -> None:
    c = Chain(0, (1, 2), "complete", (3, 4), ({"S": 1.0}, {"S": 2.0}), ({}, {}), True, 0.0)
    assert c.last == {"S": 2.0}
    assert Chain(1, (), "cancelled", (), (), (), False, 0.0).last == {}
