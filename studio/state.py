"""Session state of the studio: current design, target and playback, behind one lock.

Pure (no viser): every GUI callback and the animation thread go through :class:`Session`,
whose methods are atomic under ``Session.lock``. A design change builds a new immutable
:class:`DesignView` (design + solution + evaluation + metric rows); readers take a snapshot and
draw it without holding the lock. Rules: a parameter edit is refused (``ValueError``, nothing
changes) when the value is not a finite number, a length is <= 0, a non-angle leaves its bounds,
or the edit breaks the assembly of a design that assembles. Loading a preset, a file or a
candidate never fails for assembly: a design that does not assemble is shown where it does,
and edits are then accepted so the designer can repair it.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass, field, replace
from typing import Any

import msgspec
import numpy as np
from numpy.typing import NDArray

from core.analysis.clearance import ground_clearance, rigid
from core.analysis.evaluate import Evaluation, evaluate
from core.analysis.targets import compound_cycloid
from core.formats.design import check_params, design_from_dict, design_to_dict, value_problem
from core.formats.drawing import Plates
from core.formats.session import SESSION_FORMAT, SessionFile, check_session
from core.kinematics import mechanisms, presets
from core.kinematics.checks import MAX_ABS
from core.kinematics.design import Design
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, RTCLM_PRIMARY
from core.kinematics.model import Mechanism
from core.kinematics.params import Param
from core.kinematics.solver import Backend, Solution, solve
from core.optimize.objectives import target_scale
from core.optimize.rtclm import H4_CASES, MODE_HEIGHT, case_h4, is_rtclm, mode_clearance
from core.optimize.scale import entry_bounds
from studio.metrics import (
    Row,
    clearance_rows,
    evaluate_solution,
    feature_labels,
    metric_rows,
    other_mode_row,
    shape_error,
    stance_mask,
)
from studio.session_pack import pack_study, unpack_study
from studio.study import Branch, Selection, Study
from studio.target import Curve, TargetSpec
from studio.walking import PAPER_STEP, WalkFrames, WalkSpec, build_walk, resized, sizes_for

F64 = NDArray[np.float64]

SESSION_VERSION = 6  # 3: stage results stored once by hash, arrays packed (studio.session_pack); 4: branches
# keep the target their stages ran against and the study's state, curves stored once; 5: RTCLM heights in targets;
# 6: the cycloid an uploaded curve replaced (and, from session 29, a stage setting "transmission_min" when set)
DEFAULT_PRESET = "stephenson1/X3"
N_SAMPLES = 360
MAX_SPEED = 10.0
UNDO_DEPTH = 50  # editor changes kept for Undo (each a design view of a few hundred kB)


def _backend() -> Backend:
    """``auto`` (numba) when the fast kernel is importable, else the numpy reference."""
    try:
        import core.kinematics.kernel  # noqa: F401
    except ImportError:
        return "numpy"
    return "auto"


BACKEND: Backend = _backend()


def presets_for(mechanism: str) -> tuple[str, ...]:
    """Names of the registered presets of one mechanism, in registry order."""
    return tuple(name for name, p in presets.PRESETS.items() if p.mechanism.name == mechanism)


@functools.cache
def other_mode(a: Mechanism, b: Mechanism) -> bool:
    """``a`` and ``b`` are the RTCLM's two modes: one leg, the same parameter vector, locked two ways (paper §4)."""
    return a.name != b.name and is_rtclm(a.name) and is_rtclm(b.name)


def same_leg(a: Mechanism, b: Mechanism) -> bool:
    """``a`` and ``b`` are one mechanism, or the RTCLM's two modes (a stage's member shown in the mode on screen)."""
    return a == b or other_mode(a, b)


def mode_preset(preset: str | None, mechanism: str) -> str | None:
    """The preset of the same paper row in ``mechanism``'s mode (``rtclm/case4`` <-> ``rtclm/case4/auxiliary``),
    None if there is none."""
    if preset is None:
        return None
    base = preset.removesuffix("/auxiliary")
    for name in (base, f"{base}/auxiliary"):
        if name in presets.PRESETS and presets.get(name).mechanism.name == mechanism:
            return name
    return None


def opening_preset(mechanism: str) -> str:
    """The preset a topology opens on: its first whose evaluation is feasible (the Metrics panel's "Assembles and
    walks: yes": it assembles and its foot path gives every metric), else its first that assembles, else its first. The
    RTCLM's first rows are paper rows that do not reproduce: "RTCLM, auxiliary mode" opened on a linkage that jams
    for 42 % of the crank cycle. (The RTCLM's own Eqs. 29-31 are its stages' constraints, not checked here.) The
    RTCLM opens on a design of our own that works in both modes and meets case 1's targets (``rtclm/clm-case1``):
    the first feasible paper row was an odd one (h6 159 mm for 50, two gait constraints unmet)."""
    names = presets_for(mechanism)
    if not names:
        raise ValueError(f"{mechanism} has no preset")
    if is_rtclm(mechanism):  # our own design, in this mode
        own = mode_preset("rtclm/clm-case1", mechanism)
        if own is not None:
            return own
    assembles = None
    for name in names:
        design = presets.get(name).design()
        if evaluate(design, N_SAMPLES, backend=BACKEND).violation[0] == 0:
            return name
        if assembles is None and solve(design.mechanism, design.params, N_SAMPLES, output=design.output,
                                       joints=False, derivatives=False, backend=BACKEND).violation[0] == 0:
            assembles = name  # only needed while no feasible one has come: one solve, not one per preset
    return assembles or names[0]


def preset_label(name: str) -> str:
    """Short label of a preset inside its mechanism's list (``stephenson1/X3`` -> ``X3``)."""
    return name.split("/", 1)[1] if "/" in name else name


