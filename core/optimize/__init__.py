"""Optimization: problems over search boxes, stages, pipelines, multi-start chains, baselines, knee points.

Evolution runs on arrays (``evolve``) behind pymoo's Algorithm API; a design run is ``run.run_design``.
May import ``core.analysis`` and ``core.kinematics``; never ``core.formats``, ``core.study`` or ``core.cli``.


- ``box``: a stage's search box (spec §6).
- ``problem``: metrics -> pymoo objectives/constraints; the problem registry.
- ``algorithms``: pymoo algorithms by name.
- ``stage``: one stage, stepped generation by generation or run headless.
- ``result``: a stage's result, its pick and lossless JSON.
- ``pipeline``: stages chained by picks.
- ``multistart``: a block of stages rerun as several chains with other seeds; the best chain goes on.
- ``examples``: small test problems.
Knee points live in ``core.optimize.decision``.
"""

from __future__ import annotations

from core.optimize.algorithms import ALGORITHMS, AlgorithmSpec, make_algorithm
from core.optimize.box import SUBTASK_STEPS, Box, global_box, search_box
from core.optimize.pipeline import Pipeline, seeded
from core.optimize.problem import ASSEMBLY, Constraint, DesignProblem, ProblemSpec, make_problem, register
from core.optimize.result import StageResult
from core.optimize.stage import Progress, Stage, StageSpec

__all__ = [
    "ALGORITHMS",
    "ASSEMBLY",
    "SUBTASK_STEPS",
    "AlgorithmSpec",
    "Box",
    "Constraint",
    "DesignProblem",
    "Pipeline",
    "ProblemSpec",
    "Progress",
    "Stage",
    "StageResult",
    "StageSpec",
    "global_box",
    "make_algorithm",
    "make_problem",
    "register",
    "search_box",
    "seeded",
]
