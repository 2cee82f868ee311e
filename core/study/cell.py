"""One study cell, self-contained: (algorithm, case, seed) in as plain data, a JSON-able record out.

The case's design config is read again in the task (no pickled state), narrowed to the case's
stages, started from its preset, given the cell's algorithm and seed, run on one core (multi-start
blocks off: a study compares algorithms seed by seed) and measured.
"""

from __future__ import annotations

import time
import tomllib
import traceback
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from core.formats.config import parse_config
from core.formats.study import Study, case_stages
from core.kinematics.kernel_cache import CompileTimer
from core.optimize.decision import pareto_front
from core.optimize.result import dumps
from core.optimize.run import run_design
from core.study.provenance import code_digest

PICK_METRICS = ("mse", "S", "I", "h_s", "h6", "h4", "dh6", "dh4")
def read_config(path: str) -> dict[str, Any]:
    # utf-8-sig: a BOM, which load_config and load_study take, failed here when the study ran (review of session 31)
    return tomllib.loads(Path(path).read_text(encoding="utf-8-sig"))


def stage_names(data: dict[str, Any]) -> list[str]:
    return [str(s.get("name", "")) for s in data.get("stages", []) if isinstance(s, dict)]


def case_config(case: dict[str, Any], algorithm: dict[str, Any], seed: int) -> dict[str, Any]:
    """The case's config narrowed to one cell (plain TOML data, checked later by ``parse_config``)."""
    data = read_config(case["config"])
    missing = [n for n in case.get("stages") or [] if n not in stage_names(data)]
    if missing:
        raise ValueError(f"case {case['name']!r}: no stage {missing[0]!r} in {case['config']} "
                         f"(stages: {', '.join(stage_names(data))})")
    # The same narrowing as the settings a cell is compared by (core.formats.study.effective_settings).
    stages = case_stages(list(data.get("stages", [])), list(case.get("stages") or []))
    base = dict(data.get("algorithm", {}))
    pop = int(algorithm.get("pop_size") or base.get("pop_size", 100))
    for s in stages:
        # The budget is in evaluations, whatever an algorithm spends per generation (N to 3N; CMOES's second
        # stage a varying N + |P2| + |P3|): the stage ends once it is spent. n_gen is only a bound that never binds
        # first (every generation evaluates at least one design).
        s["max_evals"] = int(case["budget"])
        s["n_gen"] = int(case["budget"])
    if case.get("start"):
        data["preset"] = case["start"]
    data["stages"] = stages
    data["seed"] = int(seed)
    data["workers"] = 1
    data["algorithm"] = {"name": algorithm["name"], "pop_size": pop, "options": dict(algorithm.get("options", {}))}
    return data


def _front(F: np.ndarray, feasible: np.ndarray) -> list[list[float]]:
    ok = feasible & np.isfinite(F).all(axis=1)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    front = idx[pareto_front(F[idx])]
    return F[front].tolist()


def _stopped_early(r: Any) -> bool:
    """Its config's stop_below ended the stage (the RTCLM's, the paper's rule) before the budget or its generations
    were spent (one that met it on its last generation spent them all: review, session 37)."""
    if r.status != "stopped":
        return False
    settings = getattr(r, "settings", None) or {}
    budget, gens = settings.get("max_evals"), settings.get("n_gen")
    return not ((budget is not None and r.n_evals >= budget) or (gens is not None and r.generation >= gens))


def measure(run: Any) -> dict[str, Any]:
    """What a study keeps of a finished run: the last stage's front, feasibility, the pick, time, evaluations."""
    results = run.results
    out: dict[str, Any] = {"n_eval": int(sum(r.n_evals for r in results)), "wall_time": float(run.wall_time),
                           "run_status": run.status,
                           "stopped_early": [r.name for r in results if _stopped_early(r)]}
    if not results:
        return out
    last = results[-1]
    feasible = np.asarray(last.feasible)
    out.update(objectives=list(last.objectives), front=_front(np.asarray(last.F), feasible),
               feasible_ratio=float(feasible.mean()) if feasible.size else 0.0, stage=last.name)
    fin = run.final()
    if fin is not None:
        r, i = fin
        out["pick"] = {k: float(r.metrics[k][i]) for k in PICK_METRICS if k in r.metrics}
        out["pick_feasible"] = bool(r.feasible[i])
        out["params"] = r.named(i)
    return out


