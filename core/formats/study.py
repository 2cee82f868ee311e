"""The study file (TOML): which cases, algorithms and seeds, decoded through msgspec Structs.

Format (docs/studies.md)::

    name = "smoke"
    seeds = "1..3"                 # or a list [1, 2, 5]
    reference = "nsga2"            # the algorithm the others are tested against (default: the first)

    [[algorithms]]
    name = "nsga2"                 # a registered algorithm (core.optimize.algorithms)
    label = "NSGA-II"              # optional
    pop_size = 100                 # optional; the case config's otherwise
    options = {}

    [[cases]]
    name = "subtask2"
    config = "../configs/stephenson1_cycloid.toml"   # relative to the study file
    stages = ["subtask2"]          # the config's stages to run, in order (default: all)
    start = "stephenson1/X1"       # preset the first stage starts from (default: the config's start)
    budget = 4000                  # function evaluations per stage
    best = "mse"                   # pick metric that ranks runs for "best design" (default: first present)

Every error is a ``ValueError`` of one line that starts with the key path (``cases[1].budget: ...``).
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any

import msgspec

from core.formats.typed import MAX_POP, MAX_SEED, decode
from core.kinematics import presets
from core.optimize.algorithms import ALGORITHMS, unknown_algorithm

MAX_RUNS = 100_000
BEST = ("mse", "S", "I", "h_s", "h6", "h4", "dh6", "dh4", "dev")  # pick metrics a case may rank its runs by

Name = Annotated[str, msgspec.Meta(min_length=1, max_length=80, pattern=r"^[A-Za-z0-9_.\-]+$")]
Budget = Annotated[int, msgspec.Meta(ge=1, le=10**9)]
PopSize = Annotated[int, msgspec.Meta(ge=4, le=MAX_POP)]


class AlgorithmEntry(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    name: Name
    label: str = ""
    pop_size: PopSize | None = None
    options: dict[str, Any] = {}

    @property
    def title(self) -> str:
        return self.label or self.name


class CaseEntry(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    name: Name
    config: Annotated[str, msgspec.Meta(min_length=1)]
    budget: Budget
    stages: list[Name] = []
    start: str = ""
    best: str = ""


class StudyFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A study: algorithms x cases (design configs and their stages) x seeds, with a budget (docs/studies.md)."""

    algorithms: Annotated[list[AlgorithmEntry], msgspec.Meta(min_length=1)]
    cases: Annotated[list[CaseEntry], msgspec.Meta(min_length=1)]
    seeds: str | list[Annotated[int, msgspec.Meta(ge=0, le=MAX_SEED)]]
    name: str = "study"
    reference: str = ""


class Study(msgspec.Struct, frozen=True):
    """A decoded study: its file's entries with seeds expanded and config paths made absolute."""

    name: str
    algorithms: tuple[AlgorithmEntry, ...]
    cases: tuple[CaseEntry, ...]
    seeds: tuple[int, ...]
    reference: str
    path: str = ""

    def cells(self) -> list[dict[str, Any]]:
        """Every (algorithm, case, seed) as a self-contained task description (plain JSON data), with the
        ``settings`` its result depends on (see :func:`cell_settings`)."""
        out = []
        for c in self.cases:
            config = tomllib.loads(Path(c.config).read_text(encoding="utf-8-sig"))
            for a in self.algorithms:
                settings = cell_settings(a, c, config)
                out += [{"key": cell_key(a.name, c.name, s), "algorithm": msgspec.to_builtins(a),
                         "case": msgspec.to_builtins(c), "seed": s, "settings": settings} for s in self.seeds]
        return out


def cell_settings(a: AlgorithmEntry, c: CaseEntry, config: dict[str, Any]) -> str:
    """What a cell's result depends on besides its key, as canonical JSON: the algorithm (name, population,
    options), the case's budget, stages and start, and its config file's contents (parsed: comments and
    layout do not count). Labels and ``best`` only change the report."""
    data = {"algorithm": {"name": a.name, "pop_size": a.pop_size, "options": a.options},
            "case": {"budget": c.budget, "stages": c.stages, "start": c.start, "config": config}}
    return json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)


