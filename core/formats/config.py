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
(``stages[2].options.f1_max: ...``). Running a configuration is ``core.optimize.run``.
"""

from __future__ import annotations

import inspect
import math
import tomllib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from core.kinematics import presets
from core.kinematics.design import Design
from core.kinematics.mechanisms import MECHANISMS
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.kinematics.params import Param
from core.optimize import problem as problem_registry
from core.optimize.algorithms import ALGORITHMS, AlgorithmSpec, validate
from core.optimize.baselines import DP_METHODS, BaselineSettings
from core.optimize.box import SUBTASK_STEPS
from core.optimize.multistart import Screen, Starts
from core.optimize.problem import Constraint, ProblemSpec, make_problem
from core.optimize.result import PickRule
from core.optimize.run import (
    BACKENDS,
    METHODS,
    PAPER_OUTPUT,
    DesignConfig,
    StageConfig,
    placeholder,
)
from core.optimize.subtasks import LIMIT_METRICS, parse_relative

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


__all__ = ["load_config", "parse_config"]
