"""What the study panels show, as one immutable snapshot built under the session lock."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from core.kinematics.design import Design
from core.optimize.box import Box
from core.optimize.problem import Constraint
from core.optimize.result import StageResult
from core.optimize.scale import PAPER_STRIDE
from core.optimize.stage import StageSpec
from studio.chains import ChainStage, RunSettings, problems_for, stage_spec
from studio.study import RunStatus, Study
from studio.target import TargetSpec


@dataclass(frozen=True)
class StudyView:
    """An immutable snapshot of the study for the panels (taken under the lock, drawn without it).

    Attributes:
        key: changes whenever the study changes (identity and version).
        chain: the stages offered for the editor's mechanism.
        names: the pipeline's stage names; results: their results (None: not run).
        specs: the pipeline's stage specs by name (problem labels, constraints).
        status: the run status.
        viewing: stage shown in the Pareto and Pick panels; shown: its member shown.
        next_stage: the stage the Run button launches; from_pick: from the previous pick (else the editor).
        settings: run settings of ``next_stage``.
        box: the search box ``next_stage`` would get, or None; box_note: what it is built around.
        branches: labels of the kept branches.
        constraints: ``next_stage``'s constraints in words (``assembles``, ``h_s <= 6.5``).
        run_target: the target of the pipeline's last run (None before any).
        problems: the problems the Problem list offers for the editor's mechanism.
    """

    key: tuple[int, int]
    chain: tuple[ChainStage, ...]
    names: tuple[str, ...]
    results: tuple[StageResult | None, ...]
    specs: dict[str, StageSpec]
    status: RunStatus
    viewing: str | None
    shown: int | None
    next_stage: str | None
    from_pick: bool
    settings: RunSettings | None
    box: Box | None
    box_note: str
    branches: tuple[str, ...]
    constraints: tuple[str, ...] = ()
    run_target: TargetSpec | None = None
    problems: tuple[str, ...] = ()

    def result(self, name: str | None) -> StageResult | None:
        if name is None or name not in self.names:
            return None
        return self.results[self.names.index(name)]


def next_stage(study: Study, chain: tuple[ChainStage, ...]) -> str | None:
    """The stage the Run button launches and whose settings the Stages panel shows: the study's next stage if
    the chain offers it, else the chain's first (call under the session lock)."""
    return study.next_stage if study.next_stage in {c.name for c in chain} else (chain[0].name if chain else None)


def study_view(study: Study, editor: Design, chain: tuple[ChainStage, ...], target: TargetSpec) -> StudyView:
    """Snapshot the study (call under the session lock)."""
    pipe = study.pipeline
    names = study.stage_names()
    nxt = next_stage(study, chain)
    stage = next((c for c in chain if c.name == nxt), None)
    box, note = None, ""
    spec: StageSpec | None = None  # built once: the box, its note and the constraints the panel lists
    if stage is not None:
        try:  # the run's own spec: the current target (and its size), the stage's settings
            spec = stage_spec(stage, study.settings_for(stage), target)
        except ValueError:  # a problem that cannot be built here says so when run
            spec = None
        if study.from_pick:
            box = study.next_box(stage.name, target)
            prev = study.parent_result(stage.name)
            if box is not None and prev is not None:
                i = prev.picked if prev.picked is not None else prev.shortlist.first
                if spec is not None and i is not None:
                    box = spec.box(prev.pick(i))
                note = f"around {prev.name}'s pick #{i}"
            else:
                note = "no previous pick in this pipeline: run the previous stage, or start from the editor's design"
        else:
            box = None if spec is None else spec.box(editor)
            note = "global bounds" if stage.s is None else "around the design in the editor"
            if spec is not None and spec.s is not None:
                note += f" (±max({100 * spec.s:g} %, {spec.d:.3g} mm))"
        if box is not None and spec is not None and spec.problem.scale != 1.0:
            note += f"; sized for a {PAPER_STRIDE * spec.problem.scale:.4g} mm stride"
    viewing = study.viewing if study.viewing in names else (names[0] if names else None)
    return StudyView(
        key=(id(study), study.version),
        chain=chain,
        names=names,
        results=tuple(pipe.results) if pipe is not None else (),
        specs={s.name: s for s in pipe.stages} if pipe is not None else {},
        status=study.status,
        viewing=viewing,
        shown=study.shown_member(viewing),
        next_stage=nxt,
        from_pick=study.from_pick,
        settings=None if stage is None else study.settings_for(stage),
        box=box,
        box_note=note,
        branches=tuple(b.label for b in study.branches),
        constraints=() if spec is None else _constraints(spec),
        run_target=study.target,
        problems=problems_for(editor.mechanism),
    )


def constraint_text(c: Constraint, labels: Mapping[str, str] | None = None) -> str:
    """``assembles``, ``f4 = h_s (mm) ≤ 6.5``, ``theta1 (rad) ≥ 0.1`` (the problem's label for the metric)."""
    if c.metric in ("violation", "violation_mm"):
        return "assembles"
    name = (labels or {}).get(c.metric, c.metric)
    if c.upper is not None:
        return f"{name} ≤ {limit_text(c.upper)}"
    return f"{name} ≥ {limit_text(float(c.lower or 0.0))}"


def limit_text(v: float) -> str:
    """A limit to four significant digits, with "…" when that rounds it: a leg's sized limits read "≤ 2.22222"
    and "≤ 13.3333" (the paper's 5 mm² and 30 mm/s at k = 2/3)."""
    short = f"{v:.4g}"
    return short if float(short) == v else short + "…"


def _constraints(spec: StageSpec) -> tuple[str, ...]:
    return tuple(constraint_text(c, spec.problem.labels) for c in spec.problem.constraints)
