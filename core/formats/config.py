"""A design configuration (TOML): parse and validate it strictly, then run it (``clm design``).

The format is documented in docs/optimization.md; examples are in assets/configs/. In short::

    name = "..."                       # label for tables
    method = "hierarchical"            # or "single_level", "dp_sqp", "dp_ga", "dp_ga_sqp"
    mechanism = "stephenson1"          # and/or preset = "stephenson1/X0" (the start design)
    output = {k = -1.0, ox = 150.0, oy = 0.0}
    seed = 1                           # stage k runs with seed + k
    n_samples = 360
    backend = "auto"
    [target]   curve = "cycloid", L = 300.0, H = 100.0, T = 2.0   (or curve = "path.csv")
    [rtclm]    h6 = 50.0, h4 = 220.0
    [bounds]   r1 = [30.0, 200.0]      # narrower global bounds
    [algorithm] name = "nsga2", pop_size = 200, options = {...}
    [[stages]] name, problem, box, n_gen, pick, pick_where, starts, stop_below, fixed, seed_start, options,
               algorithm
    [baseline] n_points, pop_size, n_gen, maxiter

Every error is a ``ValueError`` whose message starts with the offending key
(``stages[2].options.f1_max: ...``).

Running (:func:`run_design`): stages run in order; between stages the automatic pick applies
the stage's rule (``knee``, ``knee:k``, ``best:<metric>`` or an index) to the members that
meet its ``pick_where`` limits and also satisfy the next stage's absolute constraints (so the
next stage starts feasible when it can) and, for a stage that stopped early, its
``stop_below`` thresholds; relative limits (``"start+0.5"``) are resolved against each
stage's start. A stage with a ``starts`` table runs, with the stages up to ``starts.until``,
as several chains with other seeds, and the best chain goes on (``core.optimize.multistart``).
"""

from __future__ import annotations

import inspect
import math
import threading
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics import presets
from core.kinematics.design import Design
from core.kinematics.mechanisms import MECHANISMS
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.kinematics.params import Param
from core.optimize import decision
from core.optimize import problem as problem_registry
from core.optimize.algorithms import ALGORITHMS, AlgorithmSpec, validate
from core.optimize.baselines import DP_METHODS, BaselineResult, BaselineSettings, run_baseline
from core.optimize.box import SUBTASK_STEPS
from core.optimize.multistart import SEED_STRIDE, Chain, MultiStart, Screen, Starts, rank_chains, select_chain
from core.optimize.pipeline import Pipeline
from core.optimize.problem import Constraint, ProblemSpec, make_problem
from core.optimize.result import PickRule, StageResult, best_metric
from core.optimize.stage import Progress, StageSpec
from core.optimize.subtasks import LIMIT_METRICS, parse_relative, resolve_limits
from core.optimize.workers import resolve as resolve_workers
from core.optimize.workers import run as run_jobs
from core.optimize.workers import start_method

F64 = NDArray[np.float64]

METHODS = ("hierarchical", "single_level", *DP_METHODS)
BACKENDS = ("auto", "numpy", "numba")
SHAPE_PROBLEMS = ("predesign", "subtask1", "subtask2", "subtask3", "single_level", "dp")
PAPER_OUTPUT = presets.PAPER_PANTOGRAPH

_TOP = {"name", "method", "mechanism", "preset", "output", "seed", "n_samples", "backend", "target", "rtclm",
        "bounds", "algorithm", "stages", "baseline", "workers"}
_STAGE = {"name", "problem", "box", "n_gen", "pick", "pick_where", "starts", "stop_below", "fixed", "seed_start",
          "options", "algorithm"}
_STARTS = {"n", "until", "select", "where", "screen"}
_SCREEN = {"after", "keep", "by"}
_TARGET = {"curve", "L", "H", "T"}
_RTCLM = {"h6", "h4"}
_ALGO = {"name", "pop_size", "options"}
_BASELINE = {"n_points", "pop_size", "n_gen", "maxiter"}


