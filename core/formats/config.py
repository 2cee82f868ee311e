"""A design configuration (TOML), decoded through the Structs of ``config_file`` and checked across keys.

The format: docs/optimization.md, assets/configs/, assets/schemas/design-config.schema.json. Every error is a
``ValueError`` whose message starts with the offending key (``stages[2].options.f1_max: ...``). Running a
configuration is ``core.optimize.run``.
"""

from __future__ import annotations

import inspect
import json
import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec
from msgspec import Struct

from core.formats.config_file import (
    Algorithm,
    Box,
    ConfigFile,
    NonNeg,
    Output,
    PosInt,
    Screen_,
    Stage,
    Target,
)
from core.formats.files import backslash_hint
from core.formats.typed import decode, kind
from core.kinematics import presets
from core.kinematics.checks import MAX_ABS
from core.kinematics.design import Design
from core.kinematics.mechanisms import MECHANISMS
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.kinematics.params import Param
from core.optimize import problem as problem_registry
from core.optimize.algorithms import ALGORITHMS, RANGES, AlgorithmSpec, make_algorithm, registered, suggestion, validate
from core.optimize.baselines import DP_METHODS, BaselineSettings
from core.optimize.box import SUBTASK_STEPS
from core.optimize.design_config import PAPER_OUTPUT, DesignConfig, StageConfig, placeholder
from core.optimize.multistart import Screen, Starts
from core.optimize.objectives import target_scale
from core.optimize.problem import Constraint, ProblemSpec, make_problem
from core.optimize.result import PickRule
from core.optimize.scale import sized_bounds
from core.optimize.subtasks import LIMIT_METRICS, parse_relative


def _fail(key: str, msg: str) -> ValueError:
    return ValueError(f"{key}: {msg}")


OUR_JSON = (("clm-design", "a run's result.json"), ("clm-studio-session", "a studio session"),
            ("clm-stage-result", "a stage result"), ("clm-pipeline", "a pipeline record"))
"""The JSON files clm writes, by their "format", as a config's refusal names them."""


def load_config(path: str | Path) -> DesignConfig:
    """Read and validate a TOML configuration file.

    Raises:
        ValueError: unreadable file, TOML syntax error, or an invalid entry (named in the message).
    """
    p = Path(path)
    try:
        if not p.is_file():
            why = "not a regular file" if p.exists() else "no such file"
            raise ValueError(f"cannot read config {str(p)!r}: {why}")
        if p.stat().st_size > 1_000_000:
            raise ValueError(f"{p}: a config file is at most 1 MB")
        text = p.read_text(encoding="utf-8-sig")  # a BOM (Windows editors) read as "Invalid statement" (rehearsal 8)
    except OSError as e:
        raise ValueError(f"cannot read config {str(p)!r}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a UTF-8 text file") from None
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as e:
        hint = ""
        if text.lstrip().startswith("{"):  # a JSON of ours given for a config (lab rehearsal; review of session 32)
            what = _our_json(text)
            if what is not None:
                hint = f" (this is {what}; clm design takes a TOML configuration such as assets/configs/*.toml, " \
                       "whose preset names the design it starts from)"
        raise ValueError(f"{p}: not valid TOML: {str(e).splitlines()[0] if str(e) else 'nested too deep'}"
                         f"{hint}") from None
    return parse_config(data, p.parent, str(p))


def _our_json(text: str) -> str | None:
    """What a JSON file of ours is, by its top-level "format" (a pipeline record holds stage results, whose formats
    named it "a stage result": review of session 34); a cut-off file by its first one."""
    try:
        d = json.loads(text)
    except (ValueError, RecursionError):
        m = re.search(r'"format"\s*:\s*"([^"]*)"', text)
        fmt, design = (m.group(1) if m else None), '"mechanism"' in text
    else:
        fmt, design = (d.get("format"), "mechanism" in d) if isinstance(d, dict) else (None, False)
    named = dict(OUR_JSON).get(fmt) if isinstance(fmt, str) else None
    return named or ("a design JSON" if design else None)


