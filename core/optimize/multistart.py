"""Multi-start: run a block of stages several times with other seeds, keep the best chain.

A hierarchical design is one chain of local searches, and the basin the first stages land in
decides what the later ones can reach (docs/optimization.md, "Multi-start"). A multi-start
block reruns stages ``first .. last`` ``n`` times from the same parent pick: chain ``j`` runs
stage ``k`` with seed ``seed + k + SEED_STRIDE * j`` (chain 0 is the single-start run). Each
chain picks as usual; then :func:`select_chain` keeps the chain whose pick at stage ``last``
is best by ``select`` among the chains whose pick meets ``where``, and the stages after
``last`` continue from it. An optional :class:`Screen` drops all but the ``keep`` best chains
after an earlier stage of the block (successive halving in one step: cheap stages for every
chain, the expensive rest for the promising ones).

:class:`Starts` is the configuration (a stage's ``starts`` table); :class:`MultiStart` the record
of a run (every chain's picks, the winner), saved in ``clm design``'s result.json.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from core.optimize.problem import Constraint
from core.optimize.result import LARGER_IS_BETTER, decode_float

# Seed offset between chains: far enough apart that chain j's stages never reuse chain 0's seeds.
SEED_STRIDE = 1000


def where_name(c: Constraint) -> str:
    """A limit as written in a configuration: ``I_max`` or ``S_min``."""
    return f"{c.metric}_max" if c.upper is not None else f"{c.metric}_min"


def where_to_dict(where: Sequence[Constraint]) -> dict[str, float]:
    return {where_name(c): float(c.upper if c.upper is not None else c.lower) for c in where}  # type: ignore[arg-type]


def where_from_dict(d: Mapping[str, Any]) -> tuple[Constraint, ...]:
    """Inverse of :func:`where_to_dict`.

    Raises:
        ValueError: a key that does not end in ``_max`` or ``_min``.
    """
    out = []
    for k, v in d.items():
        if k.endswith("_max") and len(k) > 4:
            out.append(Constraint(k[:-4], upper=float(v)))
        elif k.endswith("_min") and len(k) > 4:
            out.append(Constraint(k[:-4], lower=float(v)))
        else:
            raise ValueError(f"{k!r}: a limit is '<metric>_max' or '<metric>_min'")
    return tuple(out)


def shortfalls(metrics: Mapping[str, float], where: Sequence[Constraint]) -> tuple[float, ...]:
    """How far one design misses each limit, relative to the limit (0 where it meets it).

    A missing or NaN metric misses its limit by +inf.
    """
    out = []
    for c in where:
        g = float(c.value(float(metrics.get(c.metric, math.nan))))  # type: ignore[arg-type]
        bound = float(c.upper if c.upper is not None else c.lower)  # type: ignore[arg-type]
        out.append(math.inf if not math.isfinite(g) else max(0.0, g) / max(abs(bound), 1e-12))
    return tuple(out)


def rank_chains(picks: Sequence[Mapping[str, float]], feasible: Sequence[bool], select: str,
                where: Sequence[Constraint] = ()) -> list[int]:
    """Chain indices best first, by the ranking of :func:`select_chain`."""
    if not select.startswith("best:"):
        raise ValueError(f"select rule {select!r}: use 'best:<metric>'")
    name = select[5:]

    sign = -1.0 if name in LARGER_IS_BETTER else 1.0  # best:transmission: the largest

    def key(j: int) -> tuple[bool, tuple[float, ...], float, int]:
        v = sign * float(picks[j].get(name, math.nan))
        return (not feasible[j], shortfalls(picks[j], where), v if math.isfinite(v) else math.inf, j)

    return sorted(range(len(picks)), key=key)


def select_chain(picks: Sequence[Mapping[str, float]], feasible: Sequence[bool], select: str,
                 where: Sequence[Constraint] = ()) -> int:
    """The winning chain: the best pick by ``select`` among the chains that meet ``where``.

    Ranking key per chain (smallest wins): feasible pick first, then the relative shortfalls
    under the ``where`` limits compared limit by limit in the order given (all 0 for a chain
    that meets them: the first limit is the most important, and if no chain meets it, the one
    missing it least goes on), then the ``select`` metric (its best first: the smallest, the largest for one in
    ``result.LARGER_IS_BETTER``; NaN last), then the chain index.

    Args:
        picks: per chain, the metrics of its pick at the block's last stage.
        feasible: per chain, whether that pick satisfies its stage's constraints.
        select: ``"best:<metric>"``.
        where: limits on the picks' metrics.

    Raises:
        ValueError: no chains, or a rule other than ``best:<metric>``.
    """
    if not picks:
        raise ValueError("no chains to select from")
    return rank_chains(picks, feasible, select, where)[0]


@dataclass(frozen=True)
class Screen:
    """After stage ``after`` of a block, only the ``keep`` chains best by ``by`` go on.

    Attributes:
        after: name of a stage of the block before its last one.
        keep: chains that go on (>= 1).
        by: ``"best:<metric>"`` of ``after``'s pick, ranked as in :func:`select_chain`.
        where: limits on ``after``'s picks, ranked as in :func:`select_chain` (none: the metric alone).
    """

    after: str
    keep: int
    by: str
    where: tuple[Constraint, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"after": self.after, "keep": self.keep, "by": self.by}
        if self.where:
            out["where"] = where_to_dict(self.where)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Screen:
        return cls(str(d["after"]), int(d["keep"]), str(d["by"]), where_from_dict(d.get("where", {})))


@dataclass(frozen=True)
class Starts:
    """A stage's ``starts`` table: rerun it and the stages up to ``until`` ``n`` times.

    Attributes:
        n: number of chains (>= 1; 1 is the single-start run, recorded).
        until: name of the block's last stage (this stage itself or a later one).
        select: ``"best:<metric>"`` of ``until``'s pick that decides the winner.
        where: limits the winner's pick should meet (see :func:`select_chain`).
        screen: optional screening after an earlier stage of the block.
    """

    n: int
    until: str
    select: str
    where: tuple[Constraint, ...] = ()
    screen: Screen | None = None

    def to_dict(self) -> dict[str, Any]:
        out = {"n": self.n, "until": self.until, "select": self.select, "where": where_to_dict(self.where)}
        if self.screen is not None:
            out["screen"] = self.screen.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Starts:
        screen = None if d.get("screen") is None else Screen.from_dict(d["screen"])
        return cls(int(d["n"]), str(d["until"]), str(d["select"]), where_from_dict(d.get("where", {})), screen)


@dataclass(frozen=True)
class Chain:
    """One chain of a multi-start block, as recorded.

    Attributes:
        index: chain number j (its stages ran with seed offset ``SEED_STRIDE * j``).
        seeds: the seed of each stage of the block.
        status: ``complete``, ``dropped`` (by the screen: it ran the stages up to the screen's
            ``after``) or ``cancelled``.
        picks: per stage run, the picked member (None for a cancelled stage).
        metrics: per stage, the pick's metrics (``{}`` without a pick).
        params: per stage, the pick's parameters by name.
        feasible: whether the pick at the block's last stage meets its stage's constraints.
        time: compute time of the chain's stages (s).
        evals: function evaluations of the chain's stages (None in a result written before they were kept).
    """

    index: int
    seeds: tuple[int, ...]
    status: str
    picks: tuple[int | None, ...]
    metrics: tuple[Mapping[str, float], ...]
    params: tuple[Mapping[str, float], ...]
    feasible: bool
    time: float
    evals: int | None = None

    @property
    def last(self) -> Mapping[str, float]:
        """The metrics of the pick at the block's last stage."""
        return self.metrics[-1] if self.metrics else {}

    def last_pick(self) -> tuple[int, Mapping[str, float]] | None:
        """The block stage (its index in the block) of the chain's last pick and that pick's metrics: the block's
        last stage for a complete chain, the screen's for a dropped one, the stage before a cancel's; None
        without a pick."""
        for k in range(len(self.picks) - 1, -1, -1):
            if self.picks[k] is not None:
                return k, self.metrics[k]
        return None

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "seeds": list(self.seeds), "status": self.status, "picks": list(self.picks),
                "metrics": [dict(m) for m in self.metrics], "params": [dict(p) for p in self.params],
                "feasible": self.feasible, "time": self.time, "evals": self.evals}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Chain:
        def floats(m: Mapping[str, Any]) -> dict[str, float]:
            return {str(k): decode_float(v) for k, v in m.items()}

        return cls(int(d["index"]), tuple(int(s) for s in d["seeds"]), str(d["status"]),
                   tuple(None if p is None else int(p) for p in d["picks"]), tuple(floats(m) for m in d["metrics"]),
                   tuple(floats(p) for p in d["params"]), bool(d["feasible"]), decode_float(d["time"]),
                   None if d.get("evals") is None else int(d["evals"]))


