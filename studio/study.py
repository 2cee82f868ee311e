"""The optimization side of a session: the pipeline, its branches, picks, run status, and the runner.

Pure state (no viser). A :class:`Study` holds one ``core.optimize.Pipeline`` (one lineage
X0 -> X1 -> ...), the branches the designer left behind (each a frozen copy of a whole pipeline
as JSON), which stage is shown, which member of each stage is shown, and the run settings per
stage. Every method is called under the owning session's lock.

Rules:
- Running a stage from the design in the editor starts a new pipeline at that stage.
- Running a stage from the previous stage's pick, or changing a pick that later stages grew
  from, first keeps the current pipeline as a branch (results are immutable, so a branch is a
  copy of the JSON), then re-records: the pipeline itself keeps one lineage.
- A finished stage's pick is its chain rule (knee, or best h_s / I as the paper prioritises);
  the designer's pick replaces it.

The :class:`Runner` drives one stage in a worker thread, generation by generation, recording
the partial result after every generation (so a session saved then loses nothing), and stops
between generations when its cancel event is set. Only one run at a time: ``start`` checks and
marks the run under the lock, so a double-clicked Run starts one run.
"""

from __future__ import annotations

import json
import time
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from core.kinematics.design import Design
from core.optimize.algorithms import ALGORITHMS, make_algorithm
from core.optimize.box import Box
from core.optimize.lineage import auto_pick
from core.optimize.pipeline import Pipeline
from core.optimize.problem import make_problem, problem_names
from core.optimize.result import StageResult, dumps
from core.optimize.rtclm import is_rtclm
from core.optimize.stage import Progress, StageSpec
from studio.chains import ChainStage, RunSettings, default_settings, sized_where, stage_spec
from studio.study_targets import _pipeline_from, _retarget
from studio.target import CURVE_DIR, Curve, TargetSpec, curve_file

RUN_STATES = ("idle", "running", "stopping")


@dataclass(frozen=True)
class RunStatus:
    """What the Stages panel shows about the run.

    Attributes:
        state: ``idle``, ``running`` or ``stopping``.
        stage: name of the stage running (or last run).
        generation, n_gen: progress.
        message: the last run's outcome (``complete``, ``cancelled at generation 3``, an error).
        ok: False if the last run failed.
        elapsed: compute time of the run so far (s).
        compiled: of which numba compiling kernels (s): a fresh install's first run of a kind (the warm-up of
            ``scripts/studio`` or ``clm-studio --warm-up`` does it ahead).
    """

    state: str = "idle"
    stage: str | None = None
    generation: int = 0
    n_gen: int = 0
    message: str = ""
    ok: bool = True
    elapsed: float = 0.0
    compiled: float = 0.0

    @property
    def running(self) -> bool:
        return self.state != "idle"

    @property
    def fraction(self) -> float:
        return self.generation / self.n_gen if self.n_gen else 0.0


# Each result's JSON data, made once per result object (results are immutable) and shared by the current pipeline's
# data and every branch that holds the result: a session is saved after every change and every SAVE_PERIOD s of a
# run, and encoding every population again was most of a save; a re-run or a topology switch parsed another copy of
# every earlier stage's result for its branch.
_RESULT_JSON: dict[int, tuple[weakref.ref[StageResult], dict[str, Any]]] = {}


def result_json(r: StageResult, known: dict[str, Any] | None = None) -> dict[str, Any]:
    """``r`` as ``Pipeline.to_json`` writes it, read back (a shared dict: do not change it). ``known``: that data
    already read (a restored branch's), kept for ``r`` unless it has some."""
    key = id(r)
    hit = _RESULT_JSON.get(key)
    if hit is not None and hit[0]() is r:
        return hit[1]
    data = known if known is not None else json.loads(dumps(r.to_dict(), None))
    _RESULT_JSON[key] = (weakref.ref(r, lambda _: _RESULT_JSON.pop(key, None)), data)
    return data


