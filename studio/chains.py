"""Which stages the Stages panel offers for a mechanism, and how each becomes a ``StageSpec``.

A chain is the paper's hierarchy: predesign -> subtask 1 -> 2 -> 3 for the six-bars (spec §6
boxes: global bounds, then 20 %/20 mm, 10 %/10 mm, 5 %/5 mm around the previous pick), RTCLM
subtask 1 -> 2 for the RTCLM (paper §4.2, both over the global bounds as in ``clm design``'s
configurations, early stop at [0.5, 0.5] mm). Stages whose problem is
not registered are left out, and any registered problem can be run in a stage's place
(``core.optimize.problem.problem_names``), so new problems appear without touching the studio.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from core.kinematics.model import Mechanism
from core.optimize.algorithms import ALGORITHMS, AlgorithmSpec, unknown_algorithm
from core.optimize.box import SUBTASK_STEPS
from core.optimize.problem import Constraint, ProblemSpec, make_problem, problem_names
from core.optimize.rtclm import is_rtclm
from core.optimize.scale import scaled_limit
from core.optimize.stage import StageSpec
from studio.target import TargetSpec

MAX_POP = 2000
MAX_GEN = 5000


@dataclass(frozen=True)
class ChainStage:
    """One stage of a chain.

    Attributes:
        name: stage name (unique in its chain; also the default problem).
        title: what the designer reads (``Subtask 1 -> X1``).
        s, d: box rule around the previous pick (spec §6); ``s = None``: global bounds.
        stop_below: early stop once a feasible member has every objective <= these (None: off).
        pick: automatic pick when the stage completes (``core.optimize.lineage.auto_pick``, as ``clm design``
            picks: among the members that meet the next stage's constraints); the designer can change it.
        pick_where: limits that narrow the automatic pick first, if any member meets them (a config's
            ``pick_where``).
        pop_size, n_gen: default population and generations offered in the panel.
    """

    name: str
    title: str
    s: float | None = None
    d: float = 0.0
    stop_below: tuple[float, ...] | None = None
    pick: str = "knee"
    pop_size: int = 40
    n_gen: int = 30
    pick_where: tuple[Constraint, ...] = ()


def _step(k: int) -> tuple[float, float]:
    return SUBTASK_STEPS[k]


# Populations, generations and picks of assets/configs/stephenson1_cycloid.toml (one chain of it: the config runs
# twelve, see docs/studio.md): at 40 members and 30 generations a stage took ~0.2 s and X0 -> X3 ended on a design
# worse than the paper's X3 on every metric; at these, 2-3 s in all.
SIX_BAR = (
    ChainStage("predesign", "Predesign → X0", None, 0.0, pick="best:f1", pop_size=200, n_gen=60),
    ChainStage("subtask1", "Subtask 1 → X1 (shape, position)", *_step(1), pick="best:f1", pop_size=200, n_gen=30),
    ChainStage("subtask2", "Subtask 2 → X2 (h_s, I)", *_step(2), pick="best:h_s", pop_size=200, n_gen=100,
               pick_where=(Constraint("I", upper=1.0),)),
    ChainStage("subtask3", "Subtask 3 → X3 (fine-tuning)", *_step(3), pick="best:S", pop_size=200, n_gen=120,
               pick_where=(Constraint("I", upper=0.44),)),
)
# As assets/configs/rtclm_case*.toml (``clm design``): both subtasks over the global bounds (subtask 2
# holds subtask 1's h6 as a constraint and starts from its pick, seeded into the population), with the
# configs' populations and generations: each stage stops once both deviations are within 0.5 mm (about 2 s
# for a case). At 50 x 50 subtask 1 ended 2.2 mm from h6 and subtask 2 at h4 185.6 mm for a 220 mm target.
RTCLM = (
    ChainStage("rtclm1", "RTCLM subtask 1 (primary mode, h6)", None, 0.0, stop_below=(0.5,), pick="best:dh6",
               pop_size=100, n_gen=200),
    ChainStage("rtclm2", "RTCLM subtask 2 (auxiliary mode, h4)", None, 0.0, stop_below=(0.5, 0.5), pick="best:dh4",
               pop_size=100, n_gen=1500),
)


def chain_for(mechanism: Mechanism) -> tuple[ChainStage, ...]:
    """The stages offered for a mechanism whose problems are registered (in order)."""
    chain = RTCLM if is_rtclm(mechanism.name) else SIX_BAR
    known = set(problem_names())
    return tuple(c for c in chain if c.name in known)


def find(chain: tuple[ChainStage, ...], name: str) -> ChainStage:
    for c in chain:
        if c.name == name:
            return c
    raise ValueError(f"no stage {name!r}; stages: {', '.join(c.name for c in chain)}")


@dataclass(frozen=True)
class RunSettings:
    """What the designer sets for one stage: problem, algorithm, population, generations, seed, and a lower limit
    on the worst transmission angle (deg, 0: none; the problem's ``transmission_min``)."""

    problem: str
    algorithm: str = "nsga2"
    pop_size: int = 40
    n_gen: int = 30
    seed: int = 1
    transmission_min: int = 0

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ValueError(unknown_algorithm(self.algorithm))
        for name, lo, hi in (("pop_size", 2, MAX_POP), ("n_gen", 1, MAX_GEN), ("seed", 0, 2**31 - 1),
                             ("transmission_min", 0, 89)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                what = {"pop_size": "population", "n_gen": "generations", "seed": "seed",
                        "transmission_min": "min transmission angle (deg)"}[name]
                raise ValueError(f"{what} must be a whole number in [{lo}, {hi}], got {v!r}")

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"problem": self.problem, "algorithm": self.algorithm, "pop_size": self.pop_size,
                                  "n_gen": self.n_gen, "seed": self.seed}
        if self.transmission_min:  # written when set: sessions saved before it read the same
            out["transmission_min"] = self.transmission_min
        return out

    @staticmethod
    def from_dict(data: object) -> RunSettings:
        if not isinstance(data, dict):
            raise ValueError(f"stage settings must be an object, got {data!r}")
        known = ("problem", "algorithm", "pop_size", "n_gen", "seed", "transmission_min")
        unknown = [k for k in data if k not in known]
        if unknown:
            raise ValueError(f"unknown stage setting {unknown[0]!r}")
        if not isinstance(data.get("problem"), str):
            raise ValueError(f"stage settings need a problem name, got {data.get('problem')!r}")
        d = RunSettings(str(data["problem"]))
        return RunSettings(str(data["problem"]), data.get("algorithm", d.algorithm), data.get("pop_size", d.pop_size),
                           data.get("n_gen", d.n_gen), data.get("seed", d.seed),
                           data.get("transmission_min", d.transmission_min))


def default_settings(stage: ChainStage) -> RunSettings:
    return RunSettings(stage.name, pop_size=stage.pop_size, n_gen=stage.n_gen)


def _takes(name: str, **options: Any) -> bool:
    """True if the registered problem ``name`` takes these options (an unknown one is its ValueError)."""
    try:
        make_problem(name, **options)
    except ValueError as exc:
        if "unknown option" in str(exc):
            return False
        raise
    return True


@functools.cache
def takes_target(name: str) -> bool:
    """True if the registered problem ``name`` optimizes against a target (takes a ``target`` option)."""
    return _takes(name, target=TargetSpec().option())


@functools.cache
def takes_heights(name: str) -> bool:
    """True if the registered problem ``name`` takes the RTCLM's ``h6_target`` and ``h4_target`` options."""
    return _takes(name, h6_target=TargetSpec().h6, h4_target=TargetSpec().h4)


@functools.cache
def problems_for(mechanism: Mechanism) -> tuple[str, ...]:
    """The registered problems the Problem list offers for ``mechanism``: those that fit it (with their default
    options), without the library's analytic examples."""
    from core.optimize.examples import EXAMPLES

    out = []
    for name in problem_names():
        misfit = make_problem(name).misfit
        if name not in EXAMPLES and (misfit is None or misfit(mechanism) is None):
            out.append(name)
    return tuple(out)


def build_problem(name: str, target: TargetSpec, transmission_min: int = 0) -> ProblemSpec:
    """A registered problem against the studio's target: its curve (``target``) or the RTCLM's heights
    (``h6_target``, ``h4_target``) for the problems that take them; none for the others. ``transmission_min``
    (deg, 0: none): its lower limit on the worst transmission angle; ValueError for a problem without one."""
    extra: dict[str, Any] = {"transmission_min": float(transmission_min)} if transmission_min else {}
    if extra and not _takes(name, **extra):
        raise ValueError(f"problem {name!r} takes no limit on the transmission angle: set Min transmission μ "
                         "to 0 to run it")
    if takes_heights(name):
        return make_problem(name, h6_target=float(target.h6), h4_target=float(target.h4), **extra)
    try:
        return make_problem(name, target=target.option(), **extra)
    except ValueError as exc:
        if "unknown option 'target'" not in str(exc):
            raise
    return make_problem(name, **extra)


def stage_spec(stage: ChainStage, settings: RunSettings, target: TargetSpec) -> StageSpec:
    """The ``StageSpec`` a run of ``stage`` uses; ValueError naming the problem if it cannot be built."""
    problem = build_problem(settings.problem, target, settings.transmission_min)
    stop = stage.stop_below
    if stop is not None and len(stop) != problem.n_obj:
        stop = None  # another problem in this slot: the chain's early-stop rule does not apply
    pick = stage.pick
    if pick.startswith("best:") and pick[5:] not in problem.objectives and settings.problem != stage.name:
        pick = "knee"  # another problem in this slot: the stage's rule names a metric it may not report
    algorithm = AlgorithmSpec(settings.algorithm, settings.pop_size)
    # The chain's steps (20, 10, 5 mm) are the paper's, for its 300 mm stride: they follow the leg's size.
    return StageSpec(stage.name, problem, s=stage.s, d=stage.d * problem.scale, algorithm=algorithm,
                     n_gen=settings.n_gen, seed=settings.seed, stop_below=stop, pick=pick)


def sized_where(where: tuple[Constraint, ...], k: float) -> tuple[Constraint, ...]:
    """A chain's ``pick_where`` limits (the paper's, for its 300 mm stride) for a leg of scale ``k``."""
    return tuple(Constraint(c.metric, upper=None if c.upper is None else scaled_limit(c.metric, c.upper, k),
                            lower=None if c.lower is None else scaled_limit(c.metric, c.lower, k)) for c in where)
