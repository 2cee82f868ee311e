"""Checked design input: parameter vectors, output stages and the design JSON format.

The solver never raises on odd numbers (it answers NaN and a violation); this module is
the front door for designs typed by a person or read from a file, where a clear error
beats a NaN. Every failure is a ``ValueError`` with one line naming the parameter and
its unit.

Design JSON (see ``docs/cli.md``)::

    {"mechanism": "stephenson1",
     "params": {"b": 0.52, "g": 3.26, ...} | [0.52, 3.26, ...],
     "output": {"k": -1.0, "ox": 150.0, "oy": 0.0}}

``output`` is optional (identity). ``name``, ``title``, ``source`` and ``units`` may be
present (``clm presets show`` writes them); ``units``, if given, must match the mechanism's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import msgspec
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.formats.typed import decode
from core.kinematics import mechanisms
from core.kinematics.checks import MAX_ABS
from core.kinematics.design import Design
from core.kinematics.model import IDENTITY, Mechanism, OutputStage
from core.kinematics.params import Param

F64 = NDArray[np.float64]

DESIGN_KEYS = ("mechanism", "params", "output")
INFO_KEYS = ("name", "title", "source", "units")
OUTPUT_KEYS = ("k", "ox", "oy", "mirror")


class OutputFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """The output stage of a design file: leg = O + k R(mirror) (P - O)."""

    k: float = 1.0
    ox: float = 0.0
    oy: float = 0.0
    mirror: bool = False


class DesignFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A design: a mechanism by name, its parameters by name or in order (mm, rad), an optional output stage."""

    mechanism: str
    params: dict[str, float] | list[float]
    output: OutputFile | None = None
    name: str | None = None
    title: str | None = None
    source: str | None = None
    units: dict[str, str] | None = None


