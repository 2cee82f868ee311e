"""Baselines of paper §3.4.3-3.4.4: single-level optimization and discrete-point (DP) synthesis.

- Single-level: all five objectives at once over the global box, the ``single_level`` problem
  of ``core.optimize.subtasks`` run as a one-stage pipeline (``core.formats.config``).
- DP methods: the path is represented by ``n_points`` crank-uniform points compared, index by
  index, with the target's time-uniform points; the DP error is their mean *squared* distance
  (mm^2, smooth, so SQP can use it). Assembly is a constraint, never a penalty objective:
  - ``dp_sqp``: scipy SLSQP from a random feasible start (uniform in the global bounds until a
    design assembles), variables scaled to [0, 1], forward-difference gradients computed as one
    batch, the assembly violation as an inequality constraint (if its last iterate does not
    assemble, the best assembling point it visited is kept);
  - ``dp_ga``: a genetic algorithm (pymoo NSGA-II on the one DP objective, i.e. an elitist GA)
    over the global box, the ``dp`` problem run as a :class:`~core.optimize.stage.Stage`;
  - ``dp_ga_sqp``: the GA's best feasible member polished by SLSQP.

Every method reports the paper's metrics (MSE, S, I, h_s) of its result at ``n_samples``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from core.kinematics.design import Design
from core.kinematics.model import Mechanism, OutputStage
from core.optimize.algorithms import AlgorithmSpec
from core.optimize.objectives import (
    ASSEMBLY_TIER,
    DEFAULT_TARGET,
    load_target,
    quantize,
    shape_metrics,
    target_scale,
    tiered,
)
from core.optimize.problem import ASSEMBLY, Metrics, ProblemSpec, register
from core.optimize.result import decode_array, decode_float
from core.optimize.scale import sized_bounds
from core.optimize.stage import Progress, Stage, StageSpec

F64 = NDArray[np.float64]

DP_METHODS = ("dp_sqp", "dp_ga", "dp_ga_sqp")
TITLES = {"dp_sqp": "DP+SQP", "dp_ga": "DP+GA", "dp_ga_sqp": "DP+GA+SQP"}
REPORTED = ("mse", "S", "I", "h_s", "f2", "f3", "violation")
FD_STEP = 1e-7  # forward-difference step in the [0, 1]-scaled variables
MAX_DRAWS = 200  # batches of random designs tried for a feasible start


def dp_error(design: Design, target: str = DEFAULT_TARGET, n_points: int = 36, n_samples: int = 360,
             backend: str = "auto") -> tuple[F64, F64]:
    """DP error (mean squared distance, mm^2) and assembly violation of a population, ``(pop,)`` each.

    The mechanism is solved at ``n_samples`` (so assembly is checked over the whole cycle, not
    only at the points) and every ``n_samples / n_points``-th sample is a discrete point.
    """
    if n_points < 1 or n_samples % n_points:
        raise ValueError(f"n_points ({n_points}) must divide n_samples ({n_samples})")
    tgt = load_target(target).sample(n_points)
    sol = design.solve(n_samples, joints=False, derivatives=False, backend=backend)
    pts = sol.point[:, :: n_samples // n_points]
    d2 = ((pts - tgt[None]) ** 2).sum(-1).mean(1)
    viol = np.where(np.isfinite(sol.violation), sol.violation, ASSEMBLY_TIER)
    return np.where(viol == 0.0, d2, np.nan), viol


@register("dp")
def dp(target: str = DEFAULT_TARGET, n_points: int = 36, n_samples: int = 360, backend: str = "auto") -> ProblemSpec:
    """The DP problem: minimise the DP error (mm^2) subject to assembly."""
    if n_points < 1 or n_samples % n_points:
        raise ValueError(f"n_points ({n_points}) must divide n_samples ({n_samples})")
    load_target(target)

    def evaluate(design: Design) -> Metrics:
        err, viol = dp_error(design, target, n_points, n_samples, backend)
        return {"dp": quantize(err), "violation": tiered(viol)}

    return ProblemSpec("dp", evaluate, ("dp",), (ASSEMBLY,), labels={"dp": "DP error (mm^2)"},
                       scale=target_scale(target, n_samples))


@dataclass(frozen=True)
class BaselineSettings:
    """Settings of the DP baselines.

    Attributes:
        n_points: discrete points on the path and the target.
        pop_size, n_gen: the GA's population and generations.
        maxiter: SLSQP iterations.
        n_samples: samples for the reported metrics.
        target: target option string (``objectives.load_target``).
        backend: solver backend.
    """

    n_points: int = 36
    pop_size: int = 100
    n_gen: int = 100
    maxiter: int = 200
    n_samples: int = 360
    target: str = DEFAULT_TARGET
    backend: str = "auto"

    def to_dict(self) -> dict[str, Any]:
        return {"n_points": self.n_points, "pop_size": self.pop_size, "n_gen": self.n_gen, "maxiter": self.maxiter,
                "n_samples": self.n_samples, "target": self.target, "backend": self.backend}


@dataclass(frozen=True)
class BaselineResult:
    """One baseline run: the resulting design and its metrics.

    Attributes:
        method: one of ``DP_METHODS``.
        mechanism, output: the design's topology and output stage.
        params: ``(n_params,)`` the result (mm, rad).
        start: ``(n_params,)`` where SQP started (the random feasible start or the GA's best).
        metrics: ``{name: float}`` the result's MSE, S, I, h_s, f2, f3, violation at ``n_samples``.
        dp: the result's DP error (mm^2).
        time: wall time (s).
        seed: the run's seed.
        settings: :class:`BaselineSettings` as a dict.
        status: ``complete`` or ``cancelled``.
        details: solver messages and counts (SLSQP message, iterations, GA generations, ...).
    """

    method: str
    mechanism: Mechanism
    output: OutputStage
    params: F64
    start: F64
    metrics: Mapping[str, float]
    dp: float
    time: float
    seed: int
    settings: Mapping[str, Any]
    status: str = "complete"
    details: Mapping[str, Any] = field(default_factory=dict)

    def design(self) -> Design:
        return Design(self.mechanism, self.params, self.output)

    def to_dict(self) -> dict[str, Any]:
        names = self.mechanism.param_names
        return {
            "method": self.method,
            "title": TITLES[self.method],
            "mechanism": self.mechanism.name,
            "output": self.output.to_dict(),
            "params": dict(zip(names, np.asarray(self.params, dtype=float).tolist(), strict=True)),
            "start": dict(zip(names, np.asarray(self.start, dtype=float).tolist(), strict=True)),
            "metrics": dict(self.metrics),
            "dp": self.dp,
            "time": self.time,
            "seed": self.seed,
            "settings": dict(self.settings),
            "status": self.status,
            "details": dict(self.details),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> BaselineResult:
        from core.kinematics.mechanisms import get

        mech = get(d["mechanism"])
        o = d["output"]
        return cls(
            method=d["method"],
            mechanism=mech,
            output=OutputStage.from_dict(o),
            params=decode_array([d["params"][n] for n in mech.param_names]),
            start=decode_array([d["start"][n] for n in mech.param_names]),
            metrics={k: decode_float(v) for k, v in d["metrics"].items()},
            dp=decode_float(d["dp"]),
            time=decode_float(d["time"]),
            seed=int(d["seed"]),
            settings=dict(d["settings"]),
            status=d.get("status", "complete"),
            details=dict(d.get("details", {})),
        )


def _bounds(mechanism: Mechanism, settings: BaselineSettings) -> tuple[F64, F64]:
    """The global bounds sized to the target (``core.optimize.scale``), as the hierarchical stages get them."""
    return sized_bounds(mechanism, target_scale(settings.target, settings.n_samples))


def random_feasible_start(mechanism: Mechanism, output: OutputStage, rng: np.random.Generator,
                          settings: BaselineSettings, batch: int = 1000) -> F64:
    """A design drawn uniformly in the global bounds that assembles over the whole cycle.

    Raises:
        ValueError: none found in ``MAX_DRAWS`` batches.
    """
    lo, hi = _bounds(mechanism, settings)
    for _ in range(MAX_DRAWS):
        P = rng.uniform(lo, hi, size=(batch, mechanism.n_params))
        err, _ = dp_error(Design(mechanism, P, output), settings.target, settings.n_points, settings.n_samples,
                          settings.backend)
        ok = np.flatnonzero(np.isfinite(err))
        if ok.size:
            return P[ok[0]]
    raise ValueError(f"no assembling {mechanism.name} design found in {MAX_DRAWS * batch} random draws")


class _Batch:
    """Objective, constraint and their forward-difference gradients of one point, in one solver call."""

    def __init__(self, mechanism: Mechanism, output: OutputStage, settings: BaselineSettings) -> None:
        self.mechanism, self.output, self.settings = mechanism, output, settings
        lo, hi = _bounds(mechanism, settings)
        self.lo, self.span = lo, hi - lo
        self._key: bytes | None = None
        self._val: tuple[float, F64, float, F64] = (0.0, np.zeros(0), 0.0, np.zeros(0))
        self.n_calls = 0
        # The best assembling point SLSQP has visited (its last iterate may not assemble).
        self.best: tuple[float, F64] | None = None

    def params(self, u: F64) -> F64:
        return self.lo + np.asarray(u) * self.span

    def __call__(self, u: F64) -> tuple[float, F64, float, F64]:
        u = np.asarray(u, dtype=np.float64)
        if self._key != u.tobytes():
            n = u.size
            U = np.repeat(u[None], n + 1, 0)
            U[1:] += FD_STEP * np.eye(n)
            err, viol = dp_error(Design(self.mechanism, self.params(U), self.output), self.settings.target,
                                 self.settings.n_points, self.settings.n_samples, self.settings.backend)
            # Where a design does not assemble, the objective continues flat from the point itself so the
            # line search is steered by the constraint (violation), not by an undefined objective.
            if np.isfinite(err[0]) and (self.best is None or err[0] < self.best[0]):
                self.best = (float(err[0]), u.copy())
            f0 = float(err[0]) if np.isfinite(err[0]) else float(np.nanmin(np.r_[err, 1e12]))
            err = np.where(np.isfinite(err), err, f0)
            self._val = (f0, (err[1:] - err[0]) / FD_STEP, -float(viol[0]), -(viol[1:] - viol[0]) / FD_STEP)
            self._key = u.tobytes()
            self.n_calls += 1
        return self._val


def sqp(mechanism: Mechanism, output: OutputStage, x0: F64, settings: BaselineSettings) -> tuple[F64, dict[str, Any]]:
    """SLSQP on the DP error from x0 within the global bounds, assembly as an inequality constraint.

    Returns:
        The final parameters ``(n_params,)`` and SLSQP's report (message, iterations, evaluations).
    """
    batch = _Batch(mechanism, output, settings)
    u0 = np.clip((np.asarray(x0, dtype=np.float64) - batch.lo) / batch.span, 0.0, 1.0)
    # The objective in units of its start value: SLSQP's first quasi-Newton step is the raw gradient, and a
    # DP error of ~1e6 mm^2 (a random start) with gradients of ~1e6 made it stop at once on its start.
    batch(u0)
    # batch.best is set only where the start assembles; else its error is a neighbour's or a 1e12 placeholder,
    # and dividing by that would leave SLSQP nothing to do (ftol).
    scale = batch.best[0] if batch.best is not None and batch.best[0] > 0.0 else 1.0
    res = minimize(
        lambda u: (batch(u)[0] / scale, batch(u)[1] / scale),
        u0,
        jac=True,
        method="SLSQP",
        bounds=[(0.0, 1.0)] * u0.size,
        constraints=[{"type": "ineq", "fun": lambda u: batch(u)[2], "jac": lambda u: batch(u)[3]}],
        options={"maxiter": int(settings.maxiter), "ftol": 1e-10},
    )
    u = np.clip(res.x, 0.0, 1.0)
    f_end, _, c_end, _ = batch(u)
    kept = "final"
    if keeps_best(batch.best, f_end, c_end):
        assert batch.best is not None
        u, kept = batch.best[1], "best assembling iterate"
    return batch.params(u), {"message": str(res.message), "nit": int(res.nit), "batches": batch.n_calls,
                             "success": bool(res.success), "kept": kept}


def keeps_best(best: tuple[float, F64] | None, f_end: float, c_end: float) -> bool:
    """Whether SLSQP's result is the best assembling iterate rather than its final point: when the final point
    does not assemble (``c_end = -violation < 0``) or an earlier assembling iterate had a smaller error."""
    return best is not None and (c_end < 0.0 or best[0] < f_end)


def report(mechanism: Mechanism, output: OutputStage, params: F64,
           settings: BaselineSettings) -> tuple[dict[str, float], float]:
    """The paper's metrics of one design at ``settings.n_samples`` and its DP error."""
    d = Design(mechanism, np.asarray(params, dtype=np.float64)[None], output)
    m = shape_metrics(d, settings.target, settings.n_samples, settings.backend)  # type: ignore[arg-type]
    err, _ = dp_error(d, settings.target, settings.n_points, settings.n_samples, settings.backend)
    out = {k: float(m[k][0]) for k in REPORTED}
    out["violation"] = float(m["violation_mm"][0])  # the raw measure (mm), not the pymoo tier
    return out, float(err[0])


def run_baseline(method: str, mechanism: Mechanism, output: OutputStage, settings: BaselineSettings | None = None,
                 seed: int = 0, callback: Callable[[Progress], None] | None = None,
                 cancel: threading.Event | None = None) -> BaselineResult:
    """Run one DP baseline.

    Args:
        method: ``dp_sqp``, ``dp_ga`` or ``dp_ga_sqp``.
        mechanism, output: the topology and its output stage.
        settings: see :class:`BaselineSettings`.
        seed: seeds the random start (SQP) and the GA.
        callback: after every GA generation.
        cancel: checked between GA generations; a cancelled run reports the GA's best so far
            (and skips SQP).

    Raises:
        ValueError: unknown method, or no feasible start.
    """
    if method not in DP_METHODS:
        raise ValueError(f"unknown baseline {method!r}; known: {', '.join(DP_METHODS)}")
    settings = settings or BaselineSettings()
    t = time.perf_counter()
    details: dict[str, Any] = {}
    status = "complete"
    if method == "dp_sqp":
        x0 = random_feasible_start(mechanism, output, np.random.default_rng(seed), settings)
    else:
        spec = StageSpec("dp_ga", _dp_problem(settings), s=None,
                         algorithm=AlgorithmSpec("nsga2", settings.pop_size), n_gen=settings.n_gen, seed=seed,
                         seed_start=False)
        lo, hi = _bounds(mechanism, settings)
        start = Design(mechanism, 0.5 * (lo + hi), output)
        res = Stage(spec, start, callback=callback).run(cancel=cancel)
        status = "complete" if res.status in ("complete", "stopped") else "cancelled"
        i = res.choose("best:dp")
        x0 = res.X[i]
        details.update({"ga_generations": res.generation, "ga_evals": res.n_evals, "ga_dp": float(res.F[i, 0])})
    x = x0
    if method != "dp_ga" and status == "complete":
        x, info = sqp(mechanism, output, x0, settings)
        details.update({f"sqp_{k}": v for k, v in info.items()})
    metrics, err = report(mechanism, output, x, settings)
    return BaselineResult(method, mechanism, output, np.asarray(x, dtype=np.float64), np.asarray(x0), metrics, err,
                          time.perf_counter() - t, int(seed), settings.to_dict(), status, details)


def _dp_problem(settings: BaselineSettings) -> ProblemSpec:
    from core.optimize.problem import make_problem

    return make_problem("dp", target=settings.target, n_points=settings.n_points, n_samples=settings.n_samples,
                        backend=settings.backend)