def pipeline_json(p: Pipeline) -> dict[str, Any]:
    """``json.loads(p.to_json())``, its results from ``result_json``."""
    head = json.loads(dumps(p.to_dict(results=False), None))
    out = {k: v for k, v in head.items() if k not in ("picks", "versions")}
    out["results"] = [None if r is None else result_json(r) for r in p.results]
    out["picks"], out["versions"] = head["picks"], head["versions"]
    return out


@dataclass(frozen=True)
class Branch:
    """A pipeline the designer left (a JSON copy, restorable), the target its stages ran against
    (``TargetSpec.to_dict``), and the study's state when it was left: members shown per stage, the stage the
    Run button launched and whether from the previous pick. Sessions saved before branches kept these have
    None / {} / None here."""

    label: str
    pipeline: dict[str, Any]
    target: dict[str, Any] | None = None
    shown: dict[str, int] = field(default_factory=dict)
    next_stage: str | None = None
    from_pick: bool = False

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"label": self.label, "pipeline": self.pipeline}
        if self.target is not None:
            out["target"] = self.target
        if self.next_stage is not None:
            out.update(shown=dict(self.shown), next_stage=self.next_stage, from_pick=self.from_pick)
        return out


def ran_with(r: StageResult) -> RunSettings | None:
    """The Stages panel's settings a result was produced with (problem, algorithm, population, generations
    planned, seed, the transmission limit its problem held), or None if its record does not make valid ones (a
    hand-made or older file). Rehearsal 5: a restored branch lost its limit, and Run went on without it."""
    try:
        problem = r.settings["problem"]
        algorithm = r.settings["algorithm"]
        limit = (problem.get("options") or {}).get("transmission_min", 0) or 0
        return RunSettings(str(problem["name"]), str(algorithm["name"]), int(algorithm["pop_size"]), int(r.n_gen),
                           int(r.seed), int(round(float(limit))))
    except (KeyError, TypeError, ValueError, AttributeError):
        return None


@dataclass(frozen=True)
class RunPlan:
    """A prepared run: the pipeline it records into, the stage index, the pick it starts from, the spec, and
    the target it runs against."""

    pipeline: Pipeline
    index: int
    pick: int | None
    spec: StageSpec
    stage: ChainStage
    target: TargetSpec


def studio_pick(result: StageResult, plan: RunPlan) -> int:
    """A finished run's automatic pick, as ``clm design`` makes it: the stage's rule among the members that meet the
    next stage's constraints, narrowed by its ``pick_where`` (the limits on metrics this problem reports)."""
    pipe, k = plan.pipeline, plan.index
    nxt = pipe.stages[k + 1].problem if k + 1 < pipe.n_stages else None
    sized = sized_where(plan.stage.pick_where, pipe.stages[k].problem.scale)  # the chain's I limits are the paper's
    where = tuple(c for c in sized if c.metric in result.metrics)
    try:
        return auto_pick(result, plan.spec.pick, plan.spec.stop_below, nxt, where)
    except ValueError:  # a rule naming a metric another problem in this slot does not report
        return result.choose("knee")


WEIGHTED = ("cmoemt", "moead_cmt", "nsga3", "unsga3", "ctaea")  # population = their weight / reference vectors


def population_note(r: StageResult) -> str:
    """``55 members, not the 60 asked: CMOEMT keeps one per weight vector``, when a result holds another number of
    members than its run asked for ("55 feasible of 55" at population 60 left a designer asking where five went);
    "" otherwise."""
    algorithm = r.settings.get("algorithm") if isinstance(r.settings, Mapping) else None
    asked = algorithm.get("pop_size") if isinstance(algorithm, Mapping) else None
    if not isinstance(asked, int) or asked == r.pop or r.pop == 0:
        return ""
    name = str(algorithm.get("name", "")) if isinstance(algorithm, Mapping) else ""
    why = f": {algorithm_name(r.settings)} keeps one per weight vector" if name in WEIGHTED else ""
    return f"{r.pop} members, not the {asked} asked{why}"