def _mechanism(f: ConfigFile) -> tuple[Mechanism, Design | None]:
    preset = None
    if f.preset is not None:
        if f.preset not in presets.PRESETS:
            raise _fail("preset", f"unknown preset {f.preset!r} (see 'clm presets')")
        preset = presets.PRESETS[f.preset].design()
    if f.mechanism is not None:
        if f.mechanism not in MECHANISMS:
            raise _fail("mechanism", f"unknown mechanism {f.mechanism!r}; known: {', '.join(sorted(MECHANISMS))}")
        if preset is not None and preset.mechanism.name != f.mechanism:
            raise _fail("preset", f"preset is a {preset.mechanism.name} design, but mechanism = {f.mechanism!r}")
        return MECHANISMS[f.mechanism], preset
    if preset is None:
        raise _fail("mechanism", "missing; give mechanism = \"<name>\" or preset = \"<name>\"")
    return preset.mechanism, preset


def _bounds(mech: Mechanism, table: dict[str, Any]) -> Mechanism:
    for k in table:
        if k not in mech.param_names:
            raise _fail(f"bounds.{k}", f"unknown key; known: {', '.join(sorted(mech.param_names))}")
    params: list[Param] = []
    for p in mech.params:
        if p.name not in table:
            params.append(p)
            continue
        key = f"bounds.{p.name}"
        v = table[p.name]
        if not isinstance(v, list) or len(v) != 2:
            raise _fail(key, f"expected [lower, upper], got {kind(v)}")
        lo, hi = decode(v, tuple[float, float], key)
        if not max(abs(lo), abs(hi)) <= MAX_ABS:  # a design file's domain: past it the geometry is noise
            raise _fail(key, f"bounds must lie within +-{MAX_ABS:g} (mm or rad), got [{lo:g}, {hi:g}]")
        if not lo < hi:
            raise _fail(key, f"impossible bounds: lower {lo:g} is not below upper {hi:g}")
        if p.kind == "length" and lo <= 0.0:
            raise _fail(key, f"a length must stay > 0 mm, got lower bound {lo:g}")
        if p.kind == "angle" and max(abs(lo), abs(hi)) > 2.0 * math.pi:  # lab rehearsal: 349 "rad" from degrees
            raise _fail(key, f"angles are in rad and one turn is enough: [{lo:g}, {hi:g}] goes beyond +-2 pi "
                        f"(degrees? [{lo:g}, {hi:g}] deg is [{math.radians(lo):.4g}, {math.radians(hi):.4g}] rad)")
        if p.kind == "length" and hi < 1.0:  # a link under 1 mm long is no leg's: metres (lab rehearsal)
            raise _fail(key, f"[{lo:g}, {hi:g}] mm: a link under 1 mm long (metres? lengths are in mm)")
        params.append(replace(p, lo=lo, hi=hi, sized=False))
    return replace(mech, params=tuple(params))


def _output(o: Output | None, preset: Design | None, mech: Mechanism, k: float) -> OutputStage:
    if o is None:
        if preset is not None:
            return preset.output
        # The paper's leg inverts its design-frame path by a pantograph (spec §2) about a point sized with the leg;
        # RTCLM needs none.
        return IDENTITY if mech.derive is not None else replace(PAPER_OUTPUT, ox=PAPER_OUTPUT.ox * k,
                                                                oy=PAPER_OUTPUT.oy * k)
    if o.k == 0.0:
        raise _fail("output.k", "must be non-zero")
    if not isinstance(o.mirror, bool):
        raise _fail("output.mirror", f"must be true or false, got {o.mirror!r}")
    return OutputStage(o.k, o.ox, o.oy, o.mirror)