# ---------------------------------------------------------------------------------------
# Parsed configuration.


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

    def problem_spec(self) -> ProblemSpec:
        """The stage's problem with relative limits replaced by non-binding placeholders."""
        return make_problem(self.problem, **placeholder(self.options))

    def spec(self, seed: int, options: Mapping[str, Any] | None = None) -> StageSpec:
        """The :class:`StageSpec` with resolved options (default: ``options`` as given, which must be numbers)."""
        prob = make_problem(self.problem, **dict(self.options if options is None else options))
        return StageSpec(self.name, prob, s=self.s, d=self.d, algorithm=self.algorithm, n_gen=self.n_gen, seed=seed,
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
        seed: run seed (stage k uses seed + k).
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


# ---------------------------------------------------------------------------------------
# Validation helpers: each raises ValueError("<key>: <problem>").


def _fail(key: str, msg: str) -> ValueError:
    return ValueError(f"{key}: {msg}")


def _keys(table: Any, key: str, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise _fail(key, f"expected a table, got {_kind(table)}")
    for k in table:
        if k not in allowed:
            where = f"{key}.{k}" if key else k
            raise _fail(where, f"unknown key; known: {', '.join(sorted(allowed))}")
    return table


def _kind(v: Any) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
            dict: "a table"}.get(type(v), type(v).__name__)


def _num(v: Any, key: str, lo: float | None = None, hi: float | None = None, open_lo: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(key, f"expected a number, got {_kind(v)}")
    f = float(v)
    if not math.isfinite(f):
        raise _fail(key, "must be finite")
    if lo is not None and (f <= lo if open_lo else f < lo):
        raise _fail(key, f"must be {'>' if open_lo else '>='} {lo:g}, got {f:g}")
    if hi is not None and f > hi:
        raise _fail(key, f"must be <= {hi:g}, got {f:g}")
    return f


def _int(v: Any, key: str, lo: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise _fail(key, f"expected an integer, got {_kind(v)}")
    if lo is not None and v < lo:
        raise _fail(key, f"must be >= {lo}, got {v}")
    return int(v)


def _str(v: Any, key: str, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(v, str):
        raise _fail(key, f"expected a string, got {_kind(v)}")
    if choices is not None and v not in choices:
        raise _fail(key, f"{v!r} is not one of {', '.join(choices)}")
    return v


def _bool(v: Any, key: str) -> bool:
    if not isinstance(v, bool):
        raise _fail(key, f"expected true or false, got {_kind(v)}")
    return v


# ---------------------------------------------------------------------------------------
# Parsing.


def load_config(path: str | Path) -> DesignConfig:
    """Read and validate a TOML configuration file.

    Raises:
        ValueError: unreadable file, TOML syntax error, or an invalid entry (named in the message).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ValueError(f"cannot read config {str(p)!r}: {e.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{p}: not valid TOML: {e}") from None
    return parse_config(data, p.parent, str(p))


def _mechanism(data: dict[str, Any]) -> tuple[Mechanism, Design | None]:
    preset = None
    if "preset" in data:
        name = _str(data["preset"], "preset")
        if name not in presets.PRESETS:
            raise _fail("preset", f"unknown preset {name!r} (see 'clm presets')")
        preset = presets.PRESETS[name].design()
    if "mechanism" in data:
        name = _str(data["mechanism"], "mechanism")
        if name not in MECHANISMS:
            raise _fail("mechanism", f"unknown mechanism {name!r}; known: {', '.join(sorted(MECHANISMS))}")
        mech = MECHANISMS[name]
        if preset is not None and preset.mechanism.name != name:
            raise _fail("preset", f"preset is a {preset.mechanism.name} design, but mechanism = {name!r}")
        return mech, preset
    if preset is None:
        raise _fail("mechanism", "missing; give mechanism = \"<name>\" or preset = \"<name>\"")
    return preset.mechanism, preset


def _bounds(mech: Mechanism, table: Any) -> Mechanism:
    table = _keys(table, "bounds", set(mech.param_names))
    if not table:
        return mech
    params: list[Param] = []
    for p in mech.params:
        if p.name not in table:
            params.append(p)
            continue
        key = f"bounds.{p.name}"
        v = table[p.name]
        if not isinstance(v, list) or len(v) != 2:
            raise _fail(key, f"expected [lower, upper], got {_kind(v)}")
        lo, hi = _num(v[0], key + "[0]"), _num(v[1], key + "[1]")
        if not lo < hi:
            raise _fail(key, f"impossible bounds: lower {lo:g} is not below upper {hi:g}")
        if p.kind == "length" and lo <= 0.0:
            raise _fail(key, f"a length must stay > 0 mm, got lower bound {lo:g}")
        params.append(replace(p, lo=lo, hi=hi))
    return replace(mech, params=tuple(params))


def _output(data: dict[str, Any], preset: Design | None, mech: Mechanism) -> OutputStage:
    if "output" not in data:
        if preset is not None:
            return preset.output
        # The paper's leg inverts its design-frame path by a pantograph (spec §2); RTCLM needs none.
        return IDENTITY if mech.derive is not None else PAPER_OUTPUT
    o = _keys(data["output"], "output", {"k", "ox", "oy", "mirror"})
    k = _num(o.get("k", 1.0), "output.k")
    if k == 0.0:
        raise _fail("output.k", "must be non-zero")
    mirror = o.get("mirror", False)
    if not isinstance(mirror, bool):
        raise _fail("output.mirror", f"must be true or false, got {mirror!r}")
    return OutputStage(k, _num(o.get("ox", 0.0), "output.ox"), _num(o.get("oy", 0.0), "output.oy"), mirror)


def _target(data: dict[str, Any], base: Path) -> str:
    t = _keys(data.get("target", {}), "target", _TARGET)
    curve = _str(t.get("curve", "cycloid"), "target.curve")
    if curve == "cycloid":
        L = _num(t.get("L", 300.0), "target.L", 0.0, open_lo=True)
        H = _num(t.get("H", 100.0), "target.H", 0.0, open_lo=True)
        T = _num(t.get("T", 2.0), "target.T", 0.0, open_lo=True)
        return f"cycloid:L={L!r},H={H!r},T={T!r}"
    for k in ("L", "H", "T"):
        if k in t:
            raise _fail(f"target.{k}", "only for curve = \"cycloid\"")
    p = (base / curve).resolve()
    if not p.is_file():
        raise _fail("target.curve", f"file {str(p)!r} not found")
    from core.analysis.targets import load_curve

    try:
        load_curve(p)
    except ValueError as e:
        raise _fail("target.curve", str(e)) from None
    return str(p)


def _algorithm(table: Any, key: str, base: AlgorithmSpec | None) -> AlgorithmSpec:
    t = _keys(table, key, _ALGO)
    name = _str(t["name"], f"{key}.name", tuple(ALGORITHMS)) if "name" in t else (base.name if base else "nsga2")
    pop = _int(t["pop_size"], f"{key}.pop_size", 2) if "pop_size" in t else (base.pop_size if base else 200)
    opts = dict(base.options) if base is not None and name == base.name else {}
    if "options" in t:
        o = _keys(t["options"], f"{key}.options", set(ALGORITHMS[name].options))
        for k, v in o.items():
            if k == "variant":
                opts[k] = _str(v, f"{key}.options.{k}")
            elif k == "eliminate_duplicates":
                opts[k] = _bool(v, f"{key}.options.{k}")
            elif k == "n_partitions":
                opts[k] = _int(v, f"{key}.options.{k}", 1)
            elif k == "F" and isinstance(v, list):
                opts[k] = [_num(x, f"{key}.options.F[{i}]", 0.0) for i, x in enumerate(v)]
            else:
                opts[k] = _num(v, f"{key}.options.{k}", 0.0)
    spec = AlgorithmSpec(name, pop, opts)
    try:
        validate(spec)
    except ValueError as e:
        raise _fail(key, str(e)) from None
    return spec


def _box(v: Any, key: str) -> tuple[float | None, float]:
    if isinstance(v, str):
        if v == "global":
            return None, 0.0
        if v.startswith("subtask") and v[7:].isdigit() and int(v[7:]) in SUBTASK_STEPS:
            return SUBTASK_STEPS[int(v[7:])]
        raise _fail(key, f"{v!r} is not 'global', 'subtask1', 'subtask2', 'subtask3' or {{s = ..., d = ...}}")
    t = _keys(v, key, {"s", "d"})
    if "s" not in t or "d" not in t:
        raise _fail(key, "a box table needs both s (relative half-width) and d (mm)")
    return _num(t["s"], f"{key}.s", 0.0, open_lo=True), _num(t["d"], f"{key}.d", 0.0, open_lo=True)


def _pick(v: Any, key: str, spec: ProblemSpec) -> PickRule:
    if isinstance(v, int) and not isinstance(v, bool):
        return _int(v, key, 0)
    rule = _str(v, key)
    if rule == "knee":
        return rule
    if rule.startswith("knee:") and rule[5:].isdigit():
        return rule
    if rule.startswith("best:"):
        _metric(rule[5:], key, spec, rule)
        return rule
    raise _fail(key, f"unknown pick rule {rule!r}; use 'knee', 'knee:k', 'best:<metric>' or a member index")


def _metric(name: str, key: str, spec: ProblemSpec, what: str) -> str:
    if name not in spec.metric_names:
        raise _fail(key, f"{what!r}: problem {spec.name!r} reports no metric {name!r}; known: "
                    f"{', '.join(spec.metric_names)}")
    return name


def _where(v: Any, key: str, spec: ProblemSpec) -> tuple[Constraint, ...]:
    """``{I_max = 1.0, S_min = 0.5}`` -> limits on the problem's metrics."""
    if not isinstance(v, dict):
        raise _fail(key, f"expected a table of limits like {{I_max = 1.0}}, got {_kind(v)}")
    out = []
    for k, x in v.items():
        where = f"{key}.{k}"
        if not (isinstance(k, str) and len(k) > 4 and k[-4:] in ("_max", "_min")):
            raise _fail(where, "a limit is '<metric>_max' or '<metric>_min'")
        name = _metric(k[:-4], where, spec, k)
        bound = _num(x, where)
        out.append(Constraint(name, upper=bound) if k.endswith("_max") else Constraint(name, lower=bound))
    return tuple(out)


def _options(problem: str, given: Any, shared: dict[str, Any], key: str) -> dict[str, Any]:
    """Problem options: the shared ones the factory takes, then the stage's own (checked against the factory)."""
    problem_registry.problem_names()  # load the providers
    factory = problem_registry._FACTORIES[problem]
    params = inspect.signature(factory).parameters
    given = _keys(given, key, set(params))
    out = {k: v for k, v in shared.items() if k in params}
    for k, v in given.items():
        default = params[k].default
        where = f"{key}.{k}"
        if k in LIMIT_METRICS and isinstance(v, (str, list)):
            items = v if isinstance(v, list) else [v]
            if not items:
                raise _fail(where, "an empty list of limits")
            for j, item in enumerate(items):
                w = f"{where}[{j}]" if isinstance(v, list) else where
                if isinstance(item, str):
                    try:
                        parse_relative(item)
                    except ValueError as e:
                        raise _fail(w, str(e)) from None
                else:
                    _num(item, w, 0.0)
            out[k] = v
        elif isinstance(default, bool):
            out[k] = _bool(v, where)
        elif isinstance(default, int):
            out[k] = _int(v, where, 1)
        elif isinstance(default, float):
            out[k] = _num(v, where, 0.0) if (k.endswith("_max") or k.endswith("_tol")) else _num(v, where)
        else:
            out[k] = _str(v, where)
    return out


def _stage(i: int, t: Any, shared: dict[str, Any], algorithm: AlgorithmSpec, mech: Mechanism,
           names: set[str]) -> StageConfig:
    key = f"stages[{i}]"
    t = _keys(t, key, _STAGE)
    if "name" not in t:
        raise _fail(f"{key}.name", "missing")
    name = _str(t["name"], f"{key}.name")
    if name in names:
        raise _fail(f"{key}.name", f"duplicate stage name {name!r}")
    known = problem_registry.problem_names()
    prob = _str(t.get("problem", name), f"{key}.problem")
    if prob not in known:
        raise _fail(f"{key}.problem", f"unknown problem {prob!r}; known: {', '.join(known)}")
    options = _options(prob, t.get("options", {}), shared, f"{key}.options")
    # Build once with placeholder limits to learn the objectives and to check the options.
    try:
        spec = make_problem(prob, **placeholder(options))
    except ValueError as e:
        raise _fail(f"{key}.options", str(e)) from None
    s, d = _box(t.get("box", "global"), f"{key}.box")
    n_gen = _int(t.get("n_gen", 100), f"{key}.n_gen", 1)
    pick = _pick(t.get("pick", "knee"), f"{key}.pick", spec)
    pick_where = _where(t["pick_where"], f"{key}.pick_where", spec) if "pick_where" in t else ()
    stop = None
    if "stop_below" in t:
        v = t["stop_below"]
        if not isinstance(v, list) or len(v) != spec.n_obj:
            raise _fail(f"{key}.stop_below", f"expected {spec.n_obj} numbers (one per objective: "
                        f"{', '.join(spec.objectives)})")
        stop = tuple(_num(x, f"{key}.stop_below[{j}]", 0.0) for j, x in enumerate(v))
    fixed: tuple[str, ...] = ()
    if "fixed" in t:
        v = t["fixed"]
        if not isinstance(v, list):
            raise _fail(f"{key}.fixed", f"expected an array of parameter names, got {_kind(v)}")
        for j, n in enumerate(v):
            if _str(n, f"{key}.fixed[{j}]") not in mech.param_names:
                raise _fail(f"{key}.fixed[{j}]", f"{mech.name} has no parameter {n!r}")
        fixed = tuple(v)
    alg = _algorithm(t["algorithm"], f"{key}.algorithm", algorithm) if "algorithm" in t else algorithm
    if spec.repair is not None:  # placement needs a mechanism that can follow a similarity transform
        from core.optimize.predesign import placement

        try:
            placement(mech)
        except ValueError as e:
            raise _fail(f"{key}.problem", f"{prob} places designs analytically, but {e}") from None
    return StageConfig(name, prob, s, d, n_gen, pick, alg, options, stop, fixed,
                       _bool(t.get("seed_start", True), f"{key}.seed_start"), pick_where)


def _starts(stages: list[StageConfig], raw: list[Any]) -> list[StageConfig]:
    """Stages with their ``starts`` tables parsed (they name later stages, so this runs last)."""
    names = [s.name for s in stages]
    out = list(stages)
    taken = -1  # last stage of the previous block: blocks may not overlap
    for i, t in enumerate(raw):
        if "starts" not in t:
            continue
        key = f"stages[{i}].starts"
        v = _keys(t["starts"], key, _STARTS)
        if i <= taken:
            raise _fail(key, f"stage {names[i]!r} is already inside the multi-start block of an earlier stage")
        if "n" not in v:
            raise _fail(f"{key}.n", "missing; the number of chains")
        n = _int(v["n"], f"{key}.n", 1)
        until = _str(v.get("until", names[i]), f"{key}.until")
        if until not in names[i:]:
            raise _fail(f"{key}.until", f"{until!r} is not this stage or a later one; "
                        f"stages from here: {', '.join(names[i:])}")
        last = names.index(until, i)
        spec = stages[last].problem_spec()
        if "select" not in v:
            raise _fail(f"{key}.select", "missing; e.g. select = \"best:S\" (a metric of the last stage's pick)")
        select = _str(v["select"], f"{key}.select")
        if not select.startswith("best:"):
            raise _fail(f"{key}.select", f"{select!r}: use 'best:<metric>'")
        _metric(select[5:], f"{key}.select", spec, select)
        where = _where(v["where"], f"{key}.where", spec) if "where" in v else ()
        screen = _screen(v["screen"], f"{key}.screen", stages, i, last, n) if "screen" in v else None
        out[i] = replace(stages[i], starts=Starts(n, until, select, where, screen))
        taken = last
    return out


def _screen(v: Any, key: str, stages: list[StageConfig], first: int, last: int, n: int) -> Screen:
    t = _keys(v, key, _SCREEN)
    for k in ("after", "keep", "by"):
        if k not in t:
            raise _fail(f"{key}.{k}", "missing; a screen needs after, keep and by")
    names = [s.name for s in stages]
    after = _str(t["after"], f"{key}.after")
    if after not in names[first:last]:
        raise _fail(f"{key}.after", f"{after!r} is not a stage of the block before its last one; "
                    f"choose from {', '.join(names[first:last]) or '(none: the block has one stage)'}")
    keep = _int(t["keep"], f"{key}.keep", 1)
    if keep > n:
        raise _fail(f"{key}.keep", f"keeps {keep} of only {n} chains")
    by = _str(t["by"], f"{key}.by")
    if not by.startswith("best:"):
        raise _fail(f"{key}.by", f"{by!r}: use 'best:<metric>'")
    _metric(by[5:], f"{key}.by", stages[names.index(after, first)].problem_spec(), by)
    return Screen(after, keep, by)


def parse_config(data: Mapping[str, Any], base: str | Path = ".", path: str | None = None) -> DesignConfig:
    """Validate a configuration given as a dict (the parsed TOML).

    Args:
        data: the configuration.
        base: directory that relative file names (``target.curve``) are relative to.
        path: the file it came from (recorded).

    Raises:
        ValueError: the first invalid entry, named by its key.
    """
    data = _keys(dict(data), "", _TOP)
    name = _str(data.get("name", "design"), "name")
    method = _str(data.get("method", "hierarchical"), "method", METHODS)
    mech, preset = _mechanism(data)
    mech = _bounds(mech, data.get("bounds", {}))
    output = _output(data, preset, mech)
    center = preset.params[0] if preset is not None else 0.5 * (mech.lower + mech.upper)
    start = Design(mech, center[None], output)
    seed = _int(data.get("seed", 0), "seed", 0)
    n_samples = _int(data.get("n_samples", 360), "n_samples", 8)
    if n_samples % 2:
        raise _fail("n_samples", f"must be even (t + T/2 must fall on a sample), got {n_samples}")
    backend = _str(data.get("backend", "auto"), "backend", BACKENDS)
    workers = _workers(data.get("workers", "auto"), "workers")
    shared: dict[str, Any] = {"n_samples": n_samples, "backend": backend}
    if "target" in data or mech.derive is None:
        shared["target"] = _target(data, Path(base))
    if "rtclm" in data:
        r = _keys(data["rtclm"], "rtclm", _RTCLM)
        if "h6" in r:
            shared["h6_target"] = _num(r["h6"], "rtclm.h6", 0.0, open_lo=True)
        if "h4" in r:
            shared["h4_target"] = _num(r["h4"], "rtclm.h4", 0.0, open_lo=True)
    algorithm = _algorithm(data.get("algorithm", {}), "algorithm", None)
    stages: list[StageConfig] = []
    if method in ("hierarchical", "single_level"):
        raw = data.get("stages")
        if raw is None and method == "single_level":
            raw = [{"name": "single_level", "problem": "single_level", "box": "global", "pick": "best:f1"}]
        if not isinstance(raw, list) or not raw:
            raise _fail("stages", "missing; a design needs at least one [[stages]] table")
        names: set[str] = set()
        for i, t in enumerate(raw):
            stages.append(_stage(i, t, shared, algorithm, mech, names))
            names.add(stages[-1].name)
        stages = _starts(stages, raw)
    elif "stages" in data:
        raise _fail("stages", f"not used by method = {method!r}")
    baseline = BaselineSettings(target=shared.get("target", "cycloid"), n_samples=n_samples, backend=backend)
    if "baseline" in data:
        if method not in DP_METHODS:
            raise _fail("baseline", f"only for the DP methods ({', '.join(DP_METHODS)})")
        b = _keys(data["baseline"], "baseline", _BASELINE)
        ints: dict[str, Any] = {k: _int(v, f"baseline.{k}", 1) for k, v in b.items()}
        baseline = replace(baseline, **ints)
        if n_samples % baseline.n_points:
            raise _fail("baseline.n_points", f"must divide n_samples ({n_samples}), got {baseline.n_points}")
    return DesignConfig(name, method, mech, start, seed, tuple(stages), baseline, dict(data), path, workers)


def _workers(v: Any, key: str) -> int:
    """``"auto"`` (0: every available core) or a count >= 1."""
    if v == "auto":
        return 0
    if isinstance(v, str):
        raise _fail(key, f"must be 'auto' or an integer >= 1, got {v!r}")
    return _int(v, key, 1)


# ---------------------------------------------------------------------------------------
# Running.


@dataclass
class DesignRun:
    """The outcome of :func:`run_design`.

    Attributes:
        config: the configuration.
        pipeline: the stages' lineage (hierarchical / single_level), else None.
        baseline: the DP baseline result, else None.
        status: ``complete`` or ``cancelled``.
        wall_time: seconds from start to end (setup and between-stage work included).
        multistart: the record of each multi-start block (every chain's picks; the pipeline
            holds the winning chain's results).
        workers: processes the chains ran in (1 without a multi-start block).
    """

    config: DesignConfig
    pipeline: Pipeline | None = None
    baseline: BaselineResult | None = None
    status: str = "complete"
    wall_time: float = 0.0
    multistart: tuple[MultiStart, ...] = ()
    workers: int = 1

    @property
    def compute_time(self) -> float:
        """Compute time of every stage run (s): the lineage's and the losing chains'."""
        return float(sum(r.timings["total"] for r in self.results) + sum(m.time for m in self.multistart))

    @property
    def results(self) -> list[StageResult]:
        return [] if self.pipeline is None else self.pipeline.lineage

    def final(self) -> tuple[StageResult, int] | None:
        """The last stage result that has a pick, and the pick."""
        for r in reversed(self.results):
            if r.picked is not None:
                return r, r.picked
        return None

    def rows(self) -> list[dict[str, Any]]:
        """Summary rows for ``clm compare``: label, time (s) and the chosen designs' metrics."""
        c = self.config
        if self.baseline is not None:
            b = self.baseline
            return [{"label": f"{c.name}: {b.to_dict()['title']}", "method": b.method, "time": b.time,
                     "status": b.status, **b.metrics}]
        total = self.compute_time
        out: list[dict[str, Any]] = []
        if c.method == "single_level" and self.results:
            r = self.results[-1]
            # Appendix B-4: the designs with the smallest MSE, h_s and I.
            shown: list[str] = [o for o in ("f1", "h_s", "I") if o in r.objectives] or list(r.objectives)
            for obj in shown:
                if r.shortlist.best:
                    i = r.choose(f"best:{obj}")
                    out.append(_row(f"{c.name}: single-level, smallest {obj}", c.method, total, r, i, self.status))
            return out
        fin = self.final()
        if fin is not None:
            r, i = fin
            out.append(_row(f"{c.name}: {r.name} pick", c.method, total, r, i, self.status))
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": "clm-design",
            "format_version": 1,
            "name": self.config.name,
            "method": self.config.method,
            "config": dict(self.config.source),
            "config_path": self.config.path,
            "status": self.status,
            "wall_time": self.wall_time,
            "rows": self.rows(),
            "pipeline": None if self.pipeline is None else self.pipeline.to_dict(),
            "baseline": None if self.baseline is None else self.baseline.to_dict(),
            "multistart": [m.to_dict() for m in self.multistart],
            "workers": self.workers,
        }


ROW_METRICS = ("mse", "S", "I", "h_s", "f2", "f3", "h6", "h4", "dh6", "dh4")


def _row(label: str, method: str, total: float, r: StageResult, i: int, status: str) -> dict[str, Any]:
    row: dict[str, Any] = {"label": label, "method": method, "time": total, "status": status, "stage": r.name,
                           "member": i, "feasible": bool(r.feasible[i]), "params": r.named(i)}
    for k in ROW_METRICS:
        if k in r.metrics:
            row[k] = float(r.metrics[k][i])
    return row


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


def start_metrics(stage: StageConfig, design: Design) -> dict[str, F64]:
    """The metrics of a stage's start design under that stage's problem (to resolve relative limits)."""
    return dict(make_problem(stage.problem, **placeholder(stage.options)).evaluate_metrics(design))


def resolved_spec(stage: StageConfig, start: Design, seed: int) -> StageSpec:
    """A stage's spec with relative limits resolved against its start design.

    A relative limit on a metric the start does not have (it does not assemble) falls back to
    the problem's default (the paper's absolute threshold).
    """
    opts = dict(stage.options)
    relative = [k for k, v in opts.items() if isinstance(v, (str, list)) and k in LIMIT_METRICS]
    if relative:
        metrics = start_metrics(stage, start)
        defaults = inspect.signature(problem_registry._FACTORIES[stage.problem]).parameters
        for k in relative:
            if not np.isfinite(metrics[LIMIT_METRICS[k]]).all():
                opts[k] = defaults[k].default
        opts = resolve_limits(opts, metrics)
    return stage.spec(seed, opts)


def next_feasible(result: StageResult, nxt: ProblemSpec | None) -> NDArray[np.bool_]:
    """``(pop,)`` members feasible here that also satisfy the next stage's constraints on shared metrics."""
    ok = result.feasible.copy()
    if nxt is None:
        return ok
    for c in nxt.constraints:
        if c.metric in result.metrics:
            with np.errstate(invalid="ignore"):
                ok &= np.nan_to_num(c.value(result.metrics[c.metric]), nan=np.inf) <= 0.0
    return ok


def where_mask(result: StageResult, where: tuple[Constraint, ...]) -> NDArray[np.bool_]:
    """``(pop,)`` members whose metrics meet every limit (a NaN metric never does)."""
    ok = np.ones(result.pop, dtype=bool)
    for c in where:
        with np.errstate(invalid="ignore"):
            ok &= np.nan_to_num(c.value(result.metrics[c.metric]), nan=np.inf) <= 0.0
    return ok


def choose(result: StageResult, rule: PickRule, mask: NDArray[np.bool_] | None = None,
           where: tuple[Constraint, ...] = ()) -> int:
    """A pick rule applied to the members in ``mask`` (all when None or when no member is in it).

    ``where`` (a stage's ``pick_where``) narrows the candidates first: the rule applies to the
    feasible members that meet it and are in ``mask``, else to those that meet it, else it is
    ignored. With no feasible member at all, the least-violation member among those that
    assemble (``violation == 0``: their metrics are defined, so the next stage can start from them).
    """
    if not isinstance(rule, (int, np.integer)) and not result.feasible.any() and "violation" in result.metrics:
        built = np.flatnonzero(result.metrics["violation"] == 0.0)
        if built.size:
            return int(built[np.argmin(result.cv[built])])
    if where and not isinstance(rule, (int, np.integer)):
        meets = where_mask(result, where) & result.feasible
        if meets.any():
            both = meets if mask is None else meets & mask
            mask = both if both.any() else meets
    if isinstance(rule, (int, np.integer)) or mask is None or not mask.any() or mask.all():
        return result.choose(rule)
    idx = np.flatnonzero(mask)
    F, cv = result.F[idx], result.cv[idx]
    if isinstance(rule, str) and rule.startswith("best:"):
        name = rule[5:]
        if name in result.objectives:
            j = decision.best_per_objective(F, cv)[result.objectives.index(name)]
            return int(idx[j])
        best = best_metric(result.metrics[name], mask & result.feasible) if name in result.metrics else None
        return best if best is not None else result.choose(rule)
    sl = decision.shortlist(F, cv)
    k = int(rule.split(":", 1)[1]) if isinstance(rule, str) and ":" in rule else 0
    return int(idx[sl.knees[min(k, len(sl.knees) - 1)]]) if sl.knees else result.choose(rule)


def _run_stage(config: DesignConfig, pipe: Pipeline, k: int, pick: int | None, seed: int,
               callback: Callable[[Progress], None] | None, cancel: threading.Event | None) -> StageResult:
    """Run stage k of ``pipe`` from member ``pick`` of stage k-1 with its automatic pick; record and return it.

    A cancelled stage is recorded without a pick.
    """
    stage_cfg = config.stages[k]
    start, _ = pipe.parent(k, pick)
    spec = resolved_spec(stage_cfg, start, seed)
    res = pipe.stage(k, pick, spec=spec, callback=callback).run(cancel=cancel)
    if res.status not in ("complete", "stopped"):
        pipe.record(k, res)
        return res
    nxt = None
    if k + 1 < len(config.stages):
        # The next stage's absolute thresholds steer the pick (relative ones hold for every candidate).
        s = config.stages[k + 1]
        nxt = make_problem(s.problem, **placeholder(s.options, absolute=True))
    mask = next_feasible(res, nxt)
    if res.status == "stopped" and spec.stop_below is not None:
        # The stage stopped because members met its thresholds: pick among those.
        met = res.feasible & (res.F <= np.asarray(spec.stop_below)).all(axis=1)
        mask = mask & met if (mask & met).any() else met
    res = res.with_pick(choose(res, stage_cfg.pick, mask, stage_cfg.pick_where))
    pipe.record(k, res)
    return res


class _Chain:
    """A chain of a multi-start block being run: its own pipeline and what it picked so far."""

    def __init__(self, config: DesignConfig, pipe: Pipeline, first: int, last: int, j: int) -> None:
        self.config, self.j = config, j
        self.pipe = Pipeline(pipe.stages, pipe.start, pipe.results[:first])  # shares the stages before the block
        self.seeds = tuple(config.seed + k + SEED_STRIDE * j for k in range(first, last + 1))
        self.first, self.last = first, last
        self.picks: list[int | None] = []
        self.metrics: list[dict[str, float]] = []
        self.params: list[dict[str, float]] = []
        self.time = 0.0
        self.status = "running"
        self.feasible = False

    def run(self, upto: int, pick: int | None, callback: Callable[[Progress], None] | None,
            cancel: threading.Event | None) -> bool:
        """Run the chain's next stages up to stage ``upto``; False if one was cancelled."""
        if self.picks:
            pick = self.picks[-1]
        tagged = None if callback is None else _tag(callback, self.j)
        for k in range(self.first + len(self.picks), upto + 1):
            res = _run_stage(self.config, self.pipe, k, pick, self.seeds[k - self.first], tagged, cancel)
            self.time += float(res.timings["total"])
            pick = res.picked
            self.picks.append(pick)
            if pick is None:
                self.metrics.append({})
                self.params.append({})
                self.status = "cancelled"
                return False
            self.metrics.append({n: float(v[pick]) for n, v in res.metrics.items()})
            self.params.append(res.named(pick))
            self.feasible = bool(res.feasible[pick])
        if upto == self.last:
            self.status = "complete"
        return True

    def reached(self, upto: int) -> bool:
        """Whether the chain has a pick at stage ``upto``."""
        return len(self.picks) == upto - self.first + 1 and self.picks[-1] is not None

    def record(self) -> Chain:
        # A chain still running when the run stopped counts as cancelled.
        status = "cancelled" if self.status == "running" else self.status
        return Chain(self.j, self.seeds, status, tuple(self.picks), tuple(self.metrics), tuple(self.params),
                     self.feasible and status == "complete", self.time)


def _tag(callback: Callable[[Progress], None], j: int) -> Callable[[Progress], None]:
    return lambda p: callback(replace(p, chain=j))


def _chain_job(job: tuple[_Chain, int, int | None], callback: Callable[[Progress], None] | None,
               cancel: Any) -> _Chain:
    """Run one chain up to a stage (in a worker process, or here); the chain as it then is."""
    chain, upto, pick = job
    if cancel is None or not cancel.is_set():  # a chain not started before the cancel stays unrecorded
        chain.run(upto, pick, callback, cancel)
    return chain


def _run_chains(chains: list[_Chain], upto: int, pick: int | None, workers: int,
                callback: Callable[[Progress], None] | None, cancel: threading.Event | None) -> list[_Chain]:
    if resolve_workers(workers, len(chains)) > 1 and start_method() == "fork":
        _compile_here(chains[0], upto, pick)
    return run_jobs(_chain_job, [(c, upto, pick) for c in chains], workers, callback, cancel)


def _compile_here(chain: _Chain, upto: int, pick: int | None) -> None:
    """Evaluate (and repair) the chain's start design under each of its stages' problems here, so
    that forked workers inherit every numba kernel the chains use (on a cold cache each worker
    would otherwise compile them all itself)."""
    start, _ = chain.pipe.parent(chain.first + len(chain.picks), pick if not chain.picks else chain.picks[-1])
    for stage in chain.config.stages[chain.first + len(chain.picks) : upto + 1]:
        spec = stage.problem_spec()
        spec.evaluate_metrics(start)
        if spec.repair is not None:
            spec.repair(start)


def _run_block(config: DesignConfig, pipe: Pipeline, first: int, pick: int | None, starts: Starts,
               callback: Callable[[Progress], None] | None,
               cancel: threading.Event | None) -> tuple[MultiStart, Pipeline, bool]:
    """A multi-start block from stage ``first``: its record, the pipeline to go on with, and
    whether it completed (else that pipeline is the first cancelled chain's).

    The chains run in ``config.workers`` processes. After a cancel, the record holds the chains
    that had started (the cancelled ones with their partial picks).
    """
    names = [s.name for s in config.stages]
    last = names.index(starts.until, first)
    upto = last if starts.screen is None else names.index(starts.screen.after, first)
    chains = [_Chain(config, pipe, first, last, j) for j in range(starts.n)]

    def stopped(run: list[_Chain], k: int) -> tuple[MultiStart, Pipeline, bool] | None:
        # Unless every chain of this round reached stage k: the first cancelled one is chosen.
        short = sorted((c.status != "cancelled", c.j) for c in run if not c.reached(k))
        if not short:
            return None
        c = next(x for x in run if x.j == short[0][1])
        records = tuple(x.record() for x in chains if x.picks)
        return MultiStart(starts, tuple(names[first : last + 1]), first, last, records, c.j), c.pipe, False

    chains = _run_chains(chains, upto, pick, config.workers, callback, cancel)
    if (out := stopped(chains, upto)) is not None:
        return out
    going = chains
    if starts.screen is not None:
        order = rank_chains([c.metrics[-1] for c in chains], [c.feasible for c in chains], starts.screen.by)
        kept = set(order[: starts.screen.keep])
        going = [c for c in chains if c.j in kept]
        for c in chains:
            if c.j not in kept:
                c.status = "dropped"
        going = _run_chains(going, last, None, config.workers, callback, cancel)
        chains = [next((g for g in going if g.j == c.j), c) for c in chains]
        if (out := stopped(going, last)) is not None:
            return out
    won = going[select_chain([c.metrics[-1] for c in going], [c.feasible for c in going], starts.select,
                             starts.where)]
    record = MultiStart(starts, tuple(names[first : last + 1]), first, last, tuple(c.record() for c in chains), won.j)
    return record, won.pipe, True


def run_design(config: DesignConfig, callback: Callable[[Progress], None] | None = None,
               cancel: threading.Event | None = None) -> DesignRun:
    """Run a configuration headless.

    Args:
        config: the validated configuration.
        callback: after every generation (stages, and the GA of the DP baselines).
        cancel: checked between generations; the run then stops with a valid partial result.
    """
    t0 = time.perf_counter()
    if config.method in DP_METHODS:
        b = run_baseline(config.method, config.mechanism, config.start.output, config.baseline, config.seed,
                         callback, cancel)
        return DesignRun(config, baseline=b, status=b.status, wall_time=time.perf_counter() - t0)
    placeholders = [s.spec(config.seed + k, placeholder(s.options)) for k, s in enumerate(config.stages)]
    pipe = Pipeline(placeholders, config.start)
    blocks: list[MultiStart] = []
    used = max([resolve_workers(config.workers, s.starts.n) for s in config.stages if s.starts] or [1])
    pick: int | None = None
    k = 0
    while k < len(config.stages):
        starts = config.stages[k].starts
        if starts is None:
            res = _run_stage(config, pipe, k, pick, config.seed + k, callback, cancel)
            if res.picked is None:
                return DesignRun(config, pipe, status="cancelled", wall_time=time.perf_counter() - t0,
                                 multistart=tuple(blocks), workers=used)
            pick, k = res.picked, k + 1
            continue
        block, pipe, done = _run_block(config, pipe, k, pick, starts, callback, cancel)
        blocks.append(block)
        if not done:
            return DesignRun(config, pipe, status="cancelled", wall_time=time.perf_counter() - t0,
                             multistart=tuple(blocks), workers=used)
        pick, k = block.chains[block.chosen].picks[-1], block.last + 1
    return DesignRun(config, pipeline=pipe, status="complete", wall_time=time.perf_counter() - t0,
                     multistart=tuple(blocks), workers=used)
