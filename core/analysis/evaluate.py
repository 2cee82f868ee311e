"""The whole analysis stack for a population: solve -> feature points -> metrics -> shape error.

``evaluate(design)`` returns an ``Evaluation`` of ``(pop,)`` arrays; ``Evaluation.record(i)`` is
member i as a JSON-ready dict (the ``clm evaluate --json`` object).

Feasibility here means "a well-defined bench trajectory": the mechanism assembles over the whole
cycle, the path has exactly one landing/take-off pair and is a simple closed curve. The paper's
gait constraints (Eq. 30 order and 15 degree angles, Eq. 31) are reported separately as
``constraints`` (pymoo convention, <= 0 satisfied): the §3 designs were never held to them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from functools import lru_cache
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from core.analysis import metrics as M
from core.analysis.clearance import from_lowest, ground_clearance
from core.analysis.features import DEFAULT_PERIOD, FEATURE_NAMES, FeaturePoints, feature_points, periodic_derivative
from core.analysis.gait import BIPED, DEFAULT_TRUNK, quadruped, walking_trajectory
from core.analysis.shape import mse as shape_mse
from core.analysis.shape import mse_phase_optimal
from core.analysis.targets import Target, cycloid_target
from core.kinematics import checks
from core.kinematics.design import Design
from core.kinematics.solver import worst_transmission

F64 = NDArray[np.float64]
Backend = Literal["auto", "numpy", "numba"]

CONSTRAINT_NAMES = ("order", "theta1", "theta2", "h_bar", "psi2")
CONSTRAINT_UNITS = ("rad", "rad", "rad", "mm", "1")
# The unit of each value of ``Evaluation.record`` ("1": a fraction, "-": a yes/no fact): one gate written as psi2 > 20
# or theta1 >= 15 would be off by 100x or 57x without it (rehearsal 8). The human table prints deg and %.
RECORD_UNITS = {
    "feasible": "-", "violation": "mm", "kinematic_violation": "mm", "path_violation": "mm", "l_s": "mm",
    "h_s": "mm", "S": "%", "I": "mm/s", "theta1": "rad", "theta2": "rad", "landing_speed": "mm/s", "width": "mm",
    "y_min": "mm", "step_length": "mm", "h_m": "mm", "h_bar": "mm", "psi2": "1", "psi4": "1", "mse": "mm",
    "mse_phase": "mm", "crank_margin": "mm", "transmission": "deg", "clearance": "mm", "obstacle": "mm",
    "trunk": "mm", "period": "s", "n_samples": "-", "feature_points": "t: s, x and y: mm (leg frame)",
    "constraints": dict(zip(CONSTRAINT_NAMES, CONSTRAINT_UNITS, strict=True)),
}
CONSTRAINT_TEXT = {  # each constraint as a designer says it met
    "order": "order t1 -> t2 -> t5 -> t4 (Eq. 30)",
    "theta1": "landing angle theta1 >= 15 deg",
    "theta2": "take-off angle theta2 >= 15 deg",
    "h_bar": "mean swing height h_bar > h_m / 4 (Eq. 31)",
    "psi2": "psi2 > 20 % (Eq. 31)",
}
DEFAULT_OBSTACLE = (25.0, 25.0)
MIN_SAMPLES = 8  # fewer samples cannot place two landing roots and a swing; 0 or 1 used to hang the kernel


@dataclass(frozen=True)
class Evaluation:
    """Every metric of a population, ``(pop,)`` unless noted. Units mm, rad, s, mm/s, %.

    Attributes:
        feasible: violation == 0.
        violation: kinematic + path violation (>= 0).
        kinematic_violation: the solver's assembly violation (mm).
        path_violation: extra landing roots (mm) + 1 per excess turn of a self-intersecting path.
        l_s, h_s, S, I: stance length, stance fluctuation, straightness (%, h_s / l_s), impact (mm/s).
        theta1, theta2: landing and take-off angles (rad).
        landing_speed: signed vertical foot speed at landing (mm/s).
        width, y_min: design-frame path width and lowest y (the f2 and f3 inputs, spec §3).
        step_length: walking-trajectory step (2 l_s).
        h_m, h_bar: maximum and mean swing height above ground.
        psi2, psi4: crossing probabilities of the obstacle (biped module, quadruped).
        mse: time-aligned shape error against the target; mse_phase: at the best cyclic shift
            (NaN unless requested).
        times: ``(pop, 8)`` t1 ... t8 (s); points: ``(pop, 8, 2)`` leg-frame positions.
        constraints: ``(pop, 5)`` Eq. 30-31 values, columns ``CONSTRAINT_NAMES`` (<= 0 satisfied).
        crank_margin: the crank loops' exact full-rotation margin (mm, ``Solution.crank_margin``; +inf if the
            crank closes no loop, NaN for paths without a design): how far the design is from a dead point.
        transmission: the worst transmission angle over the cycle and every dyad, ``min(mu, 180 - mu)`` in
            **degrees**, the unit of the design rule (40 deg or more is the usual demand, 90 ideal; near 0 a dyad
            passes close to its dead point and transmits almost no force); NaN where the design does not assemble
            over the whole cycle and for paths without a design (``solver.worst_transmission``).
        clearance: the ground clearance (mm, ``core.analysis.clearance``): how far the lowest joint but the foot
            stays above the foot's lowest level over the cycle, < 0 when it goes below (the leg would strike the
            ground, or works upside down); NaN where the design does not assemble, its output stage is a
            pantograph (k != 1, whose bars are not modelled) and for paths without a design.
    """

    feasible: NDArray[np.bool_]
    violation: F64
    kinematic_violation: F64
    path_violation: F64
    l_s: F64
    h_s: F64
    S: F64
    I: F64  # noqa: E741 - the paper's name
    theta1: F64
    theta2: F64
    landing_speed: F64
    width: F64
    y_min: F64
    step_length: F64
    h_m: F64
    h_bar: F64
    psi2: F64
    psi4: F64
    mse: F64
    mse_phase: F64
    times: F64
    points: F64
    constraints: F64
    obstacle: tuple[float, float]
    trunk: float
    period: float
    n_samples: int
    target: str
    crank_margin: F64
    transmission: F64
    clearance: F64

    @property
    def pop(self) -> int:
        return int(self.violation.shape[0])

    def record(self, i: int = 0) -> dict[str, Any]:
        """Member i as a dict of plain Python values (NaN stays float NaN; the CLI maps it to null)."""
        out: dict[str, Any] = {}
        skip = {"times", "points", "constraints", "obstacle", "trunk", "period", "n_samples", "target"}
        for f in fields(self):
            if f.name in skip:
                continue
            v = getattr(self, f.name)[i]
            out[f.name] = bool(v) if f.name == "feasible" else float(v)
        out["obstacle"] = list(self.obstacle)
        out["trunk"] = self.trunk
        out["period"] = self.period
        out["n_samples"] = self.n_samples
        out["target"] = self.target
        out["constraints"] = {n: float(v) for n, v in zip(CONSTRAINT_NAMES, self.constraints[i], strict=True)}
        out["feature_points"] = {
            n: {"t": float(self.times[i, k]), "x": float(self.points[i, k, 0]), "y": float(self.points[i, k, 1])}
            for k, n in enumerate(FEATURE_NAMES)
        }
        return out


def _numba_ready(backend: Backend) -> bool:
    if backend == "numpy":
        return False
    try:
        import core.kinematics.kernel  # noqa: F401
    except ImportError:
        if backend == "numba":
            raise
        return False
    return True


def evaluate(
    design: Design,
    n_samples: int = 360,
    *,
    target: Target | None = None,
    period: float = DEFAULT_PERIOD,
    obstacle: tuple[float, float] = DEFAULT_OBSTACLE,
    trunk: float = DEFAULT_TRUNK,
    backend: Backend = "auto",
    phase_optimal: bool = False,
) -> Evaluation:
    """Solve a population and compute every metric.

    Args:
        design: mechanism, ``(pop, n_params)`` parameters and output stage.
        n_samples: crank samples per revolution, even (t + T/2 falls on a sample), 8 to 100 000.
        target: the shape target (default the paper's compound cycloid), compared in the design frame.
        period: crank period T (s), 1e-6 to 1e6.
        obstacle: (a, b) length and height of the psi obstacle (mm), each 0 to 1e6.
        trunk: front-to-rear hip distance of the quadruped (mm), > 0 and <= 1e6.
        backend: ``numpy``, ``numba`` or ``auto`` (numba when available) for the solver.
        phase_optimal: also compute the best-cyclic-shift shape error (O(n^2) per design).

    Raises:
        TypeError, ValueError: an argument of the wrong type or out of its range (named in the
            message). Odd *designs* never raise: they get NaN metrics and a positive violation,
            the same on both backends; ``violation == 0`` implies every metric is finite.

    With numba and without ``phase_optimal`` (the optimizer's path), one fused kernel solves and
    analyses each design while its rows are in cache (``metrics_numba.run_designs``).
    """
    checks.instance(design, Design, "design")
    n_samples = checks.samples(n_samples, minimum=MIN_SAMPLES, even=True)
    backend = checks.backend(backend)  # type: ignore[assignment]
    period, obstacle, trunk = _check_args(target, period, obstacle, trunk, phase_optimal)
    use_numba = _numba_ready(backend)
    # An empty population takes the kernel's path on either backend: both then return the same empty arrays.
    if (use_numba and not phase_optimal) or design.pop == 0:
        return _evaluate_fused(design, n_samples, target, period, obstacle, trunk)
    sol = design.solve(n_samples, joints=True, derivatives=True, backend="numba" if use_numba else "numpy")
    ev = evaluate_paths(
        sol.point,
        sol.leg,
        sol.dleg,
        sol.violation,
        target=target,
        period=period,
        obstacle=obstacle,
        trunk=trunk,
        phase_optimal=phase_optimal,
        kernel=use_numba,
    )
    mu = _assembled(np.degrees(worst_transmission(sol.mu_min, sol.mu_max)), sol.violation)
    ground = ground_clearance(sol, design.mechanism, design.output).value
    return replace(ev, crank_margin=sol.crank_margin, transmission=mu, clearance=ground)


def _assembled(mu: F64, violation: F64) -> F64:
    """The worst transmission angle where the design assembles, NaN elsewhere: a dyad that cannot close reaches
    0 deg at the edge of where it does, which read as a measured dead point (rehearsal 5, the review of session
    29: the Pick panel warned "0.0 deg" of a member that does not assemble)."""
    return np.where(np.asarray(violation) > 0.0, np.nan, mu)


def gait_verdict(constraints: F64) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The Eq. 30-31 constraint values of one member, ``(5,)``: the names of those it misses (> 0) and of those
    not defined (NaN: no well-defined bench trajectory, so not measured). One rule for ``clm evaluate`` and the
    studio (the studio said "5 unmet" where the CLI said "5 not defined")."""
    values = np.asarray(constraints, dtype=np.float64)
    unmet = tuple(n for n, v in zip(CONSTRAINT_NAMES, values, strict=True) if v > 0.0)
    undefined = tuple(n for n, v in zip(CONSTRAINT_NAMES, values, strict=True) if np.isnan(v))
    return unmet, undefined


def _check_args(
    target: Target | None, period: float, obstacle: tuple[float, float], trunk: float, phase_optimal: bool
) -> tuple[float, tuple[float, float], float]:
    """The scalar arguments of ``evaluate`` and ``evaluate_paths`` checked (see ``evaluate``)."""
    if target is not None:
        checks.instance(target, Target, "target")
    checks.flag(phase_optimal, "phase_optimal")
    period = checks.real(period, "period (s)", positive=True, maximum=checks.MAX_ABS)
    # Speeds scale with 1/T: a period below 1e-6 s (or above 1e6 s) is a unit mistake, not a crank.
    if period < 1.0 / checks.MAX_ABS:
        raise ValueError(f"period (s) must be >= {1.0 / checks.MAX_ABS:g}, got {period:g}")
    a, b = checks.pair(obstacle, "obstacle")
    a = checks.real(a, "obstacle length (mm)", nonnegative=True, maximum=checks.MAX_ABS)
    b = checks.real(b, "obstacle height (mm)", nonnegative=True, maximum=checks.MAX_ABS)
    trunk = checks.real(trunk, "trunk (mm)", positive=True, maximum=checks.MAX_ABS)
    return period, (a, b), trunk


@lru_cache(maxsize=8)
def _default_target(period: float) -> Target:
    return cycloid_target(period=period)


def _target_samples(tgt: Target, n: int) -> F64:
    """``tgt.sample(n)``; the default target's samples are built once per (period, n)."""
    return _cycloid_samples(tgt.period, n) if tgt is _default_target(tgt.period) else tgt.sample(n)


# Private caches, only read (writable: numba compiles another specialization for read-only arrays).
@lru_cache(maxsize=8)
def _cycloid_samples(period: float, n: int) -> F64:
    return _default_target(period).sample(n)


@lru_cache(maxsize=4)
def _layouts(trunk: float) -> tuple[F64, F64, F64, F64]:
    """Leg offsets and phases of the biped and of the quadruped (the kernels' layout arrays)."""
    quad = quadruped(trunk)
    f64 = np.float64
    return (np.asarray(BIPED.offsets, dtype=f64), np.asarray(BIPED.phases, dtype=f64),
            np.asarray(quad.offsets, dtype=f64), np.asarray(quad.phases, dtype=f64))


def _evaluate_fused(
    design: Design, n: int, target: Target | None, period: float, obstacle: tuple[float, float], trunk: float
) -> Evaluation:
    """``evaluate`` through ``metrics_numba.run_designs``: solve and analyse each design in one pass.

    The same results as ``design.solve`` followed by ``evaluate_paths(..., kernel=True)``, without
    the ``(pop, n_samples, 2)`` paths: nothing per sample is allocated, nothing makes a second pass.
    """
    # Imported here: PARALLEL_MIN_POP is read at call time (tests lower it to run the parallel kernel).
    from core.analysis import kernel as K
    from core.kinematics.solver import (
        PARALLEL_MIN_POP,
        assembly_violation,
        crank_margin_of,
        prepare,
        sample_angles,
        transmission_range,
    )

    prep = prepare(design.mechanism, design.params)
    tgt = _default_target(float(period)) if target is None else target
    a, b = float(obstacle[0]), float(obstacle[1])
    out = design.output
    pop = prep.vals.shape[0]
    mmin, cmin, cmax, neg, broken, ylow, index, pts, tans, S = K.run_designs(
        prep.program.ops, prep.vals, sample_angles(n), prep.program.tracked, out.kernel_args(),
        _target_samples(tgt, n), float(period), a, b, *_layouts(float(trunk)), pop >= PARALLEL_MIN_POP,
    )
    crank = crank_margin_of(prep)
    kin = assembly_violation(prep, mmin, neg, broken, crank)
    mu = _assembled(np.degrees(worst_transmission(*transmission_range(prep.program.ops, cmin, cmax))), kin)
    ground = from_lowest(ylow, design.mechanism, out, kin).value
    return _assemble(_kernel_results(index, pts, tans, S, float(period), n), np.full(pop, np.nan), kin, tgt,
                     period, (a, b), trunk, n, crank, mu, ground)


def _kernel(
    point: F64, leg: F64, dleg: F64 | None, target: F64, period: float, a: float, b: float, trunk: float
) -> tuple[FeaturePoints, F64, F64, F64, F64, F64, F64, F64, F64, F64]:
    """The numba kernel's outputs in the numpy modules' shapes."""
    from core.analysis import kernel as K

    pop, n = leg.shape[:2]
    dleg = periodic_derivative(np.nan_to_num(leg)) if dleg is None else np.asarray(dleg).reshape(leg.shape)
    index = np.empty((pop, 8))
    pts = np.empty((pop, 8, 2))
    tans = np.empty((pop, 8, 2))
    S = np.empty((pop, K.N_SCALARS))
    K.run(
        np.ascontiguousarray(leg), np.ascontiguousarray(dleg, dtype=np.float64), np.ascontiguousarray(point),
        np.ascontiguousarray(target, dtype=np.float64), float(period), float(a), float(b), *_layouts(float(trunk)),
        index, pts, tans, S,
    )
    return _kernel_results(index, pts, tans, S, period, n)


def _kernel_results(
    index: F64, pts: F64, tans: F64, S: F64, period: float, n: int
) -> tuple[FeaturePoints, F64, F64, F64, F64, F64, F64, F64, F64, F64]:
    from core.analysis import kernel as K

    fp = FeaturePoints(
        index=index,
        times=index * (period / n),
        points=pts,
        tangents=tans,
        n_roots=S[:, K.N_ROOTS].astype(np.int64),
        root_violation=S[:, K.ROOT_VIOL],
        turning=S[:, K.TURNING].astype(np.int64),
        valid=S[:, K.VALID] > 0.0,
        period=float(period),
        n_samples=n,
    )
    return (fp, S[:, K.H_S], S[:, K.H_M], S[:, K.H_BAR], S[:, K.PSI2], S[:, K.PSI4], S[:, K.STEP], S[:, K.MSE],
            S[:, K.WIDTH], S[:, K.Y_MIN])


def evaluate_paths(
    point: F64,
    leg: F64,
    dleg: F64 | None = None,
    kinematic_violation: F64 | None = None,
    *,
    target: Target | None = None,
    period: float = DEFAULT_PERIOD,
    obstacle: tuple[float, float] = DEFAULT_OBSTACLE,
    trunk: float = DEFAULT_TRUNK,
    phase_optimal: bool = False,
    kernel: bool = False,
) -> Evaluation:
    """Every metric of given paths (a solved population, or a curve read from a file).

    Args:
        point: ``(pop, n, 2)`` design-frame path (mm), for the shape error, width and y_min.
        leg: ``(pop, n, 2)`` leg-frame path (mm), for the gait metrics.
        dleg: its d/dtheta (mm/rad); periodic differences when None.
        kinematic_violation: ``(pop,)`` assembly violation (0 if None).
        target, period, obstacle, trunk, phase_optimal: see ``evaluate``.
        kernel: use the numba kernel ``core.analysis.kernel`` (same results) instead of the numpy modules.
    """
    period, obstacle, trunk = _check_args(target, period, obstacle, trunk, phase_optimal)
    checks.flag(kernel, "kernel")
    point = _paths(point, "point")
    leg = _paths(leg, "leg")
    if point.shape != leg.shape:
        raise ValueError(f"point and leg must have the same shape (pop, n, 2), got {point.shape} and {leg.shape}")
    pop, n = leg.shape[:2]
    checks.samples(n, minimum=MIN_SAMPLES, name="samples per path (n)")
    if dleg is not None:
        dleg = _paths(dleg, "dleg")
        if dleg.shape != leg.shape:
            raise ValueError(f"dleg must have the shape of leg {leg.shape}, got {dleg.shape}")
    kin = np.zeros(pop) if kinematic_violation is None else checks.real_array(kinematic_violation,
                                                                               "kinematic_violation")
    if kin.shape != (pop,):
        raise ValueError(f"kinematic_violation must have shape ({pop},), got {kin.shape}")
    tgt = _default_target(float(period)) if target is None else target
    a, b = float(obstacle[0]), float(obstacle[1])
    target_n = _target_samples(tgt, n)
    if kernel:
        results = _kernel(point, leg, dleg, target_n, period, a, b, trunk)
    else:
        fp = feature_points(leg, dleg, period)
        wt = walking_trajectory(leg, dleg, fp)
        finite = np.asarray(np.isfinite(point).all(axis=(1, 2)), dtype=bool)
        p0 = np.where(finite[:, None, None], point, 0.0)
        results = (
            fp,
            M.stance_fluctuation(leg, fp),
            M.crossing_height(wt),
            M.mean_crossing_height(wt),
            M.psi(wt, BIPED, a, b),
            M.psi(wt, quadruped(trunk), a, b),
            wt.step,
            shape_mse(point, target_n),
            np.where(finite, p0[..., 0].max(1) - p0[..., 0].min(1), np.nan),
            np.where(finite, p0[..., 1].min(1), np.nan),
        )
    err_phase = mse_phase_optimal(point, target_n)[0] if phase_optimal else np.full(pop, np.nan)
    return _assemble(results, err_phase, kin, tgt, period, (a, b), trunk, n)


def _paths(a: Any, name: str) -> F64:
    """``(pop, n, 2)`` float64 paths from ``(n, 2)`` or ``(pop, n, 2)`` real numbers."""
    p = checks.real_array(a, name, copy=False)
    p = p[None] if p.ndim == 2 else p
    if p.ndim != 3 or p.shape[2] != 2:
        raise ValueError(f"{name} must have shape (pop, n, 2) or (n, 2), got {np.shape(a)}")
    return p


def _assemble(
    results: tuple[FeaturePoints, F64, F64, F64, F64, F64, F64, F64, F64, F64],
    err_phase: F64,
    kin: F64,
    tgt: Target,
    period: float,
    obstacle: tuple[float, float],
    trunk: float,
    n: int,
    crank: F64 | None = None, transmission: F64 | None = None, clearance: F64 | None = None,
) -> Evaluation:
    """The Evaluation from the analysis results (kernel or numpy modules), the kinematic violation, the crank
    margin and the worst transmission angle (None: paths without a design, NaN)."""
    fp, h_s, h_m, h_bar, psi2, psi4, step, err, width, y_min = results
    l_s = M.stance_length(fp)
    theta = M.tangent_angles(fp)
    selfx = np.abs(np.abs(fp.turning) - 1).astype(np.float64)
    path_viol = np.where(fp.valid, fp.root_violation + selfx, np.inf)
    # An unassemblable design's violation is the solver's continuous shortfall alone.
    violation = np.where(kin > 0.0, kin, path_viol)
    cons = np.concatenate(
        [M.order_violation(fp)[:, None], M.angle_margins(fp), M.eq31(h_m, h_bar, psi2)], 1
    )
    return Evaluation(
        feasible=violation == 0.0,
        violation=violation,
        kinematic_violation=kin,
        path_violation=path_viol,
        l_s=l_s,
        h_s=h_s,
        S=M.straightness(h_s, l_s),
        I=M.impact(fp),
        theta1=theta[:, 0],
        theta2=theta[:, 1],
        landing_speed=M.landing_speed(fp),
        width=width,
        y_min=y_min,
        step_length=step,
        h_m=h_m,
        h_bar=h_bar,
        psi2=psi2,
        psi4=psi4,
        mse=err,
        mse_phase=err_phase,
        times=fp.times,
        points=fp.points,
        constraints=cons,
        obstacle=(float(obstacle[0]), float(obstacle[1])),
        trunk=float(trunk),
        period=float(period),
        n_samples=n,
        target=tgt.name,
        crank_margin=np.full(len(violation), np.nan) if crank is None else np.asarray(crank, dtype=np.float64),
        transmission=np.full(len(violation), np.nan) if transmission is None else transmission,
        clearance=np.full(len(violation), np.nan) if clearance is None else clearance,
    )


def why_infeasible(ev: Evaluation, i: int = 0) -> str:
    """Why member i has no well-defined bench trajectory, or ``""`` if it has one."""
    if ev.feasible[i]:
        return ""
    if ev.kinematic_violation[i] > 0.0:
        return f"does not assemble over the whole cycle (shortfall {ev.kinematic_violation[i]:.3g} mm)"  # not "0.00"
    if not np.isfinite(ev.path_violation[i]):
        return "the foot path is not finite"
    return "no single landing/take-off pair, or the foot path crosses itself"
