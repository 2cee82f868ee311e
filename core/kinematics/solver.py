"""The batch dyad solver: ``solve(mechanism, params, n_samples) -> Solution``.

Samples are uniform in the input crank angle, ``theta_i = 2 pi i / n_samples``; the
crank's absolute angle is ``phase + theta_i``. With a crank period T, sample i is at time
``t_i = i T / n_samples``. Derivatives are exact (differentiated construction steps) and
taken with respect to theta (mm/rad); ``derivatives=False`` skips them (about half the work)
when only the paths are needed (shape matching, drawing).

Two interpreters of the same compiled program: ``core.kinematics.reference`` (reference) and
``core.kinematics.kernel`` (fast kernel). ``backend="auto"`` picks numba.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from core.kinematics import checks
from core.kinematics import reference as solver_numpy
from core.kinematics.model import CRANK, DYAD, GROUND, IDENTITY, Mechanism, OutputStage, Program

F64 = NDArray[np.float64]
Backend = Literal["auto", "numpy", "numba"]

# Above this population the numba kernel runs in parallel over designs.
PARALLEL_MIN_POP = 2000


@dataclass(frozen=True)
class Solution:
    """Kinematics of a population over one crank revolution.

    Attributes:
        theta: ``(n_samples,)`` input crank angles (rad).
        joints, djoints: ``(pop, n_samples, n_joints, 2)`` joint positions (mm) and their
            d/dtheta (mm/rad); None when solved with ``joints=False``.
        point, dpoint: ``(pop, n_samples, 2)`` tracked point in the design frame and d/dtheta.
        leg, dleg: ``(pop, n_samples, 2)`` tracked point in the leg frame and d/dtheta.
        (djoints, dpoint and dleg are None when solved with ``derivatives=False``.)
        valid: ``(pop, n_samples)`` True where every joint is placed.
        violation: ``(pop,)`` >= 0; 0 iff the mechanism assembles over every sample and its crank
            turns fully, else the sum over dyads of the worst assembly shortfall (mm), plus negative
            lengths and any coupling violation of the mechanism (RTCLM); at least ``-crank_margin``
            where the crank cannot turn fully (its loop may open between two samples).
        dyad_margin: ``(pop, n_dyads)`` min over the cycle of each dyad's distance from its
            singular (fully stretched or folded) configuration, ``min(d - |l1-l2|, l1+l2-d)`` (mm).
        mu_min, mu_max: ``(pop, n_dyads)`` range of each dyad's transmission angle (rad) over the
            samples where it closes (a dyad that opens part of the cycle reaches 0 or pi at the edge);
            NaN where it closes at no sample.
        crank_margin: ``(pop,)`` exact full-rotation margin of the loops closed by the crank
            (mm, > 0: the crank turns fully; Grashof for a four-bar); +inf if none.
        joint_names, dyad_names: names along the joint and dyad axes.
    """

    theta: F64
    joints: F64 | None
    djoints: F64 | None
    point: F64
    dpoint: F64 | None
    leg: F64
    dleg: F64 | None
    valid: NDArray[np.bool_]
    violation: F64
    dyad_margin: F64
    mu_min: F64
    mu_max: F64
    crank_margin: F64
    joint_names: tuple[str, ...]
    dyad_names: tuple[str, ...]

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """``(pop,)`` True where the mechanism assembles over the whole cycle."""
        return self.violation == 0.0


def sample_angles(n_samples: int) -> F64:
    """``(n_samples,)`` input crank angles ``2 pi i / n`` (rad)."""
    return 2.0 * np.pi * np.arange(n_samples) / n_samples


def _crank_margin(ops: NDArray[np.int64], vals: F64) -> F64:
    """Exact full-rotation margin of every dyad joining a crank point to a ground point."""
    out = np.full(vals.shape[0], np.inf)
    ground: dict[int, tuple[F64, F64]] = {}

    def place(g: int) -> tuple[F64, F64]:
        """Ground point g, ``(pop,)`` x and y (its anchors first)."""
        if g not in ground:
            u, v, ang = vals[:, g, 0], vals[:, g, 1], vals[:, g, 2]
            c, s = np.cos(ang), np.sin(ang)
            x, y = c * u - s * v, s * u + c * v
            a = int(ops[g, 1])
            if a >= 0:
                ax, ay = place(a)
                x, y = x + ax, y + ay
            ground[g] = (x, y)
        return ground[g]

    for j, c, g in _crank_dyads(ops.tobytes(), ops.shape[0]):
        (gx, gy), (px, py) = place(g), place(int(ops[c, 1]))
        rho = np.hypot(vals[:, c, 0], vals[:, c, 1])
        dist = np.hypot(gx - px, gy - py)
        l1, l2 = vals[:, j, 0], vals[:, j, 1]
        np.minimum(out, np.minimum(l1 + l2 - (dist + rho), np.abs(dist - rho) - np.abs(l1 - l2)), out=out)
    return out


@functools.cache
def _crank_dyads(ops_bytes: bytes, n_steps: int) -> tuple[tuple[int, int, int], ...]:
    """``(dyad, crank point, ground point)`` for every dyad joining a crank point (pivoting on a
    ground point) to a ground point: the loops whose full rotation ``_crank_margin`` measures."""
    ops = np.frombuffer(ops_bytes, dtype=np.int64).reshape(n_steps, 4)
    out = []
    for j, (kind, a, b, _) in enumerate(ops):
        if kind != DYAD:
            continue
        for c, g in ((a, b), (b, a)):
            if ops[c, 0] == CRANK and ops[g, 0] == GROUND and ops[ops[c, 1], 0] == GROUND:
                out.append((j, int(c), int(g)))
    return tuple(out)


class Prepared(NamedTuple):
    """A population ready for the interpreters (see ``prepare``)."""

    program: Program
    vals: F64
    derive_violation: F64
    bad: NDArray[np.bool_]


# A parameter of kind "length" below this is no link (mm): its shortfall is part of the violation.
MIN_LENGTH = 1e-6


def length_shortfall(mechanism: Mechanism, params: F64) -> F64:
    """``(pop,)`` how far the lengths (parameters of kind ``length``) fall below ``MIN_LENGTH`` (mm), summed.

    The dyad lengths are also judged by assembly; the others (cranks, ground links, attachments) would
    otherwise solve to a mirrored, "feasible" linkage with a negative length.
    """
    cols = [j for j, p in enumerate(mechanism.params) if p.kind == "length"]
    if not cols:
        return np.zeros(params.shape[0])
    with np.errstate(invalid="ignore"):
        return np.asarray(np.maximum(0.0, MIN_LENGTH - params[:, cols]).sum(axis=1), dtype=np.float64)


def prepare(mechanism: Mechanism, params: F64) -> Prepared:
    """Check and compile a population: operand values ``(pop, n_steps, 3)`` (non-finite rows NaN),
    the mechanism's derive violation ``(pop,)`` and the rows with non-finite parameters ``(pop,)``."""
    shape = np.shape(params)
    params = np.atleast_2d(np.asarray(params, dtype=np.float64))
    if params.ndim != 2 or params.shape[1] != mechanism.n_params:
        n = mechanism.n_params
        raise ValueError(f"{mechanism.name} takes {n} parameters, params of shape (pop, {n}) or ({n},); got {shape}")
    prog = mechanism.compile()
    # Beyond checks.MAX_ABS (a kilometre, mm or rad) the geometry is floating-point noise (products overflow near
    # 1e150): out of domain. Such rows are NaN before anything is derived or solved from them (1e300 squared only
    # overflowed to the same infinite violation, with numpy warnings).
    with np.errstate(invalid="ignore"):
        bad = np.asarray(~(np.abs(params) <= checks.MAX_ABS).all(axis=1), dtype=np.bool_)
    internal, derive_viol = mechanism.internal(np.where(bad[:, None], np.nan, params) if bad.any() else params)
    vals = np.ascontiguousarray(prog.operands(internal))
    # Non-finite operands (bad input, or a coupling that has no solution) poison the whole row.
    vals[~np.isfinite(vals).all(axis=(1, 2))] = np.nan
    derive_viol = np.asarray(derive_viol, dtype=np.float64) + length_shortfall(mechanism, params)
    return Prepared(prog, vals, derive_viol, bad)