def algorithm_name(settings: object) -> str:
    """The algorithm's published name (``IMTCMO``, not ``imtcmo``) in a stage result's settings, or "" (a loaded
    session's settings are free-form: an unknown name is shown as it is)."""
    algorithm = settings.get("algorithm") if isinstance(settings, Mapping) else None
    name = algorithm.get("name") if isinstance(algorithm, Mapping) else None
    if not isinstance(name, str):
        return ""
    return ALGORITHMS[name].title if name in ALGORITHMS else name


def member_shown(r: StageResult | None, shown: Mapping[str, int]) -> int | None:
    """The member shown for a stage result: the designer's choice (``shown``, by stage), else its pick, else its
    automatic one; what a branch ends on and Restore brings back."""
    if r is None or r.pop == 0:
        return None
    i = shown.get(r.name)
    if i is not None and 0 <= i < r.pop:
        return i
    return r.picked if r.picked is not None else r.shortlist.first


def _values(r: StageResult, shown: dict[str, int]) -> str:
    """`` · h_s 5.93, I 0.452``: the objective values of the member a branch ends on (what tells branches apart)."""
    i = member_shown(r, shown)
    if i is None:
        return ""
    return " · " + ", ".join(f"{o} {v:.3g}" for o, v in zip(r.objectives, r.F[i], strict=True))


def _against(r: StageResult, target: TargetSpec | None) -> str:
    """`` · h4=300, mu>=20``: an RTCLM branch's heights and a transmission limit it held (rehearsal 7: three
    branches run against h4 220, 300, and 300 with mu >= 20 read alike but for the clock); "" for the six-bars,
    whose objective values already differ with the curve."""
    if target is None or not is_rtclm(r.mechanism.name):
        return ""
    ran = ran_with(r)
    limit = f", mu>={ran.transmission_min}" if ran is not None and ran.transmission_min else ""
    return f" · h6={target.h6:g}, h4={target.h4:g}{limit}"


def branch_stages(lineage: list[StageResult], shown: dict[str, int]) -> str:
    """``subtask1 #3, subtask2 #8 by cmoemt``: each stage's pick, the member the last one shows when that is
    another, and the last stage's algorithm (branches made to compare algorithms differ only there)."""
    parts = [r.name + (f" #{r.picked}" if r.picked is not None else "") for r in lineage]
    last = lineage[-1]
    i = member_shown(last, shown)
    if i is not None and i != last.picked:
        parts[-1] += f" showing #{i}"
    name = algorithm_name(last.settings)
    # A run the designer stopped (or one a crash interrupted) says so: its label read as a finished one's.
    cut = f", stopped at {last.generation}/{last.n_gen}" if last.status in ("cancelled", "running") else ""
    return ", ".join(parts) + (f" by {name}" if name else "") + cut


def result_labels(r: StageResult) -> dict[str, str]:
    """The display names of the metrics of the problem a result ran (``{"order_4": "Eq. 30 order ..."}``), from the
    registry; {} for a problem it does not know (a session from elsewhere)."""
    problem = r.settings.get("problem") if isinstance(r.settings, dict) else None
    name = problem.get("name") if isinstance(problem, dict) else None
    if not isinstance(name, str) or name not in problem_names():
        return {}
    try:
        return dict(make_problem(name).labels)  # the labels are the problem's, whatever its options
    except (TypeError, ValueError):
        return {}


def status_text(r: StageResult) -> str:
    """The stage's state in words; a population with no feasible member says so and names what its least
    violating member misses (``complete — no feasible member: h_s 8.72 > 6.5``)."""
    if r.status == "running":
        text = f"interrupted at generation {r.generation}/{r.n_gen}"
    elif r.status == "cancelled":
        text = f"stopped at generation {r.generation}/{r.n_gen}"
    elif r.status == "stopped":
        text = f"target reached at generation {r.generation}"
    else:
        text = r.status
    settings = getattr(r, "settings", None)
    stop = settings.get("stop_below") if isinstance(settings, dict) else None
    if r.status == "complete" and isinstance(stop, list) and stop and r.picked is not None:
        # It ran out of generations short of its target (an RTCLM stage stalled in a pocket, an h4 out of reach):
        # "complete" alone read as done.
        got = ", ".join(f"{k} {float(r.F[r.picked, j]):.3g}" for j, k in enumerate(r.objectives))
        text += f" — its early stop [{', '.join(f'{float(v):g}' for v in stop)}] not reached (pick: {got})"
    if r.pop and not r.feasible.any():
        i = int(np.argmin(np.where(np.isnan(r.cv), np.inf, r.cv)))
        unmet = "; ".join(r.unmet(i, result_labels(r)))
        text += " — no feasible member" + (f": {unmet}" if unmet else "")
    return text