def check_cells(study: Study) -> None:
    """ValueError (one line, naming the case and algorithm) for a pair whose cells could only fail: a start
    preset of another mechanism, a population the algorithm refuses, ... (what ``clm design`` refuses at load)."""
    for i, case in enumerate(study.cases):
        c = msgspec.to_builtins(case)
        for a in study.algorithms:
            data = case_config(c, msgspec.to_builtins(a), study.seeds[0])
            try:
                parse_config(data, Path(case.config).parent, case.config)
            except ValueError as e:
                raise ValueError(f"cases[{i}] ({case.name!r}) with algorithm {a.name!r}: {e}") from None


def run_cell(cell: dict[str, Any]) -> dict[str, Any]:
    """Run one cell; never raises: a failure comes back as ``status = "failed"`` with its message."""
    t0 = time.perf_counter()
    record: dict[str, Any] = {"key": cell["key"], "algorithm": cell["algorithm"]["name"],
                              "case": cell["case"]["name"], "seed": cell["seed"], "code": code_digest()}
    try:
        if cell.get("threads"):
            import numba

            numba.set_num_threads(max(1, min(int(cell["threads"]), numba.config.NUMBA_NUM_THREADS)))
        data = case_config(cell["case"], cell["algorithm"], cell["seed"])
        config = parse_config(data, Path(cell["case"]["config"]).parent, cell["case"]["config"])
        with CompileTimer() as compiling:
            run = run_design(config)
        metrics = measure(run)
        # The time row is the algorithm's: kernels a cell compiles (those the warm cells did not reach) are not
        # (rehearsal 5: one CMOES cell 39 s, the other 3.7 s, and CMOES read nine times slower).
        metrics["compile_time"] = compiling.seconds
        metrics["wall_time"] = max(0.0, metrics["wall_time"] - compiling.seconds)
        record.update(status="done", metrics=metrics, result=dumps(run.to_dict(), indent=None))
    except Exception as e:  # a cell's failure is data for the study, not a crash of it
        origin = e.__cause__ or e  # a stage's own exception (StageFailed wraps it)
        last = traceback.extract_tb(origin.__traceback__)[-1] if origin.__traceback__ else None
        where = f" ({Path(last.filename).name}:{last.lineno})" if last else ""
        record.update(status="failed", error=f"{type(e).__name__}: {e}{where}")
    record["task_time"] = time.perf_counter() - t0
    return record


def warm_cells(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """A few cells to run on every worker before the study's own, with a budget of a few generations: each
    algorithm on the first case and the first algorithm on each case, so that every kernel the cells use is loaded
    (or compiled) before any cell is timed. Without them the first cell a worker ran took ~0.7 s more, which the
    report's time row counted against the algorithm listed first."""
    if not cells:
        return []
    seen: set[tuple[str, str]] = set()
    out = []
    first_alg, first_case = cells[0]["algorithm"]["name"], cells[0]["case"]["name"]
    for c in cells:
        a, k = c["algorithm"]["name"], c["case"]["name"]
        if (k == first_case or a == first_alg) and (a, k) not in seen:
            seen.add((a, k))
            pop = int(c["algorithm"].get("pop_size") or 100)
            out.append(dict(c, case=dict(c["case"], budget=3 * pop + 1)))
    return out


def warm_up(cells: list[dict[str, Any]]) -> None:
    """Run the warm-up cells (:func:`warm_cells`) here and forget them (a failure shows in the study's own)."""
    for c in cells:
        run_cell(c)

