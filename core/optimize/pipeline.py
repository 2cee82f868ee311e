"""A chain of stages: stage k searches around the pick of stage k-1 (stage 0 around ``start``).

The pipeline holds one lineage: ``results[k]`` is stage k's latest result, which started
from member ``results[k].parent_pick`` of ``results[k-1]``. Recording a new result for stage
k (or changing stage k's pick) drops the results after k, since they grew from another pick;
a studio that keeps branches copies them first (results are immutable).

Three ways to drive it:
- by hand (the studio): ``stage = pipe.stage(k, pick=i)``; step it; ``pipe.record(k, stage.result())``;
  ``pipe.select(k, j)`` to change a pick;
- ``for progress in pipe.iterate(start=k, pick=i, cancel=event): ...`` runs stages k.. with
  their automatic pick rules, yielding after every generation;
- ``pipe.run(...)`` the same, headless.
"""

from __future__ import annotations

import json
import numbers
import threading
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from core.kinematics.design import Design
from core.kinematics.mechanisms import get as get_mechanism
from core.kinematics.model import OutputStage
from core.optimize.box import Box
from core.optimize.result import PickRule, StageResult, decode_array, dumps, versions
from core.optimize.stage import Callback, Progress, Stage, StageSpec, derived_seed

FORMAT = "clm-pipeline"
FORMAT_VERSION = 1


def seeded(stages: Sequence[StageSpec], seed: int) -> list[StageSpec]:
    """The same stages with seeds ``seed, seed + 1, ...`` (one run seed for a whole pipeline, wrapped at 2**32)."""
    return [replace(s, seed=derived_seed(seed, k)) for k, s in enumerate(stages)]