def done_at(r: StageResult) -> int:
    """The generations a finished stage was to run: all it planned, or where it reached its target."""
    return r.generation if r.status == "stopped" else r.n_gen


def last_run(r: StageResult | None) -> RunStatus:
    """The Stages panel's "Last run" for a pipeline whose last stage is ``r`` (a restored branch, a loaded
    session)."""
    if r is None:
        return RunStatus()
    return RunStatus("idle", r.name, r.generation, done_at(r), status_text(r), True, float(r.timings.get("total", 0.0)))


def _same(a: object, b: object) -> bool:
    """The same population: equal members (a pick's copy of a result copies its arrays; a re-run with the same
    seed is the same population, where the same selection holds as well)."""
    if a is None or b is None:
        return a is b
    assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
    return a is b or (a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True)))


def _one_lineage(a: Pipeline | None, b: Pipeline) -> bool:
    """The same pipeline, or a copy of it: a branch restored (by hand, or by an Undo of a restore or of a topology
    switch) is rebuilt from its JSON, and a pass-on made before could no longer be undone (review of session 36)."""
    return a is b or (a is not None and [s.name for s in a.stages] == [s.name for s in b.stages]
                      and _same(a.start.params, b.start.params))


@dataclass(frozen=True, eq=False)
class Selection:
    """What the study showed, had picked and would run next at one moment (Undo brings it back with the design it
    went with, while the pipeline still holds the same populations)."""

    pipeline: Pipeline | None
    populations: tuple[object, ...]  # each stage's result's X, or None
    picks: tuple[int | None, ...]
    shown: tuple[tuple[str, int], ...]
    viewing: str | None
    next_stage: str | None
    from_pick: bool


