"""The design-run configuration file as msgspec Structs (see ``core.formats.config`` for the format).

The Structs type every key and its range; ``core.formats.config`` decodes a file through them and then
checks what depends on more than one key (mechanisms, problems, picks, multi-start blocks).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from msgspec import Meta, Struct

from core.formats.typed import MAX_GEN, MAX_POP, MAX_SAMPLES, MAX_SEED
from core.kinematics.checks import MAX_ABS
from core.optimize.design_config import BACKENDS, METHODS

Pos = Annotated[float, Meta(gt=0)]
NonNeg = Annotated[float, Meta(ge=0)]
PosInt = Annotated[int, Meta(ge=1)]
Gens = Annotated[int, Meta(ge=1, le=MAX_GEN)]


class Output(Struct, forbid_unknown_fields=True, frozen=True):
    k: float = 1.0
    ox: float = 0.0
    oy: float = 0.0
    mirror: Any = False  # checked by hand: "must be true or false, got 'yes'" reads better for a flag


# The analysis' domain (core.kinematics.checks.MAX_ABS): past it the run failed at its first stage, exit 1 after
# writing a failed result (rehearsal 8), or "completed" on overflowed numbers.
Size = Annotated[float, Meta(gt=0, le=MAX_ABS)]
Period = Annotated[float, Meta(ge=1.0 / MAX_ABS, le=MAX_ABS)]


class Target(Struct, forbid_unknown_fields=True, frozen=True):
    curve: str = "cycloid"
    L: Size | None = None
    H: Size | None = None
    T: Period | None = None


class Rtclm(Struct, forbid_unknown_fields=True, frozen=True):
    h6: Size | None = None  # h6 = 1e300 ran and "completed" with dh6 1e+300; the studio refuses over 1e6 mm
    h4: Size | None = None


class Algorithm(Struct, forbid_unknown_fields=True, frozen=True):
    name: str | None = None
    pop_size: Annotated[int, Meta(ge=2, le=MAX_POP)] | None = None
    options: dict[str, Any] = {}


class Box(Struct, forbid_unknown_fields=True, frozen=True):
    s: Pos | None = None  # both required: checked by hand to say what each one is
    d: Pos | None = None


class Screen_(Struct, forbid_unknown_fields=True, frozen=True):
    after: str
    keep: PosInt
    by: str
    where: dict[str, Any] | None = None


class Starts_(Struct, forbid_unknown_fields=True, frozen=True):
    n: PosInt
    select: str
    until: str | None = None
    where: dict[str, Any] | None = None
    screen: Screen_ | None = None


class Stage(Struct, forbid_unknown_fields=True, frozen=True):
    name: str
    problem: str | None = None
    box: Literal["global", "subtask1", "subtask2", "subtask3"] | Box = "global"
    n_gen: Gens = 100
    max_evals: PosInt | None = None
    pick: str | Annotated[int, Meta(ge=0)] = "knee"
    pick_where: dict[str, Any] | None = None
    starts: Starts_ | None = None
    stop_below: list[NonNeg] | None = None
    fixed: list[str] = []
    seed_start: bool = True
    options: dict[str, Any] = {}
    algorithm: Algorithm | None = None


class Baseline(Struct, forbid_unknown_fields=True, frozen=True):
    n_points: PosInt | None = None
    pop_size: Annotated[int, Meta(ge=1, le=MAX_POP)] | None = None
    n_gen: Gens | None = None
    maxiter: PosInt | None = None


class ConfigFile(Struct, forbid_unknown_fields=True, frozen=True):
    """A design run: a mechanism or preset, a target, an algorithm and its stages (docs/optimization.md)."""

    name: str = "design"
    method: Literal[METHODS] = "hierarchical"  # type: ignore[valid-type]
    mechanism: str | None = None
    preset: str | None = None
    output: Output | None = None
    seed: Annotated[int, Meta(ge=0, le=MAX_SEED)] = 0
    n_samples: Annotated[int, Meta(ge=8, le=MAX_SAMPLES)] = 360
    backend: Literal[BACKENDS] = "auto"  # type: ignore[valid-type]
    target: Target | None = None
    rtclm: Rtclm | None = None
    bounds: dict[str, Any] = {}
    algorithm: Algorithm = Algorithm()
    stages: list[Stage] | None = None
    baseline: Baseline | None = None
    workers: Literal["auto"] | PosInt = "auto"
