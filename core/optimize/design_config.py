"""A validated design configuration: its stages and settings, as ``core.formats.config`` builds them from a
file and ``core.optimize.run`` runs them."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics import presets
from core.kinematics.design import Design
from core.kinematics.model import Mechanism
from core.optimize.algorithms import AlgorithmSpec
from core.optimize.baselines import DP_METHODS, BaselineSettings
from core.optimize.multistart import Starts
from core.optimize.problem import Constraint, ProblemSpec, make_problem
from core.optimize.result import PickRule
from core.optimize.stage import StageSpec
from core.optimize.subtasks import LIMIT_METRICS

F64 = NDArray[np.float64]

METHODS = ("hierarchical", "single_level", *DP_METHODS)
BACKENDS = ("auto", "numpy", "numba")
SHAPE_PROBLEMS = ("predesign", "subtask1", "subtask2", "subtask3", "single_level", "dp")
PAPER_OUTPUT = presets.PAPER_PANTOGRAPH

@dataclass(frozen=True)
class StageConfig:
    """One ``[[stages]]`` entry, validated; ``options`` may still hold relative limits."""

    name: str
    problem: str
    s: float | None
    d: float
    n_gen: int
    pick: PickRule
    algorithm: AlgorithmSpec
    options: Mapping[str, Any]
    stop_below: tuple[float, ...] | None = None
    fixed: tuple[str, ...] = ()
    seed_start: bool = True
    pick_where: tuple[Constraint, ...] = ()
    starts: Starts | None = None
    max_evals: int | None = None

    def problem_spec(self) -> ProblemSpec:
        """The stage's problem with relative limits replaced by non-binding placeholders."""
        return make_problem(self.problem, **placeholder(self.options))

    def spec(self, seed: int, options: Mapping[str, Any] | None = None) -> StageSpec:
        """The :class:`StageSpec` with resolved options (default: ``options`` as given, which must be numbers)."""
        prob = make_problem(self.problem, **dict(self.options if options is None else options))
        return StageSpec(self.name, prob, s=self.s, d=self.d, algorithm=self.algorithm, n_gen=self.n_gen, seed=seed,
                         max_evals=self.max_evals,
                         fixed=self.fixed, seed_start=self.seed_start, stop_below=self.stop_below,
                         pick=self.pick)


@dataclass(frozen=True)
class DesignConfig:
    """A validated design configuration (see the module doc).

    Attributes:
        name: label of the run.
        method: one of ``METHODS``.
        mechanism: the topology (with the configuration's ``[bounds]`` applied).
        start: the one-member start design (a preset, or the middle of the bounds).
        seed: run seed (stage k uses seed + k, wrapped past 2**32 - 1).
        stages: the stages (hierarchical / single_level).
        baseline: DP baseline settings (DP methods).
        source: the parsed TOML as a dict (recorded in results).
        path: the configuration file, if read from one.
        workers: processes a multi-start block's chains run in (0: every available core). The
            results do not depend on it: every chain's stages are seeded.
    """

    name: str
    method: str
    mechanism: Mechanism
    start: Design
    seed: int
    stages: tuple[StageConfig, ...] = ()
    baseline: BaselineSettings = field(default_factory=BaselineSettings)
    source: Mapping[str, Any] = field(default_factory=dict)
    path: str | None = None
    workers: int = 0
    scheduler: str | None = None  # a Dask scheduler address: multi-start chains run on that cluster


# ---------------------------------------------------------------------------------------
# Running.


def placeholder(options: Mapping[str, Any], absolute: bool = False) -> dict[str, Any]:
    """Options with relative limits replaced by numbers.

    Args:
        options: stage options.
        absolute: keep the absolute entries of a list of limits (``[1.0, "start+0.5"]`` -> 1.0), so
            the next stage's absolute thresholds can steer a pick; otherwise (and for a lone relative
            limit) a huge number, a constraint that never binds.
    """
    out = {}
    for k, v in options.items():
        if k in LIMIT_METRICS and isinstance(v, (str, list)):
            nums = [float(x) for x in v if not isinstance(x, str)] if isinstance(v, list) and absolute else []
            v = max(nums) if nums else 1e300
        out[k] = v
    return out