def _target(t: Target, base: Path) -> str:
    if t.curve == "cycloid":
        L, H, T = (300.0 if t.L is None else t.L), (100.0 if t.H is None else t.H), (2.0 if t.T is None else t.T)
        return f"cycloid:L={L!r},H={H!r},T={T!r}"
    for k in ("L", "H", "T"):
        if getattr(t, k) is not None:
            raise _fail(f"target.{k}", "only for curve = \"cycloid\"")
    p = (base / t.curve).resolve()
    if not p.is_file():
        # Lab rehearsal: "data\target.csv" in a TOML "..." string holds a TAB, and its repr read as typed.
        hint = ""
        if any(c in t.curve for c in "\t\n\r\b\f"):
            # '...' quotes keep the backslash, which is a folder separator on Windows only (review of session 32)
            quotes = ", or in '...' quotes" if os.sep == "\\" else ""
            hint = (" (a backslash in a TOML \"...\" string starts an escape: \\t is a tab; write the path with "
                    f"'/'{quotes})")
        else:
            hint = backslash_hint(t.curve)
        raise _fail("target.curve", f"file {p} not found{hint}")
    from core.analysis.targets import load_curve

    try:
        load_curve(p)
    except ValueError as e:
        raise _fail("target.curve", str(e)) from None
    return str(p)


def _ranged(lo: float, hi: float) -> Any:
    return Annotated[float, msgspec.Meta(ge=lo, le=hi)] if hi < math.inf else Annotated[float, msgspec.Meta(ge=lo)]


# Algorithm option types by name (any other option is a number >= 0); the numeric ranges are the algorithms' own.
ALGORITHM_OPTIONS: dict[str, Any] = {**{k: _ranged(*r) for k, r in RANGES.items() if k != "F"},
                                     "variant": str, "operator": Literal["ga", "de"],
                                     "eliminate_duplicates": bool, "ahead": bool,
                                     "n_partitions": PosInt, "reward": Literal["platemo", "improvement"],
                                     "replay": Literal["platemo", "fifo"], "success": Literal["platemo", "size"],
                                     "F": NonNeg | list[NonNeg]}


def _options_struct(name: str, fields: list[tuple[str, Any]]) -> type[Struct]:
    return msgspec.defstruct(name, [(n, t | None, None) for n, t in fields], forbid_unknown_fields=True,
                             omit_defaults=True)


def _given(struct: type[Struct], given: dict[str, Any], key: str) -> dict[str, Any]:
    """The options given, decoded through ``struct`` (only the keys that were given)."""
    decoded = decode(given, struct, key)
    return {k: getattr(decoded, k) for k in given}


def algorithm_options(name: str, given: Mapping[str, Any], key: str = "options") -> dict[str, Any]:
    """The options of algorithm ``name`` decoded as a configuration's ``[algorithm] options`` are (types, ranges,
    known keys); ValueError naming ``key.<option>`` otherwise."""
    known = ALGORITHMS[name].options
    if not known and given:
        raise _fail(f"{key}.{next(iter(given))}", f"{name} takes no options")
    struct = _options_struct(f"{name}_options", [(k, ALGORITHM_OPTIONS.get(k, NonNeg)) for k in known])
    return _given(struct, dict(given), key)


def _algorithm(t: Algorithm, key: str, base: AlgorithmSpec | None) -> AlgorithmSpec:
    given = None if t.name is None else registered(t.name)  # "CMOES" reads as clm moea reads it
    if given is not None and given not in ALGORITHMS:
        hint = suggestion(given)
        raise _fail(f"{key}.name", f"{given!r} is not one of {', '.join(ALGORITHMS)}" + (f"; {hint}" if hint else ""))
    name = given if given is not None else (base.name if base else "nsga2")
    pop = t.pop_size if t.pop_size is not None else (base.pop_size if base else 200)
    opts = dict(base.options) if base is not None and name == base.name else {}
    opts.update(algorithm_options(name, t.options, f"{key}.options"))
    spec = AlgorithmSpec(name, pop, opts)
    try:
        validate(spec)
    except ValueError as e:
        raise _fail(key, str(e)) from None
    return spec


def _box(v: str | Box, key: str) -> tuple[float | None, float]:
    if isinstance(v, Box):
        if v.s is None or v.d is None:
            raise _fail(key, "a box table needs both s (relative half-width) and d (mm)")
        return v.s, v.d
    return (None, 0.0) if v == "global" else SUBTASK_STEPS[int(v[7:])]