def crank_margin_of(prep: Prepared) -> F64:
    """``(pop,)`` ``Solution.crank_margin`` of a prepared population."""
    return _crank_margin(prep.program.ops, prep.vals)


def assembly_violation(prep: Prepared, mmin: F64, neg: F64, broken: NDArray[np.bool_],
                       crank: F64 | None = None) -> F64:
    """``Solution.violation`` from the interpreters' cycle statistics.

    Args:
        prep: the population.
        mmin, neg: see ``core.kinematics.kernel.run``.
        broken: ``(pop,)`` True where some sample has a non-finite joint.
        crank: ``(pop,)`` the crank loops' margin (``_crank_margin``) if already computed.
    """
    margin = mmin[:, prep.program.ops[:, 0] == DYAD]
    with np.errstate(invalid="ignore"):
        shortfall = np.where(np.isfinite(margin), np.maximum(0.0, -margin), 0.0).sum(axis=1)
        # neg is NaN on rows whose operands prepare() poisoned (a coupling with no solution):
        # the derive violation measures those.
        violation = shortfall + np.nan_to_num(neg, nan=0.0) + np.nan_to_num(prep.derive_violation, nan=np.inf)
    # Degenerate geometry (coincident points of an attachment) leaves NaN with no shortfall.
    violation = np.where(broken & (violation == 0.0), 1e-9, violation)
    # A crank loop that cannot turn fully: at least its exact shortfall. A loop that opens between two samples was
    # feasible; taking the shortfall only where the samples saw none made the violation drop ~1000x once the nearest
    # sample failed (a design further from assembling looked closer). The larger of the two is continuous.
    crank = _crank_margin(prep.program.ops, prep.vals) if crank is None else crank
    with np.errstate(invalid="ignore"):
        violation = np.where(crank < 0.0, np.maximum(violation, -crank), violation)
    violation[prep.bad | np.isnan(violation)] = np.inf
    return violation