@dataclass
class Study:
    """Pipeline, branches, picks shown and run settings of one session (guarded by the session's lock).

    Attributes:
        pipeline: the current lineage, or None before the first run.
        branches: pipelines left behind, oldest first.
        viewing: stage name shown in the Pareto and Pick panels.
        shown: per stage name, the member shown (animated in the editor).
        next_stage: the stage the Run button launches.
        from_pick: launch from the previous stage's pick (else from the editor's design).
        settings: per stage name, the run settings.
        target: the target the pipeline's latest run ran against (what a branch of it brings back).
        status: the run status.
        live: the latest generation of the running stage.
        version: bumped on every change (the panels redraw when it moves).
    """

    pipeline: Pipeline | None = None
    branches: list[Branch] = field(default_factory=list)
    viewing: str | None = None
    shown: dict[str, int] = field(default_factory=dict)
    next_stage: str | None = None
    from_pick: bool = False
    settings: dict[str, RunSettings] = field(default_factory=dict)
    target: TargetSpec | None = None
    status: RunStatus = field(default_factory=RunStatus)
    live: Progress | None = None
    version: int = 0
    def touch(self) -> None:
        self.version += 1

    def selection(self) -> Selection:
        """The members shown and picked and the stage to run next, as they are now."""
        pipe = self.pipeline
        results = [] if pipe is None else pipe.results
        return Selection(pipe, tuple(None if r is None else r.X for r in results),
                         tuple(None if r is None else r.picked for r in results), tuple(self.shown.items()),
                         self.viewing, self.next_stage, self.from_pick)

    def holds(self, sel: Selection) -> bool:
        """True when :meth:`reselect` can bring ``sel`` back: no run and no other pipeline came between."""
        pipe = self.pipeline
        if self.status.running or pipe is None or not _one_lineage(sel.pipeline, pipe):
            return False
        now = [None if r is None else r.X for r in pipe.results]
        return len(now) == len(sel.populations) and all(_same(a, b) for a, b in zip(now, sel.populations,
                                                                                    strict=True))

    def reselect(self, sel: Selection) -> bool:
        """Bring back what ``sel`` showed and picked, if the pipeline still holds the populations it did (a pass-on
        or a pick taken back); False, and nothing changed, once a run or another pipeline came between."""
        pipe = self.pipeline
        if pipe is None or not self.holds(sel):
            return False
        pipe.restore_picks(sel.picks)
        self.shown = dict(sel.shown)
        self.viewing, self.next_stage, self.from_pick = sel.viewing, sel.next_stage, sel.from_pick
        self.touch()
        return True

    # Reading -------------------------------------------------------------------------------

    def stage_names(self) -> tuple[str, ...]:
        return () if self.pipeline is None else tuple(s.name for s in self.pipeline.stages)

    def index(self, name: str) -> int | None:
        names = self.stage_names()
        return names.index(name) if name in names else None

    def result(self, name: str | None) -> StageResult | None:
        if name is None or self.pipeline is None:
            return None
        k = self.index(name)
        return None if k is None else self.pipeline.results[k]

    def settings_for(self, stage: ChainStage) -> RunSettings:
        return self.settings.get(stage.name) or default_settings(stage)

    def shown_member(self, name: str | None) -> int | None:
        """The member shown for a stage: the designer's choice, else its pick, else its automatic one."""
        return member_shown(self.result(name), self.shown)

    def parent_result(self, name: str) -> StageResult | None:
        k = self.index(name)
        if k is None or k == 0 or self.pipeline is None:
            return None
        return self.pipeline.results[k - 1]

    def next_box(self, name: str, target: TargetSpec) -> Box | None:
        """The box stage ``name`` would search if launched from the previous stage's pick (None if it cannot)."""
        k = self.index(name)
        prev = self.parent_result(name)
        if k is None or prev is None or prev.pop == 0 or self.pipeline is None:
            return None
        i = prev.picked if prev.picked is not None else prev.shortlist.first
        if i is None:
            return None
        return self.pipeline.stages[k].box(prev.pick(i))

    # Changing ------------------------------------------------------------------------------

    def keep_branch(self, why: str) -> Branch | None:
        """Keep a copy of the current pipeline (if it has any result) as a branch; the branch it is, if any."""
        pipe = self.pipeline
        if pipe is None or not pipe.lineage:
            return None
        # The leg first: branches of two topologies read alike ("2: predesign #0 by NSGA-II ...", QA walk).
        done = f"{pipe.lineage[-1].mechanism.title} · {branch_stages(pipe.lineage, self.shown)}"
        # Past every number in use: after a restore took one out, len + 1 repeated a number still listed.
        used = [int(b.label.split(":", 1)[0]) for b in self.branches if b.label.split(":", 1)[0].isdigit()]
        text = (f"{done}{_values(pipe.lineage[-1], self.shown)}{_against(pipe.lineage[-1], self.target)} "
                f"({why}, {time.strftime('%H:%M:%S')})")
        target = None if self.target is None else self.target.to_dict()
        data = pipeline_json(pipe)
        for b in self.branches:
            # The same pipeline against the same target is that branch, kept as it is (an undo step may name it): a
            # copy told apart only by the clock piled up at every restore (lag walk, session 25).
            if b.target == target and b.pipeline == data:
                return b
        self.branches.append(Branch(f"{max(used, default=0) + 1}: {text}", data, target, dict(self.shown),
                                    self.next_stage, self.from_pick))
        return self.branches[-1]

    def start_over(self, why: str) -> Branch | None:
        """A new topology in the editor: keep the current pipeline as a branch and start afresh (the first
        stage, from the editor's design; no chart, no candidates); the branch kept, if any."""
        kept = self.keep_branch(why)
        self.pipeline = None
        self.target = None
        self.viewing = None
        self.shown = {}
        self.next_stage = None
        self.from_pick = False
        if not self.status.running:  # "Last run: subtask2 complete" beside "No stage has run yet" otherwise
            self.status = RunStatus()
        self.touch()
        return kept

    def show(self, name: str, member: int) -> StageResult:
        """Show member ``member`` of stage ``name`` (no commitment; the pipeline is unchanged)."""
        r = self.result(name)
        if r is None:
            raise ValueError(f"stage {name!r} has no result to pick from")
        if not 0 <= member < r.pop:
            raise ValueError(f"member {member} out of range (population {r.pop})")
        self.viewing = name
        self.shown[name] = int(member)
        self.touch()
        return r

    def use_for_next(self, name: str, member: int, chain: tuple[ChainStage, ...]) -> str:
        """Commit ``member`` as stage ``name``'s pick and make the next stage the one to run.

        If later stages grew from another pick, the pipeline is first kept as a branch.

        Returns:
            the next stage's name.
        """
        if self.status.running:
            raise ValueError("a stage is running; stop it first")
        pipe = self.pipeline
        k = self.index(name)
        r = self.result(name)
        if pipe is None or k is None or r is None:
            raise ValueError(f"stage {name!r} has no result to pass on")
        if k + 1 >= pipe.n_stages:
            raise ValueError(f"{name} is the last stage of this chain; there is no next stage")
        if not 0 <= member < r.pop:
            raise ValueError(f"member {member} out of range (population {r.pop})")
        later = any(x is not None for x in pipe.results[k + 1 :])
        if later and r.picked != member:
            self.keep_branch(f"before picking #{member} of {name}")
        pipe.select(k, int(member))
        self.shown[name] = int(member)
        nxt = pipe.stages[k + 1].name
        self.next_stage = nxt
        self.from_pick = True
        self.viewing = nxt if self.result(nxt) is not None else name
        self.touch()
        return nxt

    def delete_branch(self, label: str) -> None:
        """Drop the branch with this label (ValueError if there is none)."""
        labels = [b.label for b in self.branches]
        if label not in labels:
            raise ValueError(f"no branch {label!r}")
        del self.branches[labels.index(label)]
        self.touch()

    def restore_branch(self, j: int) -> Branch | None:
        """Make branch j the current pipeline; the current one is kept as a branch in its place, which is returned
        (None if it had no result)."""
        if self.status.running:
            raise ValueError("a stage is running; stop it first")
        if not 0 <= j < len(self.branches):
            raise ValueError(f"no branch {j + 1}")
        chosen = self.branches[j]
        pipe = Pipeline.from_dict(chosen.pipeline)
        for r, d in zip(pipe.results, chosen.pipeline["results"], strict=True):  # kept again, the dicts are shared
            if r is not None:
                result_json(r, d)
        del self.branches[j]
        left = self.keep_branch("left for a branch")
        self.pipeline = pipe
        self.target = None if chosen.target is None else TargetSpec.from_dict(chosen.target)
        last = pipe.lineage[-1] if pipe.lineage else None
        self.viewing = None if last is None else last.name
        names = [st.name for st in pipe.stages]
        if chosen.next_stage in names:  # the Stages panel and the members shown as the branch was left
            self.shown = {k: v for k, v in chosen.shown.items() if k in names}
            self.next_stage, self.from_pick = chosen.next_stage, chosen.from_pick
        elif last is not None:  # an older session's branch: its last stage again, its pick shown
            self.shown = {} if last.picked is None else {last.name: last.picked}
            self.next_stage, self.from_pick = last.name, names.index(last.name) > 0
        else:  # a branch without results (a hand-made file): a fresh start
            self.shown, self.next_stage, self.from_pick = {}, None, False
        # Each stage the branch ran takes the settings it ran with back: the Stages panel showed another branch's
        # algorithm and budget beside the restored result's chart, and Run "again" ran those.
        for r in pipe.results:
            ran = None if r is None else ran_with(r)
            if r is not None and ran is not None:
                self.settings[r.name] = ran
        # The Stages panel's "Last run" line describes the branch's last stage, not what ran before the restore.
        self.status = last_run(last)
        self.touch()
        return left

    def branch_design(self) -> Design | None:
        """The design a restored pipeline stands for: its last stage's shown member (what the editor showed
        when the branch was left), else its passed-on one, else its start."""
        pipe = self.pipeline
        if pipe is None:
            return None
        if pipe.lineage:
            r = pipe.lineage[-1]
            i = self.shown.get(r.name, r.picked)
            if i is not None and 0 <= i < r.pop:
                return Design(r.mechanism, r.X[i:i + 1], r.output)
        return pipe.start

    def plan(self, stage: ChainStage, settings: RunSettings, editor: Design, target: TargetSpec,
             from_pick: bool, chain: tuple[ChainStage, ...]) -> RunPlan:
        """Prepare a run of ``stage`` (ValueError naming the problem if it cannot start).

        From the editor's design: a new pipeline over the chain from ``stage`` on (the old one is
        kept as a branch). From the previous stage's pick: the current pipeline, stage k re-run
        from stage k-1's pick (the pipeline is kept as a branch first if stage k already ran).
        """
        spec = stage_spec(stage, settings, target)
        spec.problem.check_fits(editor.mechanism)  # a session's choice the Problem list no longer offers
        # The algorithm is built here too (cheap, nothing evaluated): settings it refuses (a population too small
        # for CMOEMT, C-TAEA on one objective) stop the click with its reason before the pipeline is switched.
        make_algorithm(spec.algorithm, spec.problem.n_obj, spec.seed)
        if not from_pick:
            c = chain.index(stage)
            specs = [spec] + [stage_spec(s, self.settings_for(s), target) for s in chain[c + 1 :]]
            return RunPlan(Pipeline(specs, editor), 0, None, spec, stage, target)
        pipe = self.pipeline
        k = self.index(stage.name)
        if pipe is None or k is None or k == 0:
            raise ValueError(f"{stage.name} has no previous stage in this pipeline; start it from the editor's design")
        prev = pipe.results[k - 1]
        if prev is None or prev.pop == 0:
            raise ValueError(f"run {pipe.stages[k - 1].name} first (or start {stage.name} from the editor's design)")
        pick = prev.picked if prev.picked is not None else prev.shortlist.first
        if pick is None:
            raise ValueError(f"{prev.name} has no member to start from")
        return RunPlan(pipe, k, int(pick), spec, stage, target)

    def begin(self, plan: RunPlan) -> None:
        """Mark the run started (caller checked nothing runs); switch pipelines or keep a branch as planned."""
        if plan.pipeline is not self.pipeline:
            self.keep_branch("before a new start")
            self.pipeline = plan.pipeline
        elif plan.pipeline.results[plan.index] is not None:
            self.keep_branch(f"before re-running {plan.stage.name}")
        self.target = plan.target
        self.viewing = plan.stage.name
        self.next_stage = plan.stage.name
        self.shown.pop(plan.stage.name, None)
        self.live = None
        self.status = RunStatus("running", plan.stage.name, 0, plan.spec.n_gen, "starting")
        self.touch()

    # JSON ----------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return {
            "pipeline": None if self.pipeline is None else pipeline_json(self.pipeline),
            "branches": [b.to_dict() for b in self.branches],
            **({} if self.target is None else {"target": self.target.to_dict()}),
            "viewing": self.viewing,
            "shown": dict(self.shown),
            "next_stage": self.next_stage,
            "from_pick": self.from_pick,
            "settings": {k: v.to_dict() for k, v in self.settings.items()},
        }

    @staticmethod
    def from_dict(data: object, target: TargetSpec) -> Study:
        """A study saved by :meth:`to_dict`; ValueError naming the first problem.

        A stage whose target was an uploaded curve is pointed at the studio's copy of that curve (the saved
        path may come from another machine). Every curve the file carries (``curves``: each one a pipeline's
        stages ran against; the study's and the branches' targets) is checked, then written to the studio's
        target store, so the pipelines open anywhere; a curve shared by many targets is read once.
        """
        if data is None:
            return Study()
        if not isinstance(data, dict):
            raise ValueError(f"study must be an object, got {type(data).__name__}")
        # Everything but the pipelines first, so a refused file writes nothing to the store.
        raw = data.get("branches") or []
        if not isinstance(raw, list):
            raise ValueError("study branches must be a list")
        parsed: dict[int, Curve] = {}
        carried = data.get("curves") or {}
        if not isinstance(carried, dict):
            raise ValueError("study.curves must map names to curves")
        curves = [_curve(c, f"study.curves[{k}]", parsed) for k, c in carried.items()]
        ran = _target(data.get("target"), "study", parsed)
        states = []
        for j, b in enumerate(raw):
            where = f"branch {j + 1}"
            if not isinstance(b, dict) or not isinstance(b.get("pipeline"), dict):
                raise ValueError(f"{where} must be an object with a pipeline")
            b_next = b.get("next_stage")
            if b_next is not None and not isinstance(b_next, str):
                raise ValueError(f"{where} next_stage must be a stage name, got {b_next!r}")
            states.append((_target(b.get("target"), where, parsed), _shown(b.get("shown") or {}, where), b_next))
        shown = _shown(data.get("shown") or {}, "study")
        settings_raw = data.get("settings") or {}
        if not isinstance(settings_raw, dict):
            raise ValueError("study settings must be an object")
        settings = {str(k): RunSettings.from_dict(v) for k, v in settings_raw.items()}
        viewing, nxt = data.get("viewing"), data.get("next_stage")
        for key, v in (("viewing", viewing), ("next_stage", nxt)):
            if v is not None and not isinstance(v, str):
                raise ValueError(f"study {key} must be a stage name, got {v!r}")
        for t in (ran, *(own for own, _, _ in states)):
            if t is not None and t.curve is not None:
                curves.append(t.curve)
        try:
            for c in {id(c): c for c in curves}.values():
                curve_file(c)
        except OSError as exc:
            raise ValueError(f"cannot write the session's target curves to {CURVE_DIR} ({exc.strerror or exc})") \
                from None
        pipe = _pipeline_from(data.get("pipeline"), target, "pipeline")
        branches = []
        for j, (b, (own, b_shown, b_next)) in enumerate(zip(raw, states, strict=True)):
            _pipeline_from(b["pipeline"], target, f"branch {j + 1}")  # check it loads
            branches.append(Branch(str(b.get("label", f"branch {j + 1}")),
                                   _retarget(b["pipeline"], target, f"branch {j + 1}"),
                                   None if own is None else dict(b["target"]), b_shown, b_next,
                                   bool(b.get("from_pick", False))))
        # The Stages panel's "Last run" line, as a restored branch gets it (it read "Idle" next to a finished stage).
        return Study(pipeline=pipe, branches=branches, viewing=viewing, shown=shown, next_stage=nxt,
                     from_pick=bool(data.get("from_pick", False)), settings=settings, target=ran,
                     status=last_run(pipe.lineage[-1] if pipe is not None and pipe.lineage else None))


def _curve(data: object, where: str, parsed: dict[int, Curve]) -> Curve:
    """A carried curve, read once per object; ValueError naming where it is."""
    if id(data) not in parsed:
        try:
            parsed[id(data)] = Curve.from_dict(data)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
    return parsed[id(data)]


def _target(data: object, where: str, parsed: dict[int, Curve]) -> TargetSpec | None:
    """A saved target (the study's or a branch's), checked; ValueError naming where it is."""
    if data is None:
        return None
    try:
        return TargetSpec.from_dict(data, parsed)
    except ValueError as exc:
        raise ValueError(f"{where} target: {exc}") from None


def _shown(data: object, where: str) -> dict[str, int]:
    """Members shown per stage name, checked; ValueError naming where."""
    if not isinstance(data, dict) or not all(isinstance(v, int) and not isinstance(v, bool) for v in data.values()):
        raise ValueError(f"{where} shown must map stage names to member indices")
    return {str(k): int(v) for k, v in data.items()}