# Mechanisms the paper designs against its compound cycloid (L 300 mm, H 100 mm); the others (the walkers,
# the four-bar example, RTCLM) get a cycloid scaled to their own path, so MSE compares shapes, not sizes.
PAPER_TARGET = ("stephenson1", "stephenson3", "watt1")


def leg_target(mechanism: str) -> TargetSpec:
    """The target a leg of ``mechanism`` comes with: the paper's cycloid, or its opening preset's."""
    if mechanism in PAPER_TARGET or not presets_for(mechanism):
        return TargetSpec()
    return preset_target(opening_preset(mechanism))


def leg_step(mechanism: str, target: TargetSpec) -> tuple[float, float]:
    """The step (length, height) mm a leg of ``mechanism`` walks against ``target``, which sizes its walking view:
    the cycloid's L and H, an uploaded curve's span (the replaced cycloid's L and H stay hidden in the spec), or the
    paper's for the RTCLM, whose stages aim at crossing heights (h6, h4), not at its fitted curve."""
    if is_rtclm(mechanism):
        return PAPER_STEP
    if target.curve is not None:
        w, h = np.ptp(np.asarray(target.curve.points, dtype=np.float64), axis=0)
        return float(w), float(h)
    return float(target.length), float(target.height)


def walk_sizes(mechanism: str, target: TargetSpec) -> tuple[float, float, float]:
    """The obstacle (a, b) and trunk (mm) the walking view starts with for a leg of ``mechanism`` against
    ``target``: sized with its step (:func:`leg_step`, ``sizes_for``)."""
    return sizes_for(leg_step(mechanism, target))


def preset_target(name: str, period: float = 2.0) -> TargetSpec:
    """The target a preset is shown against: the paper's cycloid for the paper's mechanisms; else a compound
    cycloid as long and as high as the preset's own foot path (rounded to 1 mm), placed on it (the shift,
    flip, direction and start that fit it best, since MSE compares sample by sample), saying so."""
    p = presets.get(name)
    return fitted_target(p.design(), name, period, case_h4(name) or H4_CASES[1])


FITTED = "scaled to the"  # how a fitted target's origin begins ("scaled to the jansen path and placed on it")


def fitted_target(design: Design, name: str, period: float = 2.0, h4: float = H4_CASES[1]) -> TargetSpec:
    """The target a design of its own is shown against, as :func:`preset_target` does for a preset (``name``: what
    the note calls it): the paper's cycloid for the paper's mechanisms, else one fitted to its foot path."""
    if design.mechanism.name in PAPER_TARGET:
        return TargetSpec(period=period, origin="the paper's", h4=h4)
    n = 360
    sol = solve(design.mechanism, design.params[:1], n, output=design.output, backend=BACKEND)
    path = sol.point[0]
    if not np.isfinite(path).all():
        return TargetSpec(period=period, origin=f"the paper's ({name}'s path does not close)", h4=h4)
    span = path.max(axis=0) - path.min(axis=0)
    if float(np.abs(path).max()) > MAX_ABS or float(span.max()) > MAX_ABS:  # a 15 km Jansen leg (review of session
        # 31): a target there is refused everywhere, so none is fitted
        return TargetSpec(period=period, origin=f"the paper's ({name}'s path reaches past {MAX_ABS:g} mm)", h4=h4)
    length, height = max(round(float(span[0])), 1.0), max(round(float(span[1])), 1.0)
    placed = place_cycloid(path, length, height)
    note = f"{FITTED} {name} path and placed on it"
    if is_rtclm(design.mechanism.name):
        note += "; the RTCLM stages optimize h6 and h4, not this curve"
    times = tuple(float(i * period / n) for i in range(n))
    curve = Curve(f"cycloid {length:g} x {height:g} mm on {name}", tuple((float(x), float(y)) for x, y in placed),
                  times, float(period))
    return TargetSpec(length, height, period, curve, note, h4=h4)


def place_cycloid(path: NDArray[np.float64], length: float, height: float) -> NDArray[np.float64]:
    """The compound cycloid of this size, flipped and run either way, started at the sample and shifted by the
    offset that bring it closest to ``path`` (``(n, 2)``, mm) in mean distance, sample by sample."""
    n = len(path)
    base = compound_cycloid(n, length, height)[0]
    best, best_err = base, np.inf
    for flip in (1.0, -1.0):
        for step in (1, -1):
            c = base * np.array([1.0, flip])
            c = c[::step]
            for k in range(n):
                r = np.roll(c, k, axis=0)
                r = r + (path - r).mean(axis=0)
                err = float(np.hypot(*(path - r).T).mean())
                if err < best_err:
                    best, best_err = r, err
    return best