def _pick(v: str | int, key: str, spec: ProblemSpec) -> PickRule:
    if isinstance(v, int) or v == "knee" or (v.startswith("knee:") and v[5:].isdigit()):
        return v
    if v.startswith("best:"):
        _metric(v[5:], key, spec, v)
        return v
    raise _fail(key, f"unknown pick rule {v!r}; use 'knee', 'knee:k', 'best:<metric>' or a member index")


def _metric(name: str, key: str, spec: ProblemSpec, what: str) -> str:
    if name not in spec.metric_names:
        same = [m for m in spec.metric_names if m.lower() == name.lower()]  # "best:MSE" (lab rehearsal)
        hint = f"; did you mean {same[0]!r}?" if same else ""
        raise _fail(key, f"{what!r}: problem {spec.name!r} reports no metric {name!r}{hint}; known: "
                    f"{', '.join(spec.metric_names)}")
    return name


def _where(v: dict[str, Any], key: str, spec: ProblemSpec) -> tuple[Constraint, ...]:
    """``{I_max = 1.0, S_min = 0.5}`` -> limits on the problem's metrics."""
    out = []
    for k, x in v.items():
        where = f"{key}.{k}"
        if not (len(k) > 4 and k[-4:] in ("_max", "_min")):
            raise _fail(where, "a limit is '<metric>_max' or '<metric>_min'")
        name = _metric(k[:-4], where, spec, k)
        bound = decode(x, float, where)
        out.append(Constraint(name, upper=bound) if k.endswith("_max") else Constraint(name, lower=bound))
    return tuple(out)


Limit = NonNeg | str | list[NonNeg | str]


def _option_type(name: str, default: Any) -> Any:
    if name in LIMIT_METRICS:
        return Limit if default is None or isinstance(default, float) else (float | str | list[float | str])
    if isinstance(default, bool):
        return bool
    if isinstance(default, int):
        return PosInt
    if isinstance(default, float):
        return NonNeg if name.endswith(("_max", "_tol")) else float
    return str


def _options(problem: str, given: dict[str, Any], shared: dict[str, Any], key: str) -> dict[str, Any]:
    """Problem options: the shared ones the factory takes, then the stage's own (typed from the factory)."""
    problem_registry.problem_names()  # load the providers
    params = inspect.signature(problem_registry._FACTORIES[problem]).parameters
    struct = _options_struct(f"{problem}_options", [(k, _option_type(k, p.default)) for k, p in params.items()])
    out = {k: v for k, v in shared.items() if k in params}
    for k, v in _given(struct, given, key).items():
        if k in LIMIT_METRICS and isinstance(v, str | list):
            items = v if isinstance(v, list) else [v]
            if not items:
                raise _fail(f"{key}.{k}", "an empty list of limits")
            for j, item in enumerate(items):
                w = f"{key}.{k}[{j}]" if isinstance(v, list) else f"{key}.{k}"
                if isinstance(item, str):
                    try:
                        parse_relative(item)
                    except ValueError as e:
                        raise _fail(w, str(e)) from None
                elif item < 0:
                    raise _fail(w, f"must be >= 0, got {item!r}")
        out[k] = v
    return out