# Stage keys a cell replaces or drops (core.study.cell.case_config): the budget sets n_gen and max_evals, the
# cell's algorithm replaces a stage's own, and a study runs no multi-start block.
CELL_DROPS = ("starts", "algorithm", "n_gen", "max_evals")


def case_stages(stages: list[Any], names: list[str]) -> list[dict[str, Any]]:
    """The config's stages a cell runs, in the case's order (all of them if it names none), without the keys in
    ``CELL_DROPS``; a name the config lacks is skipped (the study's loader refuses it first)."""
    tables = [s for s in stages if isinstance(s, dict)]
    if names:
        by_name = {s.get("name"): s for s in tables}
        tables = [by_name[n] for n in names if n in by_name]
    return [{k: v for k, v in s.items() if k not in CELL_DROPS} for s in tables]


def effective_settings(settings: str, narrow: bool = True) -> str:
    """:func:`cell_settings` reduced to what the cell's run uses, as ``core.study.cell.case_config`` runs it: a
    population not given is the config's (else 100); of the config, only the case's stages without the keys the
    cell replaces (``CELL_DROPS``), and neither its seed, its workers, its algorithm (the cell's replaces it) nor
    its preset when the case starts elsewhere. So two cells that run alike compare equal: a population written out
    equal to the config's, and an edit of a stage the case does not run (session 24's multi-start block in the
    Stephenson-I config), were refused as a change, and the report left those cells out. ``narrow=False``: the
    settings as compared before session 24 (the population filled in only), whose digests older studies keep."""
    data = json.loads(settings)
    alg = data.get("algorithm") if isinstance(data, dict) else None
    case = data.get("case") if isinstance(data, dict) else None
    config = case.get("config") if isinstance(case, dict) else None
    if isinstance(alg, dict) and alg.get("pop_size") is None and isinstance(case, dict):
        base = config.get("algorithm") if isinstance(config, dict) else None
        alg["pop_size"] = base.get("pop_size", 100) if isinstance(base, dict) else 100
    if narrow and isinstance(case, dict) and isinstance(config, dict):
        config = dict(config)
        names = case.get("stages")
        config["stages"] = case_stages(list(config.get("stages") or []), list(names) if isinstance(names, list) else [])
        for k in ("seed", "workers", "algorithm", *(("preset",) if case.get("start") else ())):
            config.pop(k, None)
        case["config"] = config
    return json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)


def settings_change(old: str, new: str) -> str:
    """The first difference between two :func:`cell_settings`, e.g. ``case.budget 600 -> 800``."""

    def first(a: Any, b: Any, path: str) -> str:
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b)):
                if a.get(k) != b.get(k):
                    return first(a.get(k), b.get(k), f"{path}.{k}" if path else str(k))
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                if x != y:
                    return first(x, y, f"{path}[{i}]")
        show = [json.dumps(v, sort_keys=True) if v is not None else "(none)" for v in (a, b)]
        show = [v if len(v) <= 60 else v[:57] + "..." for v in show]
        return f"{path} {show[0]} -> {show[1]}"

    return first(json.loads(old), json.loads(new), "")


def cell_key(algorithm: str, case: str, seed: int) -> str:
    return f"{case}/{algorithm}/{seed}"


