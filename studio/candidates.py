"""What the Pick and History panels list, as plain data: candidates of a stage result, their labels,
metric comparisons and the lineage summary. Pure (no viser).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from core.kinematics.design import Design
from core.optimize.result import StageResult

# Metrics compared in the Pick panel after the stage's own objectives and constrained metrics.
REPORT_METRICS = ("mse", "h_s", "S", "I", "width", "y_min", "h4", "h6")


@dataclass(frozen=True)
class Candidate:
    """One entry of the Pick list.

    Attributes:
        member: row of the stage result.
        kind: ``knee``, ``best`` or ``front``.
        tag: short name (``K1``, ``best f1``, ``front 3``).
        label: the dropdown text (tag, member, objective values); unique within a list.
    """

    member: int
    kind: str
    tag: str
    label: str


def _fmt(v: float, exact: bool = False) -> str:
    """A candidate's value in a few characters: below 1e-4 (0.1 um, um/s or ppm of a percent for the studio's metrics)
    it is nothing a designer can build or measure, and "I 4.08e-07" read as noise on a slide. ``exact``: a value
    whose every nonzero digit matters (a violation: any is infeasible, "≈0" read as feasible)."""
    if not math.isfinite(v):
        return "-"
    a = abs(v)
    if 0.0 < a < 1e-4 and not exact:
        return "≈0"
    if a != 0.0 and (a < 1e-3 or a >= 1e5):
        return f"{v:.3g}"
    return f"{v:.3g}" if a < 1.0 else f"{v:.4g}"


def _fmt_pair(a: float, b: float, exact: bool = False) -> tuple[str, str]:
    """Two values of one Pick-table row with the same decimals, so their digits line up ("0.0190" beside "0.0162",
    not "0.019"): 4 significant digits of the larger from 1 on, 3 below; very large or small rows, violations and
    values under 1e-4 keep ``_fmt``'s own form."""
    finite = [abs(v) for v in (a, b) if math.isfinite(v) and v != 0.0]
    m = max(finite, default=0.0)
    if exact or m == 0.0 or m < 1e-3 or m >= 1e5:
        return _fmt(a, exact), _fmt(b, exact)
    d = max(0, (4 if m >= 1.0 else 3) - 1 - math.floor(math.log10(m)))

    def one(v: float) -> str:
        if not math.isfinite(v) or 0.0 < abs(v) < 1e-4:
            return _fmt(v)
        t = f"{v:.{d}f}"
        return t[1:] if t.startswith("-") and float(t) == 0.0 else t  # no "-0.00"

    return one(a), one(b)


def objective_text(result: StageResult, i: int) -> str:
    return ", ".join(f"{o} {_fmt(float(result.F[i, k]))}" for k, o in enumerate(result.objectives))


def front_order(result: StageResult) -> tuple[int, ...]:
    """The feasible front's distinct members, sorted by the first objective (then the others)."""
    front = list(dict.fromkeys(result.shortlist.front))
    if not front:
        return ()
    F = result.F[front]
    order = np.lexsort(tuple(F[:, k] for k in range(F.shape[1] - 1, -1, -1)))
    return tuple(front[j] for j in order)


def candidates(result: StageResult) -> tuple[Candidate, ...]:
    """Knee candidates (ranked), the best member per objective, then the whole front in order.

    With nothing feasible: the least-violation member alone (the automatic pick's fallback).
    """
    sl = result.shortlist
    out: list[Candidate] = []
    seen: set[int] = set()
    designs: set[bytes] = set()  # members with the same parameters are one design: listed once

    def add(i: int, kind: str, tag: str) -> None:
        key = np.ascontiguousarray(result.X[i]).tobytes()
        if i in seen or key in designs:
            return
        seen.add(i)
        designs.add(key)
        out.append(Candidate(i, kind, tag, f"{tag} · #{i} · {objective_text(result, i)}"))

    for j, i in enumerate(sl.knees):
        add(i, "knee", f"K{j + 1}")
    for o, i in zip(result.objectives, sl.best, strict=False):
        add(i, "best", f"best {o}")
    for j, i in enumerate(front_order(result)):
        add(i, "front", f"front {j + 1}")
    if not out and sl.fallback is not None:
        add(sl.fallback, "fallback", "least violation")
    return tuple(out)


# Report metrics that shape problems list as an objective under another name ("f1 = MSE (mm)"), when they hold
# the same numbers: "MSE (mm)" below "f1 = MSE (mm)" read one number twice.
ALIASES = {"mse": "f1"}


def _alias(result: StageResult, metric: str, names: list[str]) -> bool:
    other = ALIASES.get(metric)
    return other in names and other in result.metrics and np.array_equal(result.metrics[metric],
                                                                          result.metrics[other], equal_nan=True)


def compared_metrics(result: StageResult, constraint_metrics: tuple[str, ...] = ()) -> tuple[str, ...]:
    """Metric names the Pick panel compares: objectives, constrained metrics, then the paper's report metrics."""
    names = list(result.objectives) + [m for m in constraint_metrics if m != "violation"]
    names += [m for m in REPORT_METRICS if m in result.metrics and not _alias(result, m, names)]
    names.append("violation")
    return tuple(n for n in dict.fromkeys(names) if n in result.metrics)


def comparison(result: StageResult, member: int, start: Mapping[str, float], names: tuple[str, ...],
               labels: Mapping[str, str]) -> list[tuple[str, str, str]]:
    """Rows ``(label, start value, candidate value)`` for the compared metrics."""
    rows = []
    for n in names:
        cand = float(result.metrics[n][member])
        exact = n in ("violation", "violation_mm")
        rows.append((labels.get(n, n), *_fmt_pair(float(start.get(n, math.nan)), cand, exact)))
    return rows


def start_design(result: StageResult) -> Design:
    """The design a stage started from (its box centre)."""
    return Design(result.mechanism, np.asarray(result.box.center)[None, :], result.output)


@dataclass(frozen=True)
class HistoryRow:
    """One stage of the lineage: name, status, pick and its objective values."""

    name: str
    title: str
    status: str
    generations: str
    feasible: int
    front: int
    pick: str
    values: str
    parent: str


def history_rows(results: list[StageResult | None], titles: Mapping[str, str], names: list[str],
                 status: Mapping[str, str]) -> list[HistoryRow]:
    """The lineage table: every stage of the pipeline, run or not."""
    rows = []
    for name, r in zip(names, results, strict=True):
        title = titles.get(name, name)
        if r is None:
            rows.append(HistoryRow(name, title, "not run", "", 0, 0, "", "", ""))
            continue
        i = r.picked
        rows.append(HistoryRow(
            name, title, status.get(name, r.status), f"{r.generation}/{r.n_gen}", int(r.feasible.sum()),
            len(set(r.front)), "" if i is None else f"#{i}", "" if i is None else objective_text(r, i),
            "" if r.parent_pick is None else f"from #{r.parent_pick}",
        ))
    return rows