@dataclass(frozen=True)
class MultiStart:
    """The record of one multi-start block of a run.

    Attributes:
        starts: the block's configuration.
        stages: names of the block's stages (``first .. last``).
        first, last: their indices in the pipeline.
        chains: every chain, in order.
        chosen: the chain whose results are the pipeline's: the winner, or the chain that was
            cancelled (the run's status says which).
    """

    starts: Starts
    stages: tuple[str, ...]
    first: int
    last: int
    chains: tuple[Chain, ...]
    chosen: int

    @property
    def time(self) -> float:
        """Compute time of the chains that lost (the winner's is in its stage results)."""
        return float(sum(c.time for c in self.chains if c.index != self.chosen))

    @property
    def evals(self) -> int | None:
        """Function evaluations of the chains that lost; None when a chain's were not kept (an older result)."""
        lost = [c.evals for c in self.chains if c.index != self.chosen]
        return None if any(e is None for e in lost) else int(sum(e for e in lost if e is not None))

    def to_dict(self) -> dict[str, Any]:
        return {"starts": self.starts.to_dict(), "stages": list(self.stages), "first": self.first,
                "last": self.last, "chains": [c.to_dict() for c in self.chains], "chosen": self.chosen}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MultiStart:
        return cls(Starts.from_dict(d["starts"]), tuple(str(s) for s in d["stages"]), int(d["first"]),
                   int(d["last"]), tuple(Chain.from_dict(c) for c in d["chains"]), int(d["chosen"]))
