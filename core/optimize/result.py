"""The result of one stage, its pick, and a lossless JSON form (never pickle).

JSON floats are written with Python's shortest round-trip repr, so every finite float64
(including -0.0) loads back bit for bit; NaN and ±inf, which JSON lacks, are written as the
strings ``"NaN"``, ``"Infinity"``, ``"-Infinity"`` and decoded back. Arrays are nested lists
whose column count is known from the names stored next to them (so an empty population keeps
its shape).
"""

from __future__ import annotations

import json
import math
import platform
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.design import Design
from core.kinematics.mechanisms import get as get_mechanism
from core.kinematics.model import Mechanism, OutputStage
from core.optimize.box import Box
from core.optimize.decision import Shortlist

F64 = NDArray[np.float64]
FORMAT = "clm-stage-result"
FORMAT_VERSION = 1
STATUSES = ("not started", "running", "complete", "stopped", "cancelled")
# "stopped": the stage's early-stop rule fired; "cancelled": stopped from outside (partial result).

PickRule = str | int


# ---------------------------------------------------------------------------------------
# Lossless float encoding.

_NONFINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def encode(obj: Any) -> Any:
    """Plain JSON-able data with non-finite floats as strings (recursively; numpy values too)."""
    if isinstance(obj, np.ndarray):
        return encode(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        if math.isnan(f):
            return "NaN"
        if math.isinf(f):
            return "Infinity" if f > 0 else "-Infinity"
        return f
    if isinstance(obj, Mapping):
        return {str(k): encode(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [encode(v) for v in obj]
    return obj


def decode_float(v: Any) -> float:
    """A float written by :func:`encode`."""
    if isinstance(v, str):
        if v not in _NONFINITE:
            raise ValueError(f"not a number: {v!r}")
        return _NONFINITE[v]
    return float(v)


def decode_array(v: Any, n_cols: int | None = None) -> F64:
    """Nested lists written by :func:`encode` -> float64 array; ``(0, n_cols)`` for an empty 2-D list."""

    def conv(x: Any) -> Any:
        return [conv(y) for y in x] if isinstance(x, list) else decode_float(x)

    a = np.array(conv(v), dtype=np.float64)
    if n_cols is not None:
        a = a.reshape(-1, n_cols)
    return a


def dumps(obj: Any, indent: int | None = 1) -> str:
    """Strict JSON (no NaN literals) of :func:`encode` (obj)."""
    return json.dumps(encode(obj), indent=indent, allow_nan=False)


def versions() -> dict[str, str]:
    """Versions of the software that produced a result."""
    import pymoo

    try:
        from importlib.metadata import version

        clm = version("clm-studio")
    except Exception:  # not installed (run from the source tree)
        clm = "source"
    return {"clm-studio": clm, "pymoo": pymoo.__version__, "numpy": np.__version__,
            "python": platform.python_version()}


# ---------------------------------------------------------------------------------------


def _ro(a: Any, dtype: Any = np.float64) -> NDArray[Any]:
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class StageResult:
    """One stage's final (or partial) population and decision data.

    Attributes:
        name: stage name (``subtask1``).
        index: position of the stage in its pipeline (0 for a lone stage).
        mechanism, output: the designs' topology and output stage.
        objectives: objective (metric) names, the columns of F.
        constraints: constraint names, the columns of G.
        X: ``(pop, n_params)`` parameter vectors of the final population (mm, rad).
        F: ``(pop, n_obj)`` objectives as the optimizer saw them (+inf where undefined).
        G: ``(pop, n_con)`` constraint values (<= 0 satisfied).
        cv: ``(pop,)`` total violation, sum of max(0, G).
        metrics: ``{name: (pop,)}`` every metric the problem's evaluate returns.
        shortlist: knee candidates, best per objective, front, fallback (indices into X).
        box: the search box; ``box.center`` is the design the stage started from.
        settings: the stage spec as a dict (problem, algorithm, box rule, n_gen, ...).
        seed: the stage's seed.
        status: one of ``STATUSES``.
        generation: generations completed; ``n_gen`` planned.
        n_evals: designs evaluated.
        timings: ``{"total": s, "generations": [s, ...], "metrics": s}`` (compute time).
        versions: software versions.
        picked: the member chosen for the next stage, if any.
        parent_pick: the member of the previous stage's result this stage started from
            (None for a first stage or a hand-made start).
        trace: the algorithm's per-generation log (array-based algorithms: evaluations, feasible ratios,
            and what drives it, such as IMTCMO's epsilon or MOEA/D-CMT's task probabilities).
    """

    name: str
    index: int
    mechanism: Mechanism
    output: OutputStage
    objectives: tuple[str, ...]
    constraints: tuple[str, ...]
    X: F64
    F: F64
    G: F64
    cv: F64
    metrics: Mapping[str, F64]
    shortlist: Shortlist
    box: Box
    settings: Mapping[str, Any]
    seed: int
    status: str
    generation: int
    n_gen: int
    n_evals: int
    timings: Mapping[str, Any]
    versions: Mapping[str, str] = field(default_factory=versions)
    picked: int | None = None
    parent_pick: int | None = None
    trace: tuple[Mapping[str, float], ...] = ()

    def __post_init__(self) -> None:
        n = self.mechanism.n_params
        object.__setattr__(self, "X", _ro(self.X).reshape(-1, n))
        object.__setattr__(self, "F", _ro(self.F).reshape(-1, len(self.objectives)))
        object.__setattr__(self, "G", _ro(self.G).reshape(-1, len(self.constraints)))
        object.__setattr__(self, "cv", _ro(self.cv).reshape(-1))
        object.__setattr__(self, "metrics", {k: _ro(v).reshape(-1) for k, v in self.metrics.items()})
        pop = self.X.shape[0]
        if not (self.F.shape[0] == self.G.shape[0] == self.cv.shape[0] == pop):
            raise ValueError("X, F, G and cv must have one row per member")
        if any(v.shape != (pop,) for v in self.metrics.values()):
            raise ValueError(f"every metric must have shape ({pop},)")
        if self.status not in STATUSES:
            raise ValueError(f"unknown status {self.status!r}; known: {', '.join(STATUSES)}")
        if self.picked is not None and not 0 <= self.picked < pop:
            raise ValueError(f"picked member {self.picked} out of range (pop = {pop})")

    @property
    def pop(self) -> int:
        return int(self.X.shape[0])

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """``(pop,)`` members satisfying every constraint with finite objectives."""
        return (self.cv <= 0.0) & np.isfinite(self.F).all(axis=1)

    @property
    def front(self) -> tuple[int, ...]:
        """The feasible non-dominated members."""
        return self.shortlist.front

    def unmet(self, i: int, labels: Mapping[str, str] | None = None) -> list[str]:
        """Member i's unmet constraints in words, with its values: ``h_s 8.72 > 6.5``, ``does not assemble``; a
        metric by its ``labels`` name when it has one (the problem's: ``Eq. 30 order t1→t2→t5→t4, auxiliary (rad)
        0.00721 > 0``, where "order_4" named it as no other place did)."""
        out = []
        for j, name in enumerate(self.constraints):
            if not self.G[i, j] > 0:
                continue
            op = "<=" if "<=" in name else ">=" if ">=" in name else None
            if op is None:
                out.append(f"{name} violated by {self.G[i, j]:.3g}")
                continue
            metric, bound = name.split(op, 1)
            if metric in ("violation", "violation_mm"):
                out.append("does not assemble")
                continue
            v = self.metrics.get(metric)
            shown = f"{float(v[i]):.3g}" if v is not None else "?"
            out.append(f"{(labels or {}).get(metric, metric)} {shown} {'>' if op == '<=' else '<'} {float(bound):.3g}")
        return out

    def named(self, i: int) -> dict[str, float]:
        """Member i's parameters by name."""
        return {n: float(v) for n, v in zip(self.mechanism.param_names, self.X[i], strict=True)}

    def choose(self, rule: PickRule = "knee") -> int:
        """Resolve a pick rule to a member index.

        Rules: an int (that member); ``"knee"`` (first knee candidate) or ``"knee:k"`` (k-th,
        0-based, clamped to the last); ``"best:<objective>"`` (best feasible member of that
        objective, ties by the other objectives); ``"best:<metric>"`` for any other reported
        metric (smallest value among the front's members with a finite one, else among the feasible ones; ties by
        index).
        With no feasible member every rule but an int gives the least-violation fallback.

        Raises:
            ValueError: empty population, unknown rule or metric, index out of range.
        """
        if self.pop == 0:
            raise ValueError(f"stage {self.name!r} has no population to pick from")
        if isinstance(rule, (int, np.integer)) and not isinstance(rule, bool):
            if not 0 <= int(rule) < self.pop:
                raise ValueError(f"member {rule} out of range (pop = {self.pop})")
            return int(rule)
        sl = self.shortlist
        if not isinstance(rule, str):
            raise ValueError(f"pick rule must be an int or a string, got {rule!r}")
        if rule == "knee" or rule.startswith("knee:"):
            k = int(rule.split(":", 1)[1]) if ":" in rule else 0
            if sl.knees:
                return sl.knees[min(max(k, 0), len(sl.knees) - 1)]
        elif rule.startswith("best:"):
            name = rule.split(":", 1)[1]
            if name in self.objectives:
                if sl.best:
                    return sl.best[self.objectives.index(name)]
            elif name in self.metrics:
                i = best_on_front(self.metrics[name], self.feasible, self.front, name)
                if i is not None:
                    return i
            else:
                raise ValueError(f"pick rule {rule!r}: no objective or metric {name!r}; objectives: "
                                 f"{', '.join(self.objectives)}; metrics: {', '.join(self.metrics)}")
        else:
            raise ValueError(f"unknown pick rule {rule!r}; use an index, 'knee', 'knee:k' or 'best:<objective>'")
        if sl.fallback is None:
            raise ValueError(f"stage {self.name!r} has no member to pick")
        return sl.fallback

    def pick(self, i: int | None = None) -> Design:
        """Member i (default: the recorded pick) as a one-member Design: the next stage's start."""
        if i is None:
            i = self.picked
        if i is None:
            raise ValueError(f"stage {self.name!r}: no member picked")
        return Design(self.mechanism, self.X[self.choose(int(i))], self.output)

    def with_pick(self, rule: PickRule) -> StageResult:
        """A copy with ``picked`` set by a rule (see :meth:`choose`)."""
        return replace(self, picked=self.choose(rule))

    # --- JSON -----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain data (encode with :func:`dumps`): named parameters, fronts, shortlist, pick, ..."""
        sl = self.shortlist
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "name": self.name,
            "index": self.index,
            "mechanism": self.mechanism.name,
            "output": self.output.to_dict(),
            "param_names": list(self.mechanism.param_names),
            "objectives": list(self.objectives),
            "constraints": list(self.constraints),
            "status": self.status,
            "generation": self.generation,
            "n_gen": self.n_gen,
            "n_evals": self.n_evals,
            "seed": self.seed,
            "settings": dict(self.settings),
            "timings": dict(self.timings),
            "versions": dict(self.versions),
            "box": self.box.to_dict(),
            "start": dict(zip(self.box.names, self.box.center.tolist(), strict=True)),
            "X": self.X,
            "F": self.F,
            "G": self.G,
            "cv": self.cv,
            "metrics": dict(self.metrics),
            "front": list(sl.front),
            "shortlist": {
                "method": sl.method,
                "knees": list(sl.knees),
                "scores": list(sl.scores),
                # best is () when nothing is feasible
                "best": dict(zip(self.objectives, sl.best, strict=False)),
                "fallback": sl.fallback,
                "named": {str(i): self.named(i) for i in sl.candidates},
            },
            "picked": self.picked,
            "pick": None if self.picked is None else self.named(self.picked),
            "parent_pick": self.parent_pick,
            "trace": [dict(row) for row in self.trace],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> StageResult:
        """Inverse of :meth:`to_dict` (after :func:`json.loads`); the mechanism is looked up by name."""
        if d.get("format") != FORMAT:
            raise ValueError(f"not a stage result (format {d.get('format')!r}, expected {FORMAT!r})")
        if d.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported stage result version {d.get('format_version')!r}")
        mech = get_mechanism(d["mechanism"])
        if list(d["param_names"]) != list(mech.param_names):
            raise ValueError(f"saved parameters {d['param_names']} do not match {mech.name}")
        objectives, constraints = tuple(d["objectives"]), tuple(d["constraints"])
        s = d["shortlist"]
        best = s["best"]
        out = d["output"]
        return cls(
            name=d["name"],
            index=int(d["index"]),
            mechanism=mech,
            output=OutputStage.from_dict(out),
            objectives=objectives,
            constraints=constraints,
            X=decode_array(d["X"], mech.n_params),
            F=decode_array(d["F"], len(objectives)),
            G=decode_array(d["G"], len(constraints)),
            cv=decode_array(d["cv"]).reshape(-1),
            metrics={k: decode_array(v).reshape(-1) for k, v in d["metrics"].items()},
            shortlist=Shortlist(
                knees=tuple(int(i) for i in s["knees"]),
                scores=tuple(decode_float(v) for v in s["scores"]),
                best=tuple(int(best[o]) for o in objectives if o in best),
                front=tuple(int(i) for i in d["front"]),
                fallback=None if s["fallback"] is None else int(s["fallback"]),
                method=s["method"],
            ),
            box=Box.from_dict(_decode_floats(d["box"])),
            settings=_decode_floats(d["settings"]),
            seed=int(d["seed"]),
            status=d["status"],
            generation=int(d["generation"]),
            n_gen=int(d["n_gen"]),
            n_evals=int(d["n_evals"]),
            timings=_decode_floats(d["timings"]),
            versions=dict(d["versions"]),
            picked=None if d["picked"] is None else int(d["picked"]),
            parent_pick=None if d.get("parent_pick") is None else int(d["parent_pick"]),
            trace=tuple({str(k): decode_float(v) for k, v in row.items()} for row in d.get("trace", [])),
        )

    def to_json(self, indent: int | None = 1) -> str:
        return dumps(self.to_dict(), indent)

    @classmethod
    def from_json(cls, text: str) -> StageResult:
        return cls.from_dict(json.loads(text))


# Metrics whose best value is the largest (``best:<metric>`` takes it): the worst transmission angle (90 deg
# ideal) and the crank margin. "best:transmission" picked the design nearest a dead point.
LARGER_IS_BETTER = frozenset({"transmission", "crank_margin", "transmission_6", "transmission_4"})


def best_metric(values: F64, mask: NDArray[np.bool_], name: str = "") -> int | None:
    """Index of the best finite value among ``mask`` (ties: lowest index): the smallest, or the largest for a metric
    ``name`` in ``LARGER_IS_BETTER``; None if there is none.

    Args:
        values: ``(pop,)`` one metric.
        mask: ``(pop,)`` candidate members.
        name: the metric's name.
    """
    values = -np.asarray(values) if name in LARGER_IS_BETTER else values
    ok = np.flatnonzero(mask & np.isfinite(values))
    return int(ok[np.argmin(values[ok])]) if ok.size else None


def best_on_front(values: F64, mask: NDArray[np.bool_], front: tuple[int, ...], name: str = "") -> int | None:
    """:func:`best_metric` among the members of ``mask`` on the front, else among all of ``mask``.

    A metric that is not an objective (``best:S`` after subtask 3) is chosen on the front first: the paper's X_i
    lie "on the Pareto optimal frontier", and the smallest S over the whole population was once a member another
    one beat on both objectives (h_s and I four times smaller, S 0.001 points larger).
    """
    on = np.zeros(len(mask), dtype=bool)
    on[np.asarray(front, dtype=np.intp)] = True
    i = best_metric(values, mask & on, name)
    return i if i is not None else best_metric(values, mask, name)


def _decode_floats(obj: Any) -> Any:
    """Undo :func:`encode`'s non-finite strings inside settings-like data."""
    if isinstance(obj, str) and obj in _NONFINITE:
        return _NONFINITE[obj]
    if isinstance(obj, Mapping):
        return {k: _decode_floats(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_decode_floats(v) for v in obj]
    return obj