@dataclass(frozen=True)
class DesignView:
    """Everything drawn for one design: immutable, replaced as a whole on every change.

    Attributes:
        design: the one-member design (pop = 1).
        preset: name of the preset it started from, or None.
        target: the target settings.
        solution: kinematics with joints over ``n_samples`` crank angles.
        target_design: ``(n_samples, 2)`` target in the design frame (mm).
        target_leg: ``(n_samples, 2)`` the same target mapped to the leg frame by the output stage (mm).
        evaluation: every paper metric (``core.analysis.evaluate``), pop = 1.
        rows: Metrics panel rows.
        stance: ``(n_samples,)`` True on the stance half-cycle, or None without feature points.
        features: feature points t1 ... t8 as ``(label, (x, y))`` in the leg frame (mm); coincident
            ones share a label.
        walk: walking view settings (the obstacle (a, b) is also ψ's).
        walking: the walking view's geometry, or None without a well-defined bench trajectory.
    """

    design: Design
    preset: str | None
    target: TargetSpec
    solution: Solution
    target_design: F64
    target_leg: F64
    evaluation: Evaluation
    rows: tuple[Row, ...]
    stance: NDArray[np.bool_] | None
    features: tuple[tuple[str, tuple[float, float]], ...]
    walk: WalkSpec = field(default_factory=WalkSpec)
    walking: WalkFrames | None = None

    @property
    def n_samples(self) -> int:
        return int(self.solution.theta.shape[0])

    @property
    def assembles(self) -> bool:
        """True when the mechanism assembles over the whole cycle (and meets its own conditions)."""
        return bool(self.solution.violation[0] == 0.0)

    @property
    def values(self) -> dict[str, float]:
        return self.design.named(0)

    @property
    def edited(self) -> tuple[str, ...]:
        """Parameters that differ from the preset's values (all of them if there is no preset)."""
        names = self.design.mechanism.param_names
        if self.preset is None:
            return names
        ref = presets.get(self.preset).values
        return tuple(n for n, a, b in zip(names, self.design.params[0], ref, strict=True) if a != b)


def build_view(design: Design, preset: str | None, target: TargetSpec, n_samples: int = N_SAMPLES,
               walk: WalkSpec | None = None) -> DesignView:
    """Solve a design (with joints) and derive what the studio shows; never raises for odd designs."""
    walk = walk or WalkSpec()
    sol = solve(design.mechanism, design.params, n_samples, output=design.output, joints=True, backend=BACKEND)
    tgt = target.points(n_samples)
    ev = evaluate_solution(sol, target.target(), target.period, walk.obstacle, walk.trunk)
    assert sol.dleg is not None
    walking = build_walk(sol.leg[0], sol.dleg[0], target.period, walk) if ev.feasible[0] else None
    mode = MODE_HEIGHT.get(design.mechanism.name)  # an RTCLM mode: the height its h_m is, and that target
    height = None if mode is None else (mode, float(getattr(target, mode)))
    # The paper printed S as h_s / 300 mm (its stride), the studio's S is h_s / l_s: both, for the paper's target.
    stride = target.length if height is None and target.curve is None and target.length == 300.0 else None
    extra = clearance_rows(mode_clearance(ground_clearance(sol, design.mechanism, design.output), design.mechanism,
                                          design.params) if rigid(design.output) else None)
    if mode is not None:
        extra += (other_mode_view(design, sol, ev, target, n_samples, walk),)
    return DesignView(design, preset, target, sol, tgt, design.output.apply(tgt), ev,
                      metric_rows(sol, ev, 0, height, stride, extra),
                      stance_mask(ev, n_samples), feature_labels(ev), walk, walking)


def other_mode_view(design: Design, sol: Solution, ev: Evaluation, target: TargetSpec, n_samples: int,
                    walk: WalkSpec) -> Row:
    """The RTCLM's other mode as one Metrics row: the same leg locked the other way, solved and judged."""
    other = RTCLM_AUXILIARY if design.mechanism.name == RTCLM_PRIMARY.name else RTCLM_PRIMARY
    osol = solve(other, design.params, n_samples, output=design.output, joints=True, backend=BACKEND)
    oev = evaluate_solution(osol, target.target(), target.period, walk.obstacle, walk.trunk)
    title = "Auxiliary mode" if other is RTCLM_AUXILIARY else "Primary mode"
    name = MODE_HEIGHT[other.name]
    return other_mode_row(title, osol, oev, mode_clearance(ground_clearance(osol, other, design.output), other,
                                                           design.params),
                          float(ev.y_min[0] - oev.y_min[0]), height=(name, float(getattr(target, name))))


def assembly_reason(view: DesignView) -> str | None:
    """Why a design does not assemble over the whole cycle, or None if it does."""
    sol = view.solution
    if sol.violation[0] == 0.0:
        return None
    if not np.isfinite(sol.violation[0]):
        return "the design has non-finite values"
    bad = ~sol.valid[0]
    if not bad.any():
        return f"the mechanism violates its own conditions (violation {sol.violation[0]:.3g})"
    first = float(np.degrees(sol.theta[np.argmax(bad)]))
    return (
        f"the mechanism does not assemble over {100.0 * bad.mean():.0f} % of the crank cycle "
        f"(first at {first:.0f} deg; violation {sol.violation[0]:.2f} mm)" + grashof_note(view)
    )


def grashof_note(view: DesignView) -> str:
    """Why a four-bar's crank cannot turn fully, by Grashof's rule (``; non-Grashof: s + l = 310 > p + q = 270``),
    or "" (another mechanism, or a four-bar the rule allows)."""
    if view.design.mechanism.name != "fourbar":
        return ""
    v = view.values
    names = {"r1": "the crank AB", "r2": "the coupler BC", "r3": "the rocker DC", "r4": "the ground AD"}
    s, p, q, big = sorted(v[k] for k in names)
    if s + big > p + q:
        return f"; non-Grashof: s + l = {s + big:.4g} > p + q = {p + q:.4g} mm, so no link turns fully"
    shortest = min(names, key=lambda k: v[k])
    if shortest in ("r2", "r3") and v[shortest] < min(v["r1"], v["r4"]):  # a double rocker: AB only rocks
        return f"; Grashof, but the shortest link is {names[shortest]} ({v[shortest]:.4g} mm), so AB only rocks"
    return ""


def leg_scale(mechanism: Mechanism, target: TargetSpec) -> float:
    """The leg's size against the paper's 300 mm stride (``core.optimize.scale``): the target's width / 300 mm;
    1 for the RTCLM (its targets are heights) or a target that cannot be read."""
    if mechanism.derive is not None:
        return 1.0
    try:
        return target_scale(target.option(), 360)
    except (OSError, ValueError):
        return 1.0


