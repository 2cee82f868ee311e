"""Named design parameters: units, kinds and global bounds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Kind = Literal["length", "offset", "position", "angle"]
UNITS: dict[str, str] = {"length": "mm", "offset": "mm", "position": "mm", "angle": "rad"}


@dataclass(frozen=True)
class Param:
    """One entry of a mechanism's parameter vector.

    Args:
        name: short name as the paper prints it (``r1``, ``x_a``, ``b``).
        kind: ``length`` (must be > 0), ``offset`` (signed length), ``position``
            (a coordinate) or ``angle`` (periodic, rad).
        lo, hi: global search bounds (mm or rad).
        doc: what the parameter is, in one line.
        sized: the bounds are sized for the paper's 300 mm stride, and a stage for a leg of another size
            multiplies them by its scale (``core.optimize.scale``; angles never scale). False for bounds a
            user typed (a configuration's ``[bounds]``), which are kept as typed.
    """

    name: str
    kind: Kind
    lo: float
    hi: float
    doc: str = ""
    sized: bool = True

    @property
    def unit(self) -> str:
        return UNITS[self.kind]


def length(name: str, doc: str = "", lo: float = 30.0, hi: float = 500.0) -> Param:
    return Param(name, "length", lo, hi, doc)


def offset(name: str, doc: str = "", lo: float = -500.0, hi: float = 500.0) -> Param:
    return Param(name, "offset", lo, hi, doc)


def position(name: str, doc: str = "", lo: float = -500.0, hi: float = 500.0) -> Param:
    return Param(name, "position", lo, hi, doc)


def angle(name: str, doc: str = "", lo: float = -3.141592653589793, hi: float = 3.141592653589793) -> Param:
    return Param(name, "angle", lo, hi, doc)


# The first loop every crank-rocker leg here starts from: ground link A->D at angle b, crank AB
# with phase g, coupler BC, rocker DC (four-bar, Watt-I, Stephenson-I/III share it).
CRANK_LOOP: tuple[Param, ...] = (
    angle("b", "direction of the ground link A->D"),
    angle("g", "crank phase at sample 0"),
    position("x_a", "crank pivot A, x"),
    position("y_a", "crank pivot A, y"),
    length("r1", "crank AB"),
    length("r2", "coupler BC"),
    length("r3", "rocker DC"),
    length("r4", "ground link AD"),
)