def transmission_range(ops: NDArray[np.int64], cmin: F64, cmax: F64) -> tuple[F64, F64]:
    """``Solution.mu_min, mu_max`` ``(pop, n_dyads)`` (rad) from the interpreters' cosine range ``(pop, n_steps)``
    of each step's transmission angle; NaN for a dyad that closes at no sample."""
    dyads = np.flatnonzero(ops[:, 0] == DYAD)
    lo, hi = cmin[:, dyads], cmax[:, dyads]
    with np.errstate(invalid="ignore"):
        mu_min = np.arccos(np.clip(hi, -1.0, 1.0))
        mu_max = np.arccos(np.clip(lo, -1.0, 1.0))
    mu_min[~np.isfinite(hi)] = np.nan
    mu_max[~np.isfinite(lo)] = np.nan
    never = (hi < -1.0) | (lo > 1.0)  # no sample closes: no angle (it read 180..180)
    mu_min[never], mu_max[never] = np.nan, np.nan
    return mu_min, mu_max


MU_USUAL = 40.0  # deg: the usual lowest worst transmission angle of a linkage that is to transmit force
MU_DEAD = 10.0  # deg: under this a dyad passes close to a dead point (with play it can lock or change branch)
DEAD_POINT_RISK = "with play in its joints the leg can lock or change branch"  # what MU_DEAD warns of, in words