PAPER_BOUNDS = ("stephenson1", "stephenson3", "watt1", "fourbar", "rtclm_primary", "rtclm_auxiliary")


def paper_bounds(mechanism: Mechanism) -> bool:
    """Whether a mechanism's parameter bounds are the paper's (its Appendix B-1/C-1 and the four-bar it stands in
    with), not the project's own (Jansen, Klann: the same ranges, set here)."""
    return mechanism.name in PAPER_BOUNDS


def bounds_text(param: Param, k: float = 1.0, paper: bool = True) -> str:
    """``[12, 500] mm (the paper's 30-500 mm, sized to a 120 mm stride)``: a parameter's entry bounds and, when the
    leg's scale moved them, where they come from (rehearsal 4 read "[11.9993, 500]" and took it for physics).
    Printed inside what is taken, at the fields' precision (0.01 mm, 0.0001 rad): "[1.133, 500]" refused 1.1333
    for a bound of 1.13333 (review of session 29). ``paper``: the bounds are the paper's (``paper_bounds``)."""
    lo, hi = entry_bounds(param, k)
    step = 0.01 if param.unit == "mm" else 1e-4
    inner_lo = lo if lo == round(lo / step) * step else math.ceil(lo / step - 1e-9) * step
    inner_hi = hi if hi == round(hi / step) * step else math.floor(hi / step + 1e-9) * step
    digits = 2 if param.unit == "mm" else 4  # fixed decimals: ":.6g" rounded 10000.87 out to 10000.9 (review, s30)

    def fixed(v: float) -> str:
        return f"{v:.{digits}f}".rstrip("0").rstrip(".") if math.isfinite(v) else f"{v:g}"

    text = f"[{fixed(inner_lo)}, {fixed(inner_hi)}] {param.unit}"
    if (lo, hi) != (param.lo, param.hi):
        whose = "the paper's" if paper else "the global"
        text += (f" ({whose} {param.lo:g}-{param.hi:g} {param.unit} for a 300 mm stride, sized to this target's "
                 f"{300 * k:.4g} mm)")
    return text


def check_value(param: Param, value: object, k: float = 1.0, paper: bool = True) -> float:
    """A typed value for one parameter, or ValueError with the reason (name, unit, bounds).

    Lengths must be > 0; every non-angle must lie within the parameter's global bounds (for a leg of scale
    ``k``, ``core.optimize.scale.entry_bounds``);
    angles are periodic and need only be finite and within +-1e6 rad (the design files' limit: a session
    holding more would not load back).
    """
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{param.name} must be a number ({param.unit}), got {value!r}")
    v = float(value)
    lo, hi = entry_bounds(param, k)
    # Bounds first: 1e9 for a length read "must be within +-1e+06 mm" (the file format's limit), not its own bounds.
    # (A length at or below 0 still reads "must be > 0".)
    if param.kind != "angle" and math.isfinite(v) and not (param.kind == "length" and v <= 0) and not lo <= v <= hi:
        raise ValueError(f"{param.name} = {v:g} {param.unit} is outside its bounds {bounds_text(param, k, paper)}")
    problem = value_problem(param, v)  # what any design file refuses too
    if problem is not None:
        raise ValueError(problem)
    if param.kind != "angle" and not lo <= v <= hi:
        raise ValueError(f"{param.name} = {v:g} {param.unit} is outside its bounds {bounds_text(param, k, paper)}")
    return v