def _stage(i: int, t: Stage, shared: dict[str, Any], algorithm: AlgorithmSpec, mech: Mechanism,
           names: set[str]) -> StageConfig:
    key = f"stages[{i}]"
    if t.name in names:
        raise _fail(f"{key}.name", f"duplicate stage name {t.name!r}")
    known = problem_registry.problem_names()
    prob = t.problem or t.name
    if prob not in known:
        raise _fail(f"{key}.problem", f"unknown problem {prob!r}; known: {', '.join(known)}")
    options = _options(prob, t.options, shared, f"{key}.options")
    # Build once with placeholder limits to learn the objectives and to check the options.
    try:
        spec = make_problem(prob, **placeholder(options))
    except ValueError as e:
        raise _fail(f"{key}.options", str(e)) from None
    try:  # the RTCLM problems on another mechanism; a placement on one that cannot follow a similarity transform
        spec.check_fits(mech)
    except ValueError as e:
        raise _fail(f"{key}.problem", str(e)) from None
    s, d = _box(t.box, f"{key}.box")
    if isinstance(t.box, str):  # the paper's subtask steps (20, 10, 5 mm) follow the leg's size; a typed d is kept
        d *= spec.scale
    pick = _pick(t.pick, f"{key}.pick", spec)
    pick_where = _where(t.pick_where, f"{key}.pick_where", spec) if t.pick_where is not None else ()
    stop = None
    if t.stop_below is not None:
        if len(t.stop_below) != spec.n_obj:
            raise _fail(f"{key}.stop_below", f"expected {spec.n_obj} numbers (one per objective: "
                        f"{', '.join(spec.objectives)})")
        stop = tuple(t.stop_below)
    for j, n in enumerate(t.fixed):
        if n not in mech.param_names:
            raise _fail(f"{key}.fixed[{j}]", f"{mech.name} has no parameter {n!r}")
    if set(t.fixed) >= set(mech.param_names):
        raise _fail(f"{key}.fixed", f"every parameter of {mech.name} is fixed: leave at least one free to search")
    alg = _algorithm(t.algorithm, f"{key}.algorithm", algorithm) if t.algorithm is not None else algorithm
    try:  # what only the algorithm itself refuses (a population below CMOEMT's 10, a bad variant): before any run
        built = make_algorithm(alg, spec.n_obj, 0)
    except ValueError as e:
        raise _fail(f"{key}.algorithm" if t.algorithm is not None else "algorithm",
                    str(e) if t.algorithm is not None else f"{e} (in stage {t.name!r})") from None
    kept = getattr(built, "kept_size", None)  # CMOEMT, MOEA/D-CMT: one member per weight
    size = kept(spec.n_obj) if callable(kept) else getattr(built, "pop_size", None)
    if isinstance(pick, int) and isinstance(size, int) and pick >= size:  # else found only after the stage ran
        raise _fail(f"{key}.pick", f"member {pick} does not exist: the stage keeps {size} members (0..{size - 1})")
    return StageConfig(t.name, prob, s, d, t.n_gen, pick, alg, options, stop, tuple(t.fixed), t.seed_start,
                       pick_where, max_evals=t.max_evals)


def _starts(stages: list[StageConfig], raw: list[Stage]) -> list[StageConfig]:
    """Stages with their ``starts`` tables checked (they name later stages, so this runs last)."""
    names = [s.name for s in stages]
    out = list(stages)
    taken = -1  # last stage of the previous block: blocks may not overlap
    for i, t in enumerate(raw):
        v = t.starts
        if v is None:
            continue
        key = f"stages[{i}].starts"
        if i <= taken:
            raise _fail(key, f"stage {names[i]!r} is already inside the multi-start block of an earlier stage")
        until = v.until if v.until is not None else names[i]
        if until not in names[i:]:
            raise _fail(f"{key}.until", f"{until!r} is not this stage or a later one; "
                        f"stages from here: {', '.join(names[i:])}")
        last = names.index(until, i)
        spec = stages[last].problem_spec()
        if not v.select.startswith("best:"):
            raise _fail(f"{key}.select", f"{v.select!r}: use 'best:<metric>'")
        _metric(v.select[5:], f"{key}.select", spec, v.select)
        where = _where(v.where, f"{key}.where", spec) if v.where is not None else ()
        screen = _screen(v.screen, f"{key}.screen", stages, i, last, v.n) if v.screen is not None else None
        out[i] = replace(stages[i], starts=Starts(v.n, until, v.select, where, screen))
        taken = last
    return out


