"""Design problems: named metrics of a population -> pymoo objectives and constraints.

A problem is a :class:`ProblemSpec`: an ``evaluate(design) -> {metric: (pop,) array}``
function, the metrics to minimise and the constraints on metrics. :class:`DesignProblem`
turns it into a vectorized pymoo ``Problem`` over a stage's :class:`~core.optimize.box.Box`:
``_evaluate`` decodes the whole population, calls ``evaluate`` once and stacks columns.

Conventions:
- ``evaluate`` returns float arrays of shape ``(pop,)`` and must include ``violation``
  (>= 0, 0 iff the design assembles; ``Solution.violation``). Unassemblable members have
  NaN metrics and a positive violation; ``evaluate`` never raises for them.
- A constraint is ``metric <= upper`` or ``metric >= lower``; pymoo sees
  ``g = metric - upper`` (or ``lower - metric``), feasible iff every g <= 0.
- NaN objectives reach pymoo as +inf (infeasible members only: pymoo ranks those by
  violation). A NaN constraint value counts 0 when the member already violates another
  constraint, and +inf otherwise, so an undefined member is never feasible.

Problems are built by name from JSON-able options (``make_problem``), so a saved stage can
be rebuilt; factories register with :func:`register`.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymoo.core.problem import Problem
from pymoo.core.repair import Repair

from core.analysis.evaluate import MIN_SAMPLES
from core.kinematics import checks
from core.kinematics.design import Design
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.optimize.box import Box

F64 = NDArray[np.float64]
Metrics = dict[str, F64]
Evaluate = Callable[[Design], Mapping[str, Any]]


@dataclass(frozen=True)
class Constraint:
    """``metric <= upper`` or ``metric >= lower`` (exactly one bound)."""

    metric: str
    upper: float | None = None
    lower: float | None = None

    def __post_init__(self) -> None:
        if (self.upper is None) == (self.lower is None):
            raise ValueError(f"constraint on {self.metric!r} needs exactly one of upper, lower")

    @property
    def name(self) -> str:
        return f"{self.metric}<={self.upper!r}" if self.upper is not None else f"{self.metric}>={self.lower!r}"

    def value(self, metric: F64) -> F64:
        """``(pop,)`` pymoo inequality value g (<= 0 is satisfied), same unit as the metric."""
        if self.upper is not None:
            return metric - self.upper
        return self.lower - metric  # type: ignore[operator]

    def to_dict(self) -> dict[str, Any]:
        return {"metric": self.metric, "upper": self.upper, "lower": self.lower}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Constraint:
        return cls(str(d["metric"]), d.get("upper"), d.get("lower"))


ASSEMBLY = Constraint("violation", upper=0.0)


def transmission_limits(limit: float, metrics: tuple[str, ...] = ("transmission",)) -> tuple[Constraint, ...]:
    """A problem's ``transmission_min`` option (deg): each worst transmission angle in ``metrics`` at least this
    (0: no limit, the paper's); ValueError for an angle outside [0, 90)."""
    if not (np.isfinite(limit) and 0.0 <= limit < 90.0):
        raise ValueError(f"transmission_min must be an angle in degrees in [0, 90), got {limit!r}")
    return tuple(Constraint(m, lower=float(limit)) for m in metrics) if limit > 0.0 else ()


@dataclass(frozen=True)
class ProblemSpec:
    """What a stage optimizes.

    Attributes:
        name: registry name (``make_problem(name, **options)`` rebuilds it).
        evaluate: ``Design (pop) -> {metric: (pop,) float array}``, including ``violation``.
        objectives: metrics to minimise, in order (the columns of F).
        constraints: the columns of G; the assembly constraint first by convention.
        options: the factory's JSON-able arguments.
        labels: display label with unit per metric (``{"f1": "MSE (mm)"}``).
        repair: optional Lamarckian repair ``Design (pop) -> (pop, n_params)`` applied to
            every new member before evaluation; the repaired vectors replace the members
            (kept inside the stage's box). Predesign's analytic placement (scale, rotate,
            shift, phase so the matched shape lands on the target) belongs here.
        misfit: ``Mechanism -> reason | None``: why the problem cannot optimize that mechanism (the RTCLM
            problems any other; an analytic placement a mechanism with derived values); None: any mechanism.
        scale: the leg's size relative to the paper's 300 mm stride (``core.optimize.scale``): a stage's box
            multiplies the mechanism's sized bounds by it. 1 for problems without a shape target.
    """

    name: str
    evaluate: Evaluate = field(compare=False, repr=False)
    objectives: tuple[str, ...]
    constraints: tuple[Constraint, ...] = (ASSEMBLY,)
    options: Mapping[str, Any] = field(default_factory=dict)
    labels: Mapping[str, str] = field(default_factory=dict)
    repair: Callable[[Design], F64] | None = field(default=None, compare=False, repr=False)
    misfit: Callable[[Mechanism], str | None] | None = field(default=None, compare=False, repr=False)
    scale: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "objectives", tuple(self.objectives))
        object.__setattr__(self, "constraints", tuple(self.constraints))
        if not self.objectives:
            raise ValueError(f"problem {self.name!r} has no objectives")
        if not self.constraints:
            raise ValueError(f"problem {self.name!r} has no constraints; use at least the assembly constraint")

    def __reduce__(self) -> tuple[Any, ...]:
        # Sent to worker processes by name and options: the registry rebuilds it there, so only
        # a spec that make_problem built (it records every option) can go.
        _load_providers()
        factory = _FACTORIES.get(self.name)
        if factory is None or set(self.options) != set(inspect.signature(factory).parameters):
            raise TypeError(f"problem {self.name!r} was not built by make_problem; it cannot be pickled")
        return (make_problem_from, (self.name, dict(self.options)))

    @property
    def n_obj(self) -> int:
        return len(self.objectives)

    def check_fits(self, mechanism: Mechanism) -> None:
        """ValueError saying why this problem cannot optimize ``mechanism``, if it cannot."""
        reason = None if self.misfit is None else self.misfit(mechanism)
        if reason is not None:
            raise ValueError(f"problem {self.name!r} does not fit the {mechanism.title}: {reason}")

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.constraints)

    @property
    def metric_names(self) -> tuple[str, ...]:
        """Metrics known without evaluating: objectives, constrained metrics, then labelled ones."""
        return tuple(dict.fromkeys((*self.objectives, *(c.metric for c in self.constraints), *self.labels)))

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "options": dict(self.options),
            "objectives": list(self.objectives),
            "constraints": [c.to_dict() for c in self.constraints],
            "labels": dict(self.labels),
        }

    def evaluate_metrics(self, design: Design) -> Metrics:
        """Call ``evaluate`` and check its contract: float ``(pop,)`` arrays including every used metric."""
        raw = self.evaluate(design)
        out: Metrics = {}
        for key, value in raw.items():
            a = np.asarray(value, dtype=np.float64)
            if a.shape != (design.pop,):
                raise ValueError(f"problem {self.name!r}: metric {key!r} has shape {a.shape}, expected ({design.pop},)")
            out[key] = a
        needed = list(self.objectives) + [c.metric for c in self.constraints]
        missing = [k for k in needed if k not in out]
        if missing:
            raise ValueError(f"problem {self.name!r}: evaluate gave no metric {missing[0]!r}; got {', '.join(out)}")
        return out

    def columns(self, metrics: Mapping[str, F64]) -> tuple[F64, F64]:
        """Metrics -> ``F (pop, n_obj)`` and ``G (pop, n_con)`` as pymoo sees them (see module doc)."""
        F = np.stack([metrics[k] for k in self.objectives], axis=1)
        G = np.stack([c.value(metrics[c.metric]) for c in self.constraints], axis=1)
        nan_g = np.isnan(G)
        violates = (np.where(nan_g, 0.0, G) > 0.0).any(axis=1, keepdims=True)
        G = np.where(nan_g, np.where(violates, 0.0, np.inf), G)
        undefined = np.isnan(F).any(axis=1) & (G <= 0.0).all(axis=1)
        G[undefined, 0] = np.inf  # objectives undefined: never feasible
        return np.where(np.isnan(F), np.inf, F), G