def _number(label: str, unit: str, value: object) -> float:
    """``value`` as a float, or a ValueError naming ``label``; bools are not numbers here."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{label} must be a number ({unit}), got {value!r}")
    try:
        return float(value)
    except OverflowError:  # an integer past 1e308, which float() refuses with a traceback (QA, session 36)
        raise ValueError(f"{label} ({unit}) must be finite, got an integer of about "
                         f"{int(int(value).bit_length() * 0.30103) + 1} digits") from None


def check_params(mechanism: Mechanism, params: ArrayLike) -> F64:
    """Check a population of design vectors against a mechanism.

    Args:
        mechanism: the topology.
        params: ``(pop, n_params)`` or ``(n_params,)`` design vectors (mm, rad).

    Returns:
        ``(pop, n_params)`` float64 copy.

    Raises:
        ValueError: wrong parameter count, a non-finite value, one beyond +-1e6 (mm or rad), or a
            length <= 0; the message names the first offending parameter, its unit and (for pop > 1)
            the member.
    """
    try:
        p = np.array(params, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{mechanism.name} parameters must be numbers, got {params!r}") from None
    p = np.atleast_2d(p)
    if p.ndim != 2 or p.shape[1] != mechanism.n_params:
        got = p.shape[-1] if p.ndim == 2 else f"shape {p.shape}"
        raise ValueError(
            f"{mechanism.name} takes {mechanism.n_params} parameters "
            f"({', '.join(mechanism.param_names)}), got {got}"
        )
    many = p.shape[0] > 1
    for j, spec in enumerate(mechanism.params):
        col = p[:, j]
        bad = ~(np.abs(col) <= MAX_ABS) | ((col <= 0.0) if spec.kind == "length" else False)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(value_problem(spec, float(col[i]), f"{spec.name} of design {i}" if many else None))
    return p


def value_problem(spec: Param, v: float, who: str | None = None) -> str | None:
    """Why ``v`` cannot be parameter ``spec`` of a design (``who`` names it in the message), or None: not finite,
    beyond +-1e6 (the solver's domain: past it the geometry is floating-point noise), or a length <= 0."""
    who = who or spec.name
    if not math.isfinite(v):
        return f"{who} ({spec.unit}) must be finite, got {v}"
    if abs(v) > MAX_ABS:
        return f"{who} must be within +-{MAX_ABS:g} {spec.unit}, got {v:g} {spec.unit}"
    if spec.kind == "length" and v <= 0.0:
        return f"{who} is a length and must be > 0 {spec.unit}, got {v:g} {spec.unit}"
    return None


def params_from(mechanism: Mechanism, values: Mapping[str, object] | Sequence[object]) -> F64:
    """One design vector from ``{name: value}`` (every name, no other) or a plain list.

    Returns:
        ``(1, n_params)`` checked design vector (mm, rad).
    """
    units = {p.name: p.unit for p in mechanism.params}
    if isinstance(values, Mapping):
        unknown = [k for k in values if k not in units]
        if unknown:
            raise ValueError(
                f"unknown parameter {unknown[0]!r} for {mechanism.name}; it takes {', '.join(mechanism.param_names)}"
            )
        missing = [n for n in mechanism.param_names if n not in values]
        if missing:
            raise ValueError(f"missing parameter {missing[0]!r} ({units[missing[0]]}) for {mechanism.name}")
        row = [_number(n, units[n], values[n]) for n in mechanism.param_names]
    elif isinstance(values, Sequence) and not isinstance(values, str | bytes):
        if len(values) != mechanism.n_params:
            raise ValueError(
                f"{mechanism.name} takes {mechanism.n_params} parameters "
                f"({', '.join(mechanism.param_names)}), got {len(values)}"
            )
        row = [_number(n, units[n], v) for n, v in zip(mechanism.param_names, values, strict=True)]
    else:
        raise ValueError(f"params must be an object {{name: value}} or a list of numbers, got {values!r}")
    return check_params(mechanism, [row])


def check_output(output: OutputStage) -> OutputStage:
    """An output stage with finite k, ox, oy and k != 0 (a zero ratio collapses the leg to O)."""
    for key, unit in (("k", "ratio"), ("ox", "mm"), ("oy", "mm")):
        if not math.isfinite(getattr(output, key)):
            raise ValueError(f"output {key} ({unit}) must be finite, got {getattr(output, key)}")
    if output.k == 0.0:
        raise ValueError("output k (ratio) must be non-zero")
    if not isinstance(output.mirror, bool | np.bool_):
        raise ValueError(f"output mirror must be true or false, got {output.mirror!r}")
    return output


def output_from(data: object) -> OutputStage:
    """An output stage from ``{"k": .., "ox": .., "oy": .., "mirror": ..}`` (missing keys take
    identity's values; mirror is a boolean)."""
    if not isinstance(data, Mapping):
        raise ValueError(f"output must be an object {{k, ox, oy, mirror}}, got {data!r}")
    unknown = [k for k in data if k not in OUTPUT_KEYS]
    if unknown:
        raise ValueError(f"unknown output key {unknown[0]!r}; expected k, ox, oy, mirror")
    units = {"k": "ratio", "ox": "mm", "oy": "mm"}
    vals = {k: _number(f"output {k}", units[k], data[k]) for k in ("k", "ox", "oy") if k in data}
    mirror = data.get("mirror", False)
    if not isinstance(mirror, bool):
        raise ValueError(f"output mirror must be true or false, got {mirror!r}")
    return check_output(OutputStage(**vals, mirror=mirror))


def check_design(design: Design) -> Design:
    """The same design after checking its parameters and output stage."""
    check_params(design.mechanism, design.params)
    check_output(design.output)
    return design


def design_from_dict(data: object) -> Design:
    """A checked one-member design from the design JSON format (see module docstring)."""
    if not isinstance(data, Mapping):
        keys = ", ".join(DESIGN_KEYS)
        raise ValueError(f"a design must be a JSON object with keys {keys}, got {type(data).__name__}")
    unknown = [k for k in data if k not in DESIGN_KEYS + INFO_KEYS]
    if unknown:
        raise ValueError(f"unknown design key {unknown[0]!r}; expected {', '.join(DESIGN_KEYS)} "
                         f"(and optionally {', '.join(INFO_KEYS)})")
    for key in ("mechanism", "params"):
        if key not in data:
            raise ValueError(f"design has no {key!r}")
    name = data["mechanism"]
    if not isinstance(name, str):
        raise ValueError(f"mechanism must be a name, got {name!r}")
    mech = mechanisms.get(name)
    units = data.get("units")
    if units is not None:
        if not isinstance(units, Mapping):
            raise ValueError(f"units must be an object {{name: unit}}, got {units!r}")
        expected = {p.name: p.unit for p in mech.params}
        for k, u in units.items():
            if k not in expected:  # a unit for a parameter this mechanism lacks: a file made for another one?
                raise ValueError(f"units names {k!r}, which {mech.name} does not have; its parameters: "
                                 f"{', '.join(expected)}")
            if u != expected[k]:
                raise ValueError(f"{k} is given in {u!r} but {mech.name} takes it in {expected[k]}")
    params = params_from(mech, data["params"])
    output = output_from(data["output"]) if data.get("output") is not None else IDENTITY  # null: as the schema allows
    decode(dict(data), DesignFile)  # what the checks above, which name parameters with units, leave out
    return Design(mech, params, output)


def unit_note(design: Design, path: ArrayLike | None = None, i: int = 0) -> str:
    """A word when member ``i`` looks written in other units than mm and rad, else "" (lab rehearsal: a design in
    metres read "feasible" with a 0.3 mm stride, one with angles in degrees was another leg, without a word): an
    angle beyond one turn (29.8 "rad" is 29.8 degrees), and, given its foot ``path`` ``(n, 2)`` (mm), a path far
    from a leg's size (``core.analysis.targets.scale_note``)."""
    from core.analysis.targets import scale_note

    notes = []
    turns = [(p.name, float(v)) for p, v in zip(design.mechanism.params, design.params[i], strict=True)
             if p.kind == "angle" and abs(float(v)) > 2.0 * math.pi]
    if turns:
        named = ", ".join(f"{n} = {v:g}" for n, v in turns[:3]) + (", ..." if len(turns) > 3 else "")
        n, v = turns[0]
        notes.append(f"{named} rad: beyond one turn, so probably degrees; angles are in rad ({n} = {v:g} deg would "
                     f"be {math.radians(v):.4g} rad)")
    if path is not None:
        pts = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        pts = pts[np.isfinite(pts).all(axis=1)]
        size = scale_note(pts) if len(pts) > 1 else ""
        if size:
            notes.append(f"its foot path: {size}")
    return "; ".join(notes)


def design_to_dict(design: Design, i: int = 0) -> dict[str, Any]:
    """Member ``i`` in the design JSON format (``params`` by name, with ``units``).

    ValueError (as :func:`value_problem` words it) for a member no reader would take back: a NaN or
    negative length written out is a file that is refused when opened, far from where it was made."""
    for spec, v in zip(design.mechanism.params, design.params[i], strict=True):
        problem = value_problem(spec, float(v))
        if problem is not None:
            raise ValueError(f"cannot write {design.mechanism.name} member {i}: {problem}")
    return {
        "mechanism": design.mechanism.name,
        "params": design.named(i),
        "units": {p.name: p.unit for p in design.mechanism.params},
        "output": design.output.to_dict(),
    }