def parse_seeds(v: str | list[int], key: str = "seeds") -> tuple[int, ...]:
    """``"1..20"`` (inclusive), ``"3"`` or a list of ints -> the seeds, each in [0, 2**32 - 1], no repeats."""
    if isinstance(v, list):
        seeds = tuple(v)
    else:
        m = re.fullmatch(r"\s*(\d+)\s*(?:\.\.\s*(\d+)\s*)?", v)
        if m is None:
            raise ValueError(f"{key}: expected \"a..b\", a seed or a list of seeds, got {v!r}")
        lo = int(m.group(1))
        hi = int(m.group(2)) if m.group(2) is not None else lo
        if hi > MAX_SEED:
            raise ValueError(f"{key}: seeds must be <= {MAX_SEED}, got {hi}")
        if hi < lo:
            raise ValueError(f"{key}: empty seed range {v!r}")
        if hi - lo + 1 > MAX_RUNS:
            raise ValueError(f"{key}: at most {MAX_RUNS} seeds, got {hi - lo + 1}")
        seeds = tuple(range(lo, hi + 1))
    if not seeds:
        raise ValueError(f"{key}: no seeds")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"{key}: a seed is listed twice")
    return seeds


def _unique(names: list[str], key: str) -> None:
    seen: set[str] = set()
    for i, n in enumerate(names):
        if n in seen:
            raise ValueError(f"{key}[{i}].name: {n!r} is listed twice")
        seen.add(n)


def _check_case(i: int, case: CaseEntry, config: Path) -> None:
    """The case's stages exist in its config and its start preset exists (read before any work is sent out)."""
    try:
        data = tomllib.loads(config.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise ValueError(f"cases[{i}].config: {config} is not a valid TOML file ({str(e).splitlines()[0]})") from None
    names = [str(s.get("name", "")) for s in data.get("stages", []) if isinstance(s, dict)]
    for j, s in enumerate(case.stages):
        if s not in names:
            raise ValueError(f"cases[{i}].stages[{j}]: no stage {s!r} in {config.name} (stages: {', '.join(names)})")
    if case.start:
        try:
            presets.get(case.start)
        except (KeyError, ValueError):
            raise ValueError(f"cases[{i}].start: unknown preset {case.start!r} (see 'clm presets')") from None
    if case.best and case.best not in BEST:
        raise ValueError(f"cases[{i}].best: unknown pick metric {case.best!r}; one of {', '.join(BEST)}")


def parse_study(data: dict[str, Any], base: str | Path = ".", path: str = "") -> Study:
    """Check a study given as a dict (the parsed TOML) and resolve its seeds and config paths."""
    if "stages" in data and "cases" not in data:  # read "mechanism: unknown key; known: algorithms, cases, ..." (QA)
        raise ValueError("this is a design configuration ([[stages]]), not a study: run it with clm design, or name it "
                         "in a study's [[cases]] config")
    f = decode(data, StudyFile)
    seeds = parse_seeds(f.seeds)
    _unique([a.name for a in f.algorithms], "algorithms")
    _unique([c.name for c in f.cases], "cases")
    for i, a in enumerate(f.algorithms):
        if a.name not in ALGORITHMS:
            raise ValueError(f"algorithms[{i}].name: {unknown_algorithm(a.name)}")
    cases = []
    for i, c in enumerate(f.cases):
        cfg = (Path(base) / c.config).resolve()
        if not cfg.is_file():
            raise ValueError(f"cases[{i}].config: no such config file {str(cfg)!r}")
        _check_case(i, c, cfg)
        cases.append(msgspec.structs.replace(c, config=str(cfg)))
    names = [a.name for a in f.algorithms]
    reference = f.reference or names[0]
    if reference not in names:
        raise ValueError(f"reference: {reference!r} is not one of the study's algorithms ({', '.join(names)})")
    n_runs = len(seeds) * len(names) * len(cases)
    if n_runs > MAX_RUNS:
        raise ValueError(f"study: {n_runs} runs is more than the {MAX_RUNS} a study may hold")
    return Study(f.name, tuple(f.algorithms), tuple(cases), seeds, reference, path)


def load_study(path: str | Path) -> Study:
    """Read and check a study file; ValueError (one line) if it is missing or malformed."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such study file")
    if p.stat().st_size > 1_000_000:
        raise ValueError(f"{p}: a study file is at most 1 MB")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise ValueError(f"{p}: not a valid TOML file ({str(e).splitlines()[0]})") from None
    return parse_study(data, p.parent, str(p.resolve()))