class Pipeline:
    """Stages chained by picks.

    Args:
        stages: the stage specs, in order.
        start: one-member Design stage 0 starts from (for a global-bounds stage, only its
            fixed parameters matter).
        results: saved results of the first stages (a lineage), e.g. from :meth:`from_dict`.
    """

    def __init__(self, stages: Sequence[StageSpec], start: Design, results: Sequence[StageResult | None] = ()) -> None:
        if not isinstance(start, Design):
            raise TypeError(f"a pipeline starts from a Design, got {type(start).__name__}")
        if start.pop != 1:
            raise ValueError(f"a pipeline starts from one design, got pop = {start.pop}")
        if not stages:
            raise ValueError("a pipeline needs at least one stage")
        bad = [type(s).__name__ for s in stages if not isinstance(s, StageSpec)]
        if bad:
            raise TypeError(f"a pipeline's stages must be StageSpecs, got {bad[0]}")
        if len(results) > len(stages):
            raise ValueError(f"{len(results)} results for {len(stages)} stages")
        bad = [type(r).__name__ for r in results if r is not None and not isinstance(r, StageResult)]
        if bad:
            raise TypeError(f"a pipeline's results must be StageResults or None, got {bad[0]}")
        if not np.isfinite(start.params).all():
            raise ValueError(f"a pipeline starts from finite parameters, got {start.named()}")
        self.stages: list[StageSpec] = list(stages)
        self.start = start
        self.results: list[StageResult | None] = list(results) + [None] * (len(stages) - len(results))

    @property
    def n_stages(self) -> int:
        return len(self.stages)

    @property
    def lineage(self) -> list[StageResult]:
        """The recorded results from stage 0 up to the first missing one."""
        out = []
        for r in self.results:
            if r is None:
                break
            out.append(r)
        return out

    def _check(self, k: int) -> None:
        if isinstance(k, bool) or not isinstance(k, numbers.Integral):
            raise TypeError(f"a stage index must be an integer, got {type(k).__name__} {k!r}")
        if not 0 <= k < self.n_stages:
            raise ValueError(f"no stage {k}; the pipeline has stages 0 to {self.n_stages - 1}")

    def parent(self, k: int, pick: PickRule | None = None) -> tuple[Design, int | None]:
        """Stage k's start design and the member of stage k-1 it is.

        Args:
            k: stage index.
            pick: member (or rule) of stage k-1's result; default its recorded pick, else
                stage k-1's automatic rule.

        Raises:
            ValueError: stage k-1 has no result, or nothing to pick.
        """
        self._check(k)
        if k == 0:
            return self.start, None
        prev = self.results[k - 1]
        if prev is None:
            raise ValueError(f"stage {k} ({self.stages[k].name}) needs a result of stage {k - 1} first")
        if pick is None:
            pick = prev.picked if prev.picked is not None else self.stages[k - 1].pick
        i = prev.choose(pick)
        return prev.pick(i), i

    def box(self, k: int, pick: PickRule | None = None, spec: StageSpec | None = None) -> Box:
        """The search box stage k would get from that pick (for display before launching)."""
        return (spec or self.stages[k]).box(self.parent(k, pick)[0])

    def stage(self, k: int, pick: PickRule | None = None, spec: StageSpec | None = None,
              callback: Callback | None = None) -> Stage:
        """A new, not yet set-up Stage k starting from a pick of stage k-1 (see :meth:`parent`).

        Args:
            spec: replaces stage k's spec (e.g. new algorithm settings); kept by the pipeline.
        """
        self._check(k)
        if spec is not None:
            if not isinstance(spec, StageSpec):
                raise TypeError(f"spec must be a StageSpec, got {type(spec).__name__}")
            self.stages[k] = spec
        start, i = self.parent(k, pick)
        return Stage(self.stages[k], start, index=k, callback=callback, parent_pick=i)

    def record(self, k: int, result: StageResult) -> None:
        """Store stage k's result; set stage k-1's pick to the member it started from; drop later results."""
        self._check(k)
        if not isinstance(result, StageResult):
            raise TypeError(f"a pipeline records StageResults, got {type(result).__name__}")
        if k > 0 and result.parent_pick is not None:
            prev = self.results[k - 1]
            if prev is not None and prev.picked != result.parent_pick:
                self.results[k - 1] = replace(prev, picked=result.parent_pick)
        self.results[k] = result
        self.results[k + 1 :] = [None] * (self.n_stages - k - 1)

    def select(self, k: int, rule: PickRule) -> StageResult:
        """Set stage k's pick (index or rule); results after k are dropped if the pick changes."""
        self._check(k)
        res = self.results[k]
        if res is None:
            raise ValueError(f"stage {k} ({self.stages[k].name}) has no result to pick from")
        new = res.with_pick(rule)
        if new.picked != res.picked:
            self.results[k] = new
            self.results[k + 1 :] = [None] * (self.n_stages - k - 1)
        return self.results[k]  # type: ignore[return-value]

    def restore_picks(self, picks: Sequence[int | None]) -> None:
        """Set every stage's picked member at once and keep every result (Undo of a pick over the same
        populations); ``picks`` has one entry a stage, None for no pick."""
        if len(picks) != self.n_stages:
            raise ValueError(f"{len(picks)} picks for {self.n_stages} stages")
        for k, (r, m) in enumerate(zip(self.results, picks, strict=True)):
            if r is not None and r.picked != m:
                if m is not None and not 0 <= m < len(r.X):
                    raise ValueError(f"stage {k} ({self.stages[k].name}) has no member {m}")
                self.results[k] = replace(r, picked=m)

    def iterate(self, start: int = 0, pick: PickRule | None = None,
                cancel: threading.Event | None = None) -> Iterator[Progress]:
        """Run stages ``start, start + 1, ...``, yielding after every generation.

        Each finished stage is recorded with its automatic pick. Cancelling (the event, or
        closing the generator) records the current stage's partial result and stops.

        Args:
            start: first stage to run; the stages before it keep their results.
            pick: member (or rule) of stage ``start - 1`` to start from.
            cancel: checked before every generation.
        """
        for k in range(start, self.n_stages):
            stage = self.stage(k, pick if k == start else None)
            try:
                while stage.has_next():
                    if cancel is not None and cancel.is_set():
                        stage.cancel()
                        break
                    yield stage.next()
            except GeneratorExit:
                stage.cancel()
                self.record(k, stage.result())
                raise
            res = stage.result()
            if res.status in ("complete", "stopped") and res.pop > 0:
                res = res.with_pick(self.stages[k].pick)
            self.record(k, res)
            if res.status not in ("complete", "stopped"):
                return

    def run(self, start: int = 0, pick: PickRule | None = None, callback: Callback | None = None,
            cancel: threading.Event | None = None) -> list[StageResult]:
        """Headless :meth:`iterate`; returns the lineage."""
        for progress in self.iterate(start, pick, cancel):
            if callback is not None:
                callback(progress)
        return self.lineage

    # --- JSON -----------------------------------------------------------------------------

    def to_dict(self, results: bool = True) -> dict[str, Any]:
        """The pipeline as data; ``results=False`` leaves the results' entry out (a caller that keeps their data)."""
        out = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "mechanism": self.start.mechanism.name,
            "output": self.start.output.to_dict(),
            "start": self.start.named(),
            "start_params": self.start.params[0],
            "stages": [s.to_dict() for s in self.stages],
            "results": [None if r is None else r.to_dict() for r in self.results] if results else None,
            "picks": [None if r is None else r.picked for r in self.results],
            "versions": versions(),
        }
        if not results:
            del out["results"]
        return out

    def to_json(self, indent: int | None = 1) -> str:
        return dumps(self.to_dict(), indent)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], stages: Sequence[StageSpec] | None = None) -> Pipeline:
        """Rebuild a pipeline; stage specs come from the registry unless given (same count)."""
        if d.get("format") != FORMAT:
            raise ValueError(f"not a pipeline (format {d.get('format')!r}, expected {FORMAT!r})")
        if d.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported pipeline version {d.get('format_version')!r}")
        mech = get_mechanism(d["mechanism"])
        out = d["output"]
        start = Design(mech, decode_array(d["start_params"], mech.n_params),
                       OutputStage.from_dict(out))
        specs = list(stages) if stages is not None else [StageSpec.from_dict(s) for s in d["stages"]]
        if len(specs) != len(d["stages"]):
            raise ValueError(f"{len(specs)} stage specs for {len(d['stages'])} saved stages")
        results = [None if r is None else StageResult.from_dict(r) for r in d["results"]]
        return cls(specs, start, results)

    @classmethod
    def from_json(cls, text: str, stages: Sequence[StageSpec] | None = None) -> Pipeline:
        return cls.from_dict(json.loads(text), stages)