def change_summary(a: DesignView, b: DesignView) -> str:
    """What differs from view ``a`` to view ``b``, in a few words: the topology, the preset, up to three
    parameter names, the target, the walking view ("topology → Theo Jansen leg", "r4, r5", "preset → X3 · target")."""
    if a.design.mechanism != b.design.mechanism:
        return f"topology → {b.design.mechanism.title}"
    parts = []
    if a.preset != b.preset:
        parts.append(f"preset → {preset_label(b.preset) if b.preset is not None else '(none)'}")
    names = [n for n, x, y in zip(a.design.mechanism.param_names, a.design.params[0], b.design.params[0],
                                  strict=True) if x != y]
    if names and not parts:
        # A few edits by name; a run's pick or a restored branch changes most of them ("b, g, x_a and 13 more").
        if len(names) == len(a.design.mechanism.param_names) and len(names) > 5:
            parts.append("design")
        elif len(names) > 5:
            parts.append(f"{len(names)} parameters")
        else:
            parts.append(", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else ""))
    if a.design.output != b.design.output:
        parts.append("output stage")
    if a.target != b.target:
        parts.append("target")
    if a.walk != b.walk:
        parts.append("walking view")
    return " · ".join(parts)


@dataclass(frozen=True)
class Step:
    """An editor state Undo or Redo brings back, the branch a topology switch kept when it was left (its
    stages are restored with it), and what the study showed, had picked and would run next then (brought back
    while the pipeline holds the same populations: a pick or a pass-on taken back)."""

    view: DesignView
    branch: Branch | None = None
    selection: Selection | None = None
    cause: str = ""  # what made the change, when its diff says it badly ("subtask2's pick", not "15 parameters")


@dataclass(frozen=True)
class Playback:
    """Animation state: playing, speed (x real time, one revolution per target period T), crank angle (rad)."""

    playing: bool = True
    speed: float = 1.0
    angle: float = 0.0


@dataclass
class Session:
    """The studio's shared state. Thread-safe: every method takes ``lock``.

    Args:
        view: the current design view (its design must assemble).
        playback: animation state.
    """

    view: DesignView
    playback: Playback = field(default_factory=Playback)
    lock: threading.RLock = field(default_factory=threading.RLock, repr=False, compare=False)
    version: int = 0
    study: Study = field(default_factory=Study)
    undone: list[Step] = field(default_factory=list, repr=False, compare=False)  # what Undo brings back
    redone: list[Step] = field(default_factory=list, repr=False, compare=False)  # what Redo brings back
    # The cycloid an upload replaced, as it was (its T too: a curve's period took its place), for going back to it.
    cycloid: TargetSpec | None = field(default=None, repr=False, compare=False)
    # How the drawings' parts are made (Pin hole Ø): the designer's, saved with the session (review of session 29:
    # it lived on the panel, and a reload put 5 mm holes back in the DXF without a word).
    plates: Plates = field(default_factory=Plates, compare=False)

    @classmethod
    def default(cls, preset: str = DEFAULT_PRESET, target: TargetSpec | None = None) -> Session:
        """A session on a preset (the paper's Stephenson-I X3 by default), animating, as the Topology and Preset
        dropdowns load it: the paper's target for the paper's mechanisms, else one fitted to the preset's path
        (``preset_target``), an RTCLM case's preset with that case's h4, and the walking view sized to the leg
        (``walk_sizes``). (Until session 39 every preset got the paper's cycloid and obstacle: a Jansen leg read MSE
        206 mm here and 2.3 mm in the studio.)"""
        design = presets.get(preset).design()
        if target is None:
            target = (TargetSpec(h4=case_h4(preset) or H4_CASES[1]) if design.mechanism.name in PAPER_TARGET
                      else preset_target(preset))
        walk = resized(WalkSpec(), walk_sizes(design.mechanism.name, target))
        return cls(build_view(design, preset, target, walk=walk))

    def _rebuild(self, design: Design, preset: str | None, target: TargetSpec | None = None,
                 walk: WalkSpec | None = None) -> DesignView:
        v = self.view
        t = target or v.target
        if walk is None:
            walk = v.walk
            if design.mechanism.name != v.design.mechanism.name and "uploaded" not in (t.origin, v.target.origin):
                old = v.design.mechanism.name  # another leg's size: the sizes the old leg started with, for the
                # target shown or its own (a target edited since kept the walk the leg came with; fitted only if
                # needed: ~50 ms)
                now = (float(walk.a), float(walk.b), float(walk.trunk))
                if now == walk_sizes(old, v.target) or now == walk_sizes(old, leg_target(old)):
                    walk = resized(walk, walk_sizes(design.mechanism.name, t))
        return build_view(design, preset, t, v.n_samples, walk)

    def snapshot(self) -> tuple[DesignView, Playback, int]:
        """The current view, playback and version, read together."""
        with self.lock:
            return self.view, self.playback, self.version

    def _commit(self, view: DesignView, keep_assembly: bool = False, into: list[Step] | None = None,
                selection: Selection | None = None, cause: str = "", left: Branch | None = None) -> DesignView:
        """Make ``view`` current; with ``keep_assembly``, refuse to lose the assembly of the current design.
        The replaced view, with the branch a topology switch kept (or ``left``, the pipeline a branch restore just
        kept as a branch), goes onto ``into``: by default the Undo history (and what was undone is forgotten); Undo
        and Redo pass each other's."""
        if keep_assembly and self.view.assembles and not view.assembles:
            raise ValueError(assembly_reason(view))
        old, new = self.view.design.mechanism, view.design.mechanism
        if self.study.status.running and view.design is not self.view.design:
            # The run's pick replaces the editor's design when it ends: an edit made meanwhile would be lost.
            what = "switching the mechanism" if new.name != old.name else "editing the design"
            raise ValueError(f"a stage is running, and its pick replaces the design when it ends; stop it or wait "
                             f"before {what}")
        pipe = self.study.pipeline
        kept = left
        if (left is None and new.name != old.name and pipe is not None and pipe.start.mechanism.name != new.name
                and not other_mode(pipe.start.mechanism, new)):  # the RTCLM's other mode: the same leg's stages
            kept = self.study.start_over(f"before switching to {new.title}")
        if view is not self.view:
            self._remember(Step(self.view, kept, selection or self.study.selection(), cause), into)
        self.view = view
        self.version += 1
        return view

    # Undo ---------------------------------------------------------------------------------

    def _remember(self, step: Step, into: list[Step] | None = None) -> None:
        """Put ``step`` on the Undo history (what was undone is forgotten), or onto ``into``."""
        if into is None:
            self.undone, self.redone = [*self.undone[-(UNDO_DEPTH - 1):], step], []
        else:
            into.append(step)

    def pass_on(self, stage: str, member: int, chain: tuple[Any, ...]) -> str:
        """``Study.use_for_next`` as a step Undo takes back (the pick, the next stage and where it starts)."""
        with self.lock:
            before = self.study.selection()
            nxt = self.study.use_for_next(stage, member, chain)
            self._remember(Step(self.view, None, before))
            return nxt

    def undo(self) -> DesignView:
        """Bring back the editor as it was before its last change (design, preset, target, walking view: a
        parameter, a preset, a topology, a pick, a run's end); ValueError if there is none or a stage runs.
        The study is not rewound, except that undoing a topology switch restores the branch the switch kept, and
        undoing a branch restore the pipeline the restore left (whatever ran since is kept as a branch in turn)."""
        with self.lock:
            return self._step(self.undone, self.redone, "undo")

    def redo(self) -> DesignView:
        """Make again the change the last :meth:`undo` took back; ValueError if there is none or a stage runs."""
        with self.lock:
            return self._step(self.redone, self.undone, "redo")

    def _step(self, source: list[Step], sink: list[Step], what: str) -> DesignView:
        if not source:
            raise ValueError(f"nothing to {what}")
        step, study = source[-1], self.study
        # The step's branch, or the one holding the same stages (each restore keeps the pipeline it leaves as a new
        # branch: a second restore and two Undos found none, review of session 36).
        kept = [j for j, b in enumerate(study.branches) if b is step.branch] or [
            j for j, b in enumerate(study.branches) if step.branch is not None
            and b.pipeline == step.branch.pipeline and b.target == step.branch.target]
        # The branch a topology switch or a restore kept (not deleted since): its stages come back with the design,
        # and the pipeline they replace is the branch the step back restores.
        left = study.restore_branch(kept[0]) if kept else None
        before = study.selection()
        if step.view is self.view:  # a pass-on: only the study's selection moves
            if study.status.running:
                raise ValueError(f"a stage is running; stop it or wait before you {what} a pass-on")
            self._remember(Step(self.view, left, before), sink)
        else:
            self._commit(step.view, into=sink, selection=before, cause=step.cause, left=left)
        if step.selection is not None:
            study.reselect(step.selection)
        source.pop()
        return self.view

    def change_names(self, which: str) -> str:
        """What :meth:`undo` (``which="undo"``) or :meth:`redo` would change, in a few words ("" if nothing)."""
        with self.lock:
            stack = self.undone if which == "undo" else self.redone
            if not stack:
                return ""
            step, now = stack[-1], self.study.selection()
            text = step.cause or change_summary(self.view, step.view)
            sel = step.selection if step.selection is not None and self.study.holds(step.selection) else None
            if sel is not None and (sel.picks, sel.next_stage) != (now.picks, now.next_stage):
                text = " · ".join(t for t in (text, "pass-on") if t)
            elif sel is not None and sel.shown != now.shown and not text.startswith("topology"):
                text = "pick"  # another member shown: that is what Undo takes back, not its parameters or preset
            return text or "the same design"

    # Design -------------------------------------------------------------------------------

    def load_preset(self, name: str) -> DesignView:
        """Switch to a registered preset; ValueError (state unchanged) if the name is unknown.

        A preset of another mechanism brings its own target (``preset_target``) unless the designer uploaded
        the target; within one mechanism the target stays as it is.
        """
        p = presets.get(name)
        with self.lock:
            view = self._commit(self._rebuild(p.design(), name, self._target_for(p.mechanism.name, name)))
            self._from_editor()
            return view

    def _from_editor(self) -> None:
        """The designer changed the design by hand: the next run starts from it, not from the previous stage's
        pick (Run searched around the old pick and then replaced the preset just loaded with its result)."""
        if self.study.from_pick:
            self.study.from_pick = False
            self.study.touch()

    def _target_for(self, mechanism: str, preset: str | None, design: Design | None = None,
                    label: str = "") -> TargetSpec:
        """The target a design of ``mechanism`` brings into the editor: the current one within the editor's
        mechanism (or its other RTCLM mode) or when the designer uploaded the target, else ``preset``'s own
        (``preset_target``), or one fitted to ``design`` (a loaded file, called ``label``: it kept the other
        mechanism's target, and a Jansen leg read MSE 206 mm where its preset reads 2.3).
        For the RTCLM the h4 follows a case's preset unless the designer set it by hand, and an h6 set stays."""
        v = self.view
        old = v.design.mechanism
        keep = (mechanism == old.name or v.target.origin == "uploaded"
                or other_mode(old, mechanisms.get(mechanism)))  # the same leg in its other mode: its target
        if keep:
            t = v.target
        elif design is not None:
            t = fitted_target(design, label or "loaded design", v.target.period)
            if not t.origin.startswith(FITTED) and mechanism not in PAPER_TARGET:
                # A path that does not close has nothing to fit: its mechanism's opening preset's target, which a
                # later file refits (the paper's cycloid in its place stopped that; review of session 31).
                t = preset_target(opening_preset(mechanism), v.target.period)
        else:
            assert preset is not None
            t = preset_target(preset, v.target.period)
        if is_rtclm(mechanism):  # the heights: a case's h4 unless the designer set one; a typed h6 stays
            was = is_rtclm(old.name)
            untouched = not was or v.target.h4 == (case_h4(v.preset) or H4_CASES[1])
            case = case_h4(preset)
            h4 = case if untouched and case is not None else (v.target.h4 if was else t.h4)
            t = replace(t, h6=v.target.h6 if was else t.h6, h4=h4)
        return t

    def select_mechanism(self, name: str) -> DesignView:
        """Switch topology: loads the mechanism's opening preset (``opening_preset``); from one of the RTCLM's
        modes to the other, the same leg in that mode (its design, target and stages stay)."""
        mech = mechanisms.get(name)
        with self.lock:
            v = self.view
            if mech.name == v.design.mechanism.name:
                return v
            if other_mode(v.design.mechanism, mech):  # it loaded a preset, and the leg's stages went to a branch
                design = Design(mech, v.design.params, v.design.output)
                return self._commit(self._rebuild(design, mode_preset(v.preset, mech.name), v.target))
            if not presets_for(mech.name):
                raise ValueError(f"{mech.title} has no preset yet; there is no design to start from")
            return self.load_preset(opening_preset(mech.name))

    def reset_to_preset(self) -> DesignView:
        """Back to the values of the preset the design started from."""
        with self.lock:
            if self.view.preset is None:
                raise ValueError("the design did not start from a preset")
            return self.load_preset(self.view.preset)

    def set_param(self, name: str, value: object) -> DesignView:
        """Change one parameter and re-solve; ValueError (state unchanged) with the reason if invalid.

        Invalid: not a finite number, a length <= 0, a non-angle outside its bounds, or an
        assembling design that would stop assembling.
        """
        with self.lock:
            design = self.view.design
            names = design.mechanism.param_names
            if name not in names:
                raise ValueError(f"{design.mechanism.name} has no parameter {name!r}; it has {', '.join(names)}")
            v = check_value(design.mechanism.params[names.index(name)], value,
                            leg_scale(design.mechanism, self.view.target), paper_bounds(design.mechanism))
            if v == design.named(0)[name]:
                return self.view
            new = design.replace(**{name: v})
            view = self._commit(self._rebuild(new, self.view.preset), keep_assembly=True)
            self._from_editor()
            return view

    def set_design(self, design: Design, preset: str | None = None, by_hand: bool = False,
                   cause: str = "", refit: bool = False) -> DesignView:
        """Replace the whole design (a loaded file, a picked candidate); ValueError if malformed. ``by_hand``:
        the designer brought it (a study's design), so the next run starts from it. ``cause`` names the change
        on the Undo button ("subtask2's pick"). ``refit``: a design file, which gets a target fitted to its own
        path when the editor's was fitted to another design's (a Jansen leg scaled x0.4 read MSE 58.6 mm against
        the preset's target, 0.99 against its own: it depended on what the editor showed before)."""
        if design.pop != 1:
            raise ValueError(f"the studio shows one design at a time, got a population of {design.pop}")
        check_params(design.mechanism, design.params)
        with self.lock:
            shown = self.view.design.mechanism
            if not by_hand and other_mode(shown, design.mechanism):
                # A stage's member of the RTCLM is the same leg: shown in the mode on screen (rehearsal 7 picked an
                # rtclm2 candidate while showing the auxiliary mode, and the editor flipped to the primary one).
                design = Design(shown, design.params, design.output)
            target = None
            if design.mechanism.name != self.view.design.mechanism.name:  # a file or a study's design of another
                target = self._target_for(design.mechanism.name, preset, design, preset or cause or "")
            elif refit and self.view.target.origin.startswith(FITTED):  # not the paper's, uploaded or typed
                t = fitted_target(design, cause or "loaded design", self.view.target.period)
                # A path that does not close has nothing to fit: the target stays (the paper's cycloid in its place
                # stopped every later file from being refitted; review of session 30).
                if t.origin.startswith(FITTED):
                    target = replace(t, h6=self.view.target.h6, h4=self.view.target.h4)
            view = self._commit(self._rebuild(design, preset, target), cause=cause)
            if by_hand:
                self._from_editor()
            return view

    def set_target(self, **changes: float) -> DesignView:
        """Change the compound cycloid (``length``, ``height``, ``period``); ValueError if not positive.

        Editing the cycloid while an uploaded curve is the target goes back to the cycloid.
        """
        with self.lock:
            target = replace(self.view.target, curve=None, origin="set by hand", **changes)
            paper = TargetSpec(origin="the paper's", h6=target.h6, h4=target.h4)  # the heights are not the curve's
            if replace(target, origin=paper.origin) == paper and self.view.design.mechanism.name in PAPER_TARGET:
                target = paper  # typed back to the paper's values: it is the paper's again, not "set by hand"
            if target == self.view.target:
                return self.view
            v = self.view
            return self._commit(self._rebuild(v.design, v.preset, target))

    def set_heights(self, **changes: float) -> DesignView:
        """Change the RTCLM's targets (``h6``, ``h4``, mm); ValueError if not positive. The curve stays."""
        with self.lock:
            t = self.view.target
            target = replace(t, h6=changes.get("h6", t.h6), h4=changes.get("h4", t.h4))
            if target == self.view.target:
                return self.view
            v = self.view
            return self._commit(self._rebuild(v.design, v.preset, target))

    def set_curve(self, curve: Curve | None) -> DesignView:
        """Make an uploaded curve the target (None: back to the compound cycloid)."""
        with self.lock:
            v = self.view
            target = v.target.with_curve(curve)
            if curve is not None and v.target.curve is None:
                self.cycloid = v.target
            if curve is None and v.target.curve is not None:  # back to the cycloid it replaced, with today's heights
                was = self.cycloid or TargetSpec(v.target.length, v.target.height)  # (a version-5 file: T's default)
                target = replace(was, h6=v.target.h6, h4=v.target.h4)
            if target == v.target:
                return v
            return self._commit(self._rebuild(v.design, v.preset, target))

    def set_walk(self, **changes: object) -> DesignView:
        """Change the walking view (``layout``, ``a``, ``b``, ``place``, ``trunk``); ValueError if invalid."""
        with self.lock:
            v = self.view
            walk = replace(v.walk, **changes)  # type: ignore[arg-type]
            if walk == v.walk:
                return v
            return self._commit(self._rebuild(v.design, v.preset, walk=walk))

    # Playback -----------------------------------------------------------------------------

    def set_playing(self, playing: bool) -> Playback:
        with self.lock:
            self.playback = replace(self.playback, playing=bool(playing))
            return self.playback

    def set_speed(self, speed: float) -> Playback:
        """Playback speed as a multiple of real time (0 < speed <= MAX_SPEED)."""
        if not (math.isfinite(speed) and 0.0 < speed <= MAX_SPEED):
            raise ValueError(f"speed must be in (0, {MAX_SPEED:g}], got {speed}")
        with self.lock:
            self.playback = replace(self.playback, speed=float(speed))
            return self.playback

    def scrub(self, angle: float) -> Playback:
        """Jump to a crank angle (rad) and pause, as dragging a time slider does."""
        if not math.isfinite(angle):
            raise ValueError(f"crank angle must be finite, got {angle}")
        with self.lock:
            self.playback = Playback(False, self.playback.speed, angle % (2.0 * math.pi))
            return self.playback

    def advance(self, dt: float) -> Playback:
        """Move the crank by ``dt`` seconds of playback if playing (one revolution per target period)."""
        with self.lock:
            pb = self.playback
            if pb.playing and dt > 0.0:
                step = 2.0 * math.pi * pb.speed * dt / self.view.target.period
                self.playback = replace(pb, angle=(pb.angle + step) % (2.0 * math.pi))
            return self.playback

    # Files --------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The session as JSON-ready data: design, preset, target, walk, playback and the study
        (pipeline, branches, picks, run settings)."""
        with self.lock:
            v, pb = self.view, self.playback
            return {
                "format": SESSION_FORMAT,
                "version": SESSION_VERSION,
                "design": design_to_dict(v.design),
                "preset": v.preset,
                "target": v.target.to_dict(),
                "walk": v.walk.to_dict(),
                "playback": {"playing": pb.playing, "speed": pb.speed, "angle": pb.angle},
                "study": pack_study(self.study.to_dict()),
                **({"cycloid": self.cycloid.to_dict()} if self.cycloid is not None and v.target.curve is not None
                   else {}),
                **({"plates": {"hole": self.plates.hole, "width": self.plates.width}}
                   if self.plates != Plates() else {}),
            }

    @classmethod
    def from_dict(cls, data: object) -> Session:
        """A session from :meth:`to_dict` data (or a version-1 file); ValueError naming the first problem.

        Never any other exception: whatever a hand-edited or hostile file holds, it is refused with one
        message (``core.formats.session`` checks the shell first; the parts are checked by their decoders).
        """
        f = check_session(data)
        try:
            return cls._from_checked(f)
        except ValueError:
            raise
        except (TypeError, AttributeError, KeyError, IndexError, OverflowError, RecursionError) as exc:
            raise ValueError(f"malformed session ({type(exc).__name__}: {exc})") from None

    @classmethod
    def _from_checked(cls, f: SessionFile) -> Session:
        design = design_from_dict(f.design)
        preset = f.preset
        if preset is not None and (preset not in presets.PRESETS or presets.get(preset).mechanism != design.mechanism):
            preset = None
        target = TargetSpec.from_dict(f.target)
        walk = WalkSpec.from_dict(f.walk)
        view = build_view(design, preset, target, walk=walk)
        pb = f.playback
        study = None if f.study is None else unpack_study(msgspec.to_builtins(f.study))
        session = cls(view, study=Study.from_dict(study, target))
        session.set_speed(float(pb.speed))
        session.playback = Playback(pb.playing, float(pb.speed), float(pb.angle) % (2.0 * math.pi))
        if f.cycloid is not None and target.curve is not None:
            try:
                session.cycloid = TargetSpec.from_dict(f.cycloid)
            except ValueError as exc:
                raise ValueError(f"cycloid: {exc}") from None
            if session.cycloid.curve is not None:
                raise ValueError("cycloid: must be a compound cycloid (L, H, T), not a curve")
        if f.plates is not None:
            try:
                session.plates = Plates(float(f.plates.hole), None if f.plates.width is None else float(f.plates.width))
            except ValueError as exc:
                raise ValueError(f"plates: {exc}") from None
        return session

    def restore_branch(self, j: int) -> DesignView:
        """Branch j becomes the current pipeline and its design the editor's (mechanism, parameters, output),
        with the target its stages ran against (an older session's branch, which did not keep it: its
        mechanism's target when it is another topology's, as switching topology does)."""
        with self.lock:
            left = self.study.restore_branch(j)
            design = self.study.branch_design()
            if design is None:
                return self.view
            target = self.study.target
            if target is None:
                name = design.mechanism.name
                target = self._target_for(name, opening_preset(name)) if presets_for(name) else None
            return self._commit(self._rebuild(design, None, target), cause="branch restore", left=left)

    def holds_work(self) -> bool:
        """True when replacing this session would lose something the designer made: a stage result, a branch, an
        edit or an Undo history."""
        with self.lock:
            return (self.study.pipeline is not None or bool(self.study.branches) or bool(self.view.edited)
                    or bool(self.undone))

    def summary(self) -> str:
        """``Stephenson-I six-bar, 3 stage results, 6 branches, last run subtask3; editor: stephenson1/X3 (edited),
        MSE 4.76 mm``: what a session holds, in words (two sessions of one pipeline read alike without the editor's
        design, which a rehearsal had changed)."""
        with self.lock:
            study, v = self.study, self.view
            runs = sum(r is not None for r in study.pipeline.results) if study.pipeline is not None else 0
            last = study.status.stage
            who = v.preset or "a design of its own"
            mse = shape_error(v.evaluation)  # the Metrics row's: the best phase for a target without times
            return (f"{v.design.mechanism.title}, {runs} stage result{'s' * (runs != 1)}, "
                    f"{len(study.branches)} branch{'es' * (len(study.branches) != 1)}"
                    + (f", last run {last}" if last else "")
                    + f"; editor: {who}{' (edited)' if v.edited else ''}"
                    + (f", MSE {mse:.3g} mm" if math.isfinite(mse) else ", not assembled"))

    def set_plates(self, plates: Plates) -> None:
        """The drawings' pin holes and plate width (mm), kept with the session."""
        with self.lock:
            self.plates = plates
            self.version += 1

    def restore(self, other: Session) -> None:
        """Take over another session's state (a loaded file) in one step; ValueError while a stage runs."""
        with self.lock:
            if self.study.status.running:
                raise ValueError("a stage is running; stop it before loading a session")
            self.undone, self.redone = [], []  # a loaded session is another piece of work
            self.cycloid = other.cycloid
            self.plates = other.plates
            self.view = other.view
            self.playback = other.playback
            self.study = other.study
            self.study.touch()
            self.version += 1
