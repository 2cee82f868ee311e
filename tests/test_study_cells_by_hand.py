"""A study cell's config, its measurements and the store's rows, checked on hand-made inputs (no Dask)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from core.study.cell import case_config, measure
from core.study.store import Store

CONFIG = """
name = "hand"
preset = "stephenson1/X0"
seed = 5
workers = 4
[algorithm]
name = "nsga2"
pop_size = 30
[[stages]]
name = "a"
n_gen = 3
starts = { n = 3, until = "b", select = "best:S" }
[[stages]]
name = "b"
n_gen = 4
[stages.algorithm]
name = "spea2"
[[stages]]
name = "c"
n_gen = 5
"""


def test_a_cell_narrows_the_case_to_its_stages_budget_seed_start_and_algorithm(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(CONFIG)
    case = {"name": "k", "config": str(path), "stages": ["c", "a"], "budget": 300, "start": "stephenson1/X1"}
    data = case_config(case, {"name": "cmoemt", "pop_size": 12, "options": {"x": 1}}, 7)
    # The case's stages, in the case's order, each with the budget in evaluations and no multi-start or own algorithm.
    assert [s["name"] for s in data["stages"]] == ["c", "a"]
    for s in data["stages"]:
        assert s["max_evals"] == 300 and s["n_gen"] == 300
        assert "starts" not in s and "algorithm" not in s
    assert data["preset"] == "stephenson1/X1" and data["seed"] == 7 and data["workers"] == 1
    assert data["algorithm"] == {"name": "cmoemt", "pop_size": 12, "options": {"x": 1}}
    # Without a population size of its own, the cell keeps the config's.
    data = case_config({**case, "start": None, "stages": None}, {"name": "nsga2"}, 2)
    assert data["algorithm"]["pop_size"] == 30 and data["preset"] == "stephenson1/X0" and data["seed"] == 2
    assert [s["name"] for s in data["stages"]] == ["a", "b", "c"]


def _result(name: str, n_evals: int, F: np.ndarray, feasible: np.ndarray, status: str = "complete") -> SimpleNamespace:
    return SimpleNamespace(name=name, n_evals=n_evals, objectives=("f1", "f2"), F=F, feasible=feasible, status=status)


def test_measure_counts_every_stage_s_evaluations_and_keeps_the_last_stage_s_feasible_front() -> None:
    F = np.array([[1.0, 4.0], [0.0, 0.0], [2.0, 2.0], [3.0, 3.0], [4.0, 1.0]])
    feasible = np.array([True, False, True, True, True])  # (0, 0) dominates all but violates
    run = SimpleNamespace(results=[_result("a", 100, F, feasible, "stopped"), _result("b", 40, F, feasible)],
                          wall_time=2.5, status="complete", final=lambda: None)
    m = measure(run)
    assert m["n_eval"] == 140 and m["stage"] == "b" and m["run_status"] == "complete"
    assert m["stopped_early"] == ["a"]  # its config's stop_below ended stage a before the budget
    # One that met its stop_below on the last generation it had spent the whole budget: not early (review, s. 37).
    last = _result("a", 100, F, feasible, "stopped")
    last.settings, last.generation = {"max_evals": 100, "n_gen": 100}, 4
    assert measure(SimpleNamespace(results=[last], wall_time=1.0, status="complete",
                                   final=lambda: None))["stopped_early"] == []
    last.n_evals = 60
    assert measure(SimpleNamespace(results=[last], wall_time=1.0, status="complete",
                                   final=lambda: None))["stopped_early"] == ["a"]
    assert m["feasible_ratio"] == 0.8
    assert sorted(map(tuple, m["front"])) == [(1.0, 4.0), (2.0, 2.0), (4.0, 1.0)]


def _record(key: str, case: str, alg: str, seed: int, status: str) -> dict:
    return {"key": key, "case": case, "algorithm": alg, "seed": seed, "status": status, "result": "{}",
            "metrics": {"n_eval": 1}, "task_time": 0.1, **({"error": "boom"} if status == "failed" else {})}


def test_the_store_keeps_done_cells_counts_attempts_and_orders_by_case_algorithm_seed(tmp_path: Path) -> None:
    store = Store(tmp_path)
    try:
        store.save(_record("z", "c1", "nsga2", 1, "failed"))
        assert store.done() == set()  # a failed cell runs again
        store.save(_record("z", "c1", "nsga2", 1, "done"))
        store.save(_record("a", "c1", "nsga2", 10, "done"))
        store.save(_record("m", "c1", "nsga2", 9, "done"))
        store.save(_record("b", "c0", "spea2", 3, "failed"))
        assert store.done() == {"z", "a", "m"}
        rows = store.rows()
        assert [r["key"] for r in rows] == ["b", "z", "m", "a"]  # c0 first; then seeds 1, 9, 10 (numbers)
        assert {r["key"]: r["attempts"] for r in rows} == {"b": 1, "z": 2, "m": 1, "a": 1}
        assert rows[1]["result_path"] == str(Path("runs") / "c1" / "nsga2" / "1.json")
        assert (tmp_path / rows[1]["result_path"]).read_text() == "{}"
        assert rows[0]["result_path"] is None and rows[0]["error"] == "boom"
    finally:
        store.close()


def test_measure_keeps_the_final_pick_its_feasibility_and_parameters() -> None:
    F = np.array([[1.0, 4.0], [2.0, 2.0]])
    last = SimpleNamespace(name="b", n_evals=10, status="complete", objectives=("f1", "f2"), F=F,
                           feasible=np.array([True, False]),
                           metrics={"S": np.array([40.0, 55.0]), "I": np.array([3.0, 9.0]), "f1": F[:, 0]},
                           named=lambda i: {"r1": 10.0 + i})
    run = SimpleNamespace(results=[last], wall_time=1.0, status="complete", final=lambda: (last, 1))
    m = measure(run)
    assert m["pick"] == {"S": 55.0, "I": 9.0}  # the study's pick metrics only
    assert m["pick_feasible"] is False and m["params"] == {"r1": 11.0}


def test_the_warm_up_runs_each_algorithm_and_each_case_once_with_a_few_generations() -> None:
    from core.study.cell import warm_cells

    cells = [{"key": f"{k}/{a}/{s}", "seed": s, "algorithm": {"name": a, "pop_size": p},
              "case": {"name": k, "budget": 20000}}
             for k in ("s1", "s2", "s3") for a, p in (("nsga2", 200), ("imtcmo", 100)) for s in (1, 2)]
    warm = warm_cells(cells)
    # Every algorithm on the first case and the first algorithm on every case: 2 + 3 - 1 cells, not 12.
    assert [(c["case"]["name"], c["algorithm"]["name"]) for c in warm] == \
        [("s1", "nsga2"), ("s1", "imtcmo"), ("s2", "nsga2"), ("s3", "nsga2")]
    assert [c["case"]["budget"] for c in warm] == [601, 301, 601, 601]  # a few generations, whatever N per one
    assert cells[0]["case"]["budget"] == 20000 and warm_cells([]) == []  # the study's own cells untouched