def _screen(t: Screen_, key: str, stages: list[StageConfig], first: int, last: int, n: int) -> Screen:
    names = [s.name for s in stages]
    if t.after not in names[first:last]:
        raise _fail(f"{key}.after", f"{t.after!r} is not a stage of the block before its last one; "
                    f"choose from {', '.join(names[first:last]) or '(none: the block has one stage)'}")
    if t.keep > n:
        raise _fail(f"{key}.keep", f"keeps {t.keep} of only {n} chains")
    if not t.by.startswith("best:"):
        raise _fail(f"{key}.by", f"{t.by!r}: use 'best:<metric>'")
    spec = stages[names.index(t.after, first)].problem_spec()
    _metric(t.by[5:], f"{key}.by", spec, t.by)
    where = _where(t.where, f"{key}.where", spec) if t.where is not None else ()
    return Screen(t.after, t.keep, t.by, where)


def parse_config(data: Mapping[str, Any], base: str | Path = ".", path: str | None = None) -> DesignConfig:
    """Validate a configuration given as a dict (the parsed TOML).

    Args:
        data: the configuration.
        base: directory that relative file names (``target.curve``) are relative to.
        path: the file it came from (recorded).

    Raises:
        ValueError: the first invalid entry, named by its key.
    """
    if not isinstance(data, Mapping):
        raise _fail("file", f"expected a table, got {kind(data)}")
    f = decode(dict(data), ConfigFile)
    mech, preset = _mechanism(f)
    mech = _bounds(mech, f.bounds)
    if f.n_samples % 2:
        raise _fail("n_samples", f"must be even (t + T/2 must fall on a sample), got {f.n_samples}")
    shared: dict[str, Any] = {"n_samples": f.n_samples, "backend": f.backend}
    k = 1.0  # the leg's size against the paper's (core.optimize.scale); the RTCLM's targets are heights
    if f.target is not None or mech.derive is None:
        shared["target"] = _target(f.target or Target(), Path(base))
        if mech.derive is None:
            k = target_scale(shared["target"], f.n_samples)
    output = _output(f.output, preset, mech, k)
    lo, hi = sized_bounds(mech, k)
    center = preset.params[0] if preset is not None else 0.5 * (lo + hi)
    start = Design(mech, center[None], output)
    if f.rtclm is not None:
        if mech.derive is None:  # it was silently ignored: the run optimized the shape target instead
            raise _fail("rtclm", f"the h6/h4 targets are for the reconfigurable leg (mechanism rtclm), not "
                        f"{mech.name}")
        if f.rtclm.h6 is not None:
            shared["h6_target"] = f.rtclm.h6
        if f.rtclm.h4 is not None:
            shared["h4_target"] = f.rtclm.h4
    algorithm = _algorithm(f.algorithm, "algorithm", None)
    stages: list[StageConfig] = []
    if f.method in ("hierarchical", "single_level"):
        raw = f.stages
        if raw is None and f.method == "single_level":
            raw = [Stage("single_level", problem="single_level", box="global", pick="best:f1")]
        if not raw:
            raise _fail("stages", "missing; a design needs at least one [[stages]] table")
        names: set[str] = set()
        for i, t in enumerate(raw):
            stages.append(_stage(i, t, shared, algorithm, mech, names))
            names.add(stages[-1].name)
        stages = _starts(stages, raw)
    elif f.stages is not None:
        raise _fail("stages", f"not used by method = {f.method!r}")
    baseline = BaselineSettings(target=shared.get("target", "cycloid"), n_samples=f.n_samples, backend=f.backend)
    if f.baseline is not None:
        if f.method not in DP_METHODS:
            raise _fail("baseline", f"only for the DP methods ({', '.join(DP_METHODS)})")
        given = {k: getattr(f.baseline, k) for k in f.baseline.__struct_fields__ if getattr(f.baseline, k) is not None}
        baseline = replace(baseline, **given)
        if f.n_samples % baseline.n_points:
            raise _fail("baseline.n_points", f"must divide n_samples ({f.n_samples}), got {baseline.n_points}")
    workers = 0 if f.workers == "auto" else int(f.workers)
    return DesignConfig(f.name, f.method, mech, start, f.seed, tuple(stages), baseline, dict(data), path, workers)


__all__ = ["ConfigFile", "load_config", "parse_config"]