def worst_transmission(mu_min: F64, mu_max: F64) -> F64:
    """``(pop,)`` the worst transmission angle over the cycle and every dyad, ``min(mu, pi - mu)`` (rad, in
    [0, pi/2]; pi/2 is ideal, 0 a dyad at its dead point); NaN where no dyad closes."""
    worst = np.fmin(mu_min, np.pi - mu_max)
    out = np.full(worst.shape[0], np.nan)
    ok = np.isfinite(worst).any(axis=1)
    out[ok] = np.nanmin(worst[ok], axis=1)
    return out


def solve(
    mechanism: Mechanism,
    params: F64,
    n_samples: int = 360,
    *,
    output: OutputStage = IDENTITY,
    joints: bool = True,
    derivatives: bool = True,
    backend: Backend = "auto",
) -> Solution:
    """Solve a population of designs over one crank revolution.

    Never raises for unassemblable or non-finite designs: their samples are NaN and their
    violation is positive (+inf for non-finite parameters or any beyond +-1e6; a parameter of
    kind ``length`` below 1e-6 mm adds its shortfall). Odd *calls* raise before any work:
    TypeError for a wrong type (parameters must be real numbers: floats, or integers, which
    convert), ValueError for a value out of range, each naming the argument.

    Args:
        mechanism: the topology.
        params: ``(pop, n_params)`` or ``(n_params,)`` design vectors (mm, rad); not mutated.
        n_samples: samples per revolution, an integer in [1, 100 000].
        output: design frame -> leg frame map of the tracked point.
        joints: also return every joint (memory: pop * n_samples * n_joints * 32 bytes).
        derivatives: also return d/dtheta (djoints, dpoint, dleg; else None).
        backend: ``numpy`` reference, ``numba`` kernel, or ``auto`` (numba).
    """
    checks.instance(mechanism, Mechanism, "mechanism")
    checks.instance(output, OutputStage, "output")
    n_samples = checks.samples(n_samples)
    backend = checks.backend(backend)  # type: ignore[assignment]
    joints, derivatives = checks.flag(joints, "joints"), checks.flag(derivatives, "derivatives")
    prep = prepare(mechanism, checks.real_array(params))
    prog, vals = prep.program, prep.vals
    theta = sample_angles(n_samples)
    if backend == "numpy":
        pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg = solver_numpy.reduce(
            prog.ops, vals, theta, prog.tracked, joints, derivatives
        )
        leg = output.apply(point)
        dleg = None if dpoint is None else output.apply_derivative(dpoint)
    else:
        from core.kinematics import kernel as solver_numba

        out = solver_numba.solve_all(prog.ops, vals, theta, prog.tracked, joints, vals.shape[0] >= PARALLEL_MIN_POP,
                                     stage=output.kernel_args(), derivatives=derivatives)
        pos, dpos, point, dpoint, valid, mmin, cmin, cmax, neg = (
            out.pos, out.dpos, out.point, out.dpoint, out.valid, out.mmin, out.cmin, out.cmax, out.neg
        )
        assert out.leg is not None
        leg, dleg = out.leg, out.dleg
    dyads = np.flatnonzero(prog.ops[:, 0] == DYAD)
    crank = _crank_margin(prog.ops, vals)
    violation = assembly_violation(prep, mmin, neg, np.asarray((~valid).any(axis=1), dtype=np.bool_), crank)
    mu_min, mu_max = transmission_range(prog.ops, cmin, cmax)
    names = mechanism.joint_names
    return Solution(
        theta=theta,
        joints=pos,
        djoints=dpos,
        point=point,
        dpoint=dpoint,
        leg=leg,
        dleg=dleg,
        valid=valid,
        violation=violation,
        dyad_margin=mmin[:, dyads],
        mu_min=mu_min,
        mu_max=mu_max,
        crank_margin=crank,
        joint_names=names,
        dyad_names=tuple(names[j] for j in dyads),
    )