class DesignProblem(Problem):
    """A vectorized pymoo problem: one stage's :class:`ProblemSpec` over a :class:`Box`.

    The optimizer's variables are the box's free parameters; ``_evaluate`` maps the whole
    population to parameter vectors (``Box.decode``) and evaluates it in one call.
    """

    def __init__(self, spec: ProblemSpec, mechanism: Mechanism, box: Box, output: OutputStage = IDENTITY) -> None:
        if box.names != mechanism.param_names:
            raise ValueError(f"box parameters {box.names} do not match {mechanism.name}")
        self.spec, self.mechanism, self.box, self.output = spec, mechanism, box, output
        super().__init__(n_var=box.n_var, n_obj=spec.n_obj, n_ieq_constr=len(spec.constraints),
                         xl=box.xl.copy(), xu=box.xu.copy(), elementwise=False)

    def design(self, params: F64) -> Design:
        """Parameter vectors ``(pop, n_params)`` -> a population Design."""
        return Design(self.mechanism, np.atleast_2d(params), self.output)

    def metrics(self, params: F64) -> Metrics:
        """Every metric of parameter vectors ``(pop, n_params)``; empty arrays for pop = 0."""
        params = np.asarray(params, dtype=np.float64).reshape(-1, self.mechanism.n_params)
        if params.shape[0] == 0:
            return {}
        return self.spec.evaluate_metrics(self.design(params))

    def _evaluate(self, X: F64, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
        F, G = self.spec.columns(self.metrics(self.box.decode(X)))
        out["F"], out["G"] = F, G
        # pymoo's constraint violation (its default: the sum of positive G) for the whole population at
        # once; otherwise every Individual computes it in Python on first use. Set as "_CV", the slot
        # behind pymoo's CV property: setting "CV" makes Individual.set evaluate the property first.
        out["_CV"] = np.maximum(0.0, G).sum(axis=1)[:, None]


class BoxRepair(Repair):
    """pymoo Repair running a :class:`ProblemSpec`'s ``repair`` on decoded members, kept in the box."""

    def __init__(self, problem: DesignProblem) -> None:
        super().__init__()
        self.design_problem = problem

    def _do(self, problem: Any, X: F64, **kwargs: Any) -> F64:
        dp = self.design_problem
        if dp.spec.repair is None or len(X) == 0:
            return X
        params = np.asarray(dp.spec.repair(dp.design(dp.box.decode(X))), dtype=np.float64)
        if params.shape != (len(X), dp.mechanism.n_params):
            raise ValueError(f"problem {dp.spec.name!r}: repair gave shape {params.shape}, "
                             f"expected ({len(X)}, {dp.mechanism.n_params})")
        # Non-finite repairs keep the member as it was (it is then judged by its own violation).
        params = np.where(np.isfinite(params), params, dp.box.decode(X))
        return np.clip(dp.box.encode(params), dp.box.xl, dp.box.xu)


# ---------------------------------------------------------------------------------------
# Registry: problems by name from JSON-able options.

ProblemFactory = Callable[..., ProblemSpec]
_FACTORIES: dict[str, ProblemFactory] = {}
# Modules that register problems when imported (looked up lazily; missing ones are skipped).
PROVIDERS: tuple[str, ...] = ("core.optimize.examples", "core.optimize.subtasks", "core.optimize.rtclm",
                              "core.optimize.baselines")


def register(name: str) -> Callable[[ProblemFactory], ProblemFactory]:
    """Decorator: register a factory ``(**options) -> ProblemSpec`` under ``name``."""

    def deco(factory: ProblemFactory) -> ProblemFactory:
        _FACTORIES[name] = factory
        return factory

    return deco


def _load_providers() -> None:
    from importlib import import_module

    for module in PROVIDERS:
        try:
            import_module(module)
        except ModuleNotFoundError as e:
            if e.name != module:  # a provider that exists but fails to import is a real error
                raise


def problem_names() -> tuple[str, ...]:
    _load_providers()
    return tuple(sorted(_FACTORIES))


def make_problem_from(name: str, options: Mapping[str, Any]) -> ProblemSpec:
    """``make_problem(name, **options)`` (positional, for unpickling)."""
    return make_problem(name, **options)


def make_problem(name: str, **options: Any) -> ProblemSpec:
    """Build a registered problem; the spec records every option (defaults included).

    Raises:
        ValueError: unknown problem or option, or an option out of range (named in the message).
        TypeError: an option of the wrong type (by the factory's annotation: ``float`` options must be
            finite real numbers, ``bool`` options booleans, ``int`` options counts >= 1, ``str`` strings).
    """
    if name not in _FACTORIES:
        _load_providers()
    if name not in _FACTORIES:
        raise ValueError(f"unknown problem {name!r}; known: {', '.join(sorted(_FACTORIES))}")
    factory = _FACTORIES[name]
    sig = inspect.signature(factory)
    for key in options:
        if key not in sig.parameters:
            known = ", ".join(sig.parameters) or "none"
            raise ValueError(f"unknown option {key!r} for problem {name!r}; known: {known}")
    bound = sig.bind(**options)
    bound.apply_defaults()
    for key, value in bound.arguments.items():
        bound.arguments[key] = _option(name, key, sig.parameters[key].annotation, value)
    spec = factory(**bound.arguments)
    # An option left None means "the factory's choice" (a limit sized to the target): it records the value it took.
    resolved = {k: v for k, v in spec.options.items() if k in bound.arguments and bound.arguments[k] is None}
    return replace(spec, name=name, options=dict(bound.arguments) | resolved)


def _option(problem: str, key: str, annotation: Any, value: Any) -> Any:
    """A factory option checked against its annotation: ``float`` finite (ints convert), ``int`` a count in
    [1, MAX_SAMPLES] (not a bool), ``bool`` a boolean, ``str`` a string; ``n_samples`` even, >= 8."""
    where = f"problem {problem!r} option {key}"
    kind = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", "")
    if key == "n_samples":
        return checks.samples(value, minimum=MIN_SAMPLES, even=True, name=where)
    if key == "backend":
        return checks.backend(value)
    if kind == "float":
        return checks.real(value, where)
    if kind == "float | None":
        return None if value is None else checks.real(value, where)
    if kind == "int":  # the registry's int options are counts (points, harmonics)
        return checks.samples(value, minimum=1, name=where)
    if kind == "bool":
        return checks.flag(value, where)
    if kind == "str" and not isinstance(value, str):
        raise TypeError(f"{where} must be a string, got {type(value).__name__} {value!r}")
    return value
