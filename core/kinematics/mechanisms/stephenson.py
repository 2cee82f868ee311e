"""Stephenson-I and Stephenson-III six-bar legs, exactly as spec §1 reconstructs them."""

from __future__ import annotations

from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.params import CRANK_LOOP, length, offset

_HEAD = CRANK_LOOP

STEPHENSON1 = Mechanism(
    name="stephenson1",
    title="Stephenson-I six-bar",
    params=_HEAD
    + (
        length("r5", "crank point F, along AB"),
        offset("r6", "crank point F, across AB"),
        length("r7", "rocker point E, along DC"),
        offset("r8", "rocker point E, across DC (E = D + r7 e - r8 rot90(e))"),
        length("r9", "link EG"),
        length("r10", "link FG"),
        offset("r11", "foot P, along FG"),
        length("r12", "foot P, across FG"),
    ),
    steps=(
        Ground("A", "x_a", "y_a"),
        Ground("D", "r4", 0.0, origin="A", angle="b"),
        Crank("B", "A", "r1", 0.0, phase="g"),
        Crank("F", "A", "r5", "r6", phase="g"),
        Dyad("C", "B", "D", "r2", "r3", +1),
        Attach("E", "D", "C", "r7", "-r8"),
        Dyad("G", "E", "F", "r9", "r10", -1),
        Attach("P", "F", "G", "r11", "r12"),
    ),
    tracked="P",
    doc=(
        "Ternary crank A-B-F, ternary rocker D-C-E, dyad E-G-F, foot P on link F-G "
        "(spec §1)."
    ),
)

STEPHENSON3 = Mechanism(
    name="stephenson3",
    title="Stephenson-III six-bar",
    params=_HEAD
    + (
        length("r5", "coupler point F, along BC"),
        offset("r6", "coupler point F, across BC"),
        length("r7", "ground pivot E, along AD"),
        offset("r8", "ground pivot E, across AD"),
        length("r9", "link EG"),
        length("r10", "link FG"),
        offset("r11", "foot P, along GF"),
        offset("r12", "foot P, across GF"),
    ),
    steps=(
        Ground("A", "x_a", "y_a"),
        Ground("D", "r4", 0.0, origin="A", angle="b"),
        Ground("E", "r7", "r8", origin="A", angle="b"),
        Crank("B", "A", "r1", 0.0, phase="g"),
        Dyad("C", "B", "D", "r2", "r3", +1),
        Attach("F", "B", "C", "r5", "r6"),
        Dyad("G", "E", "F", "r9", "r10", +1),
        Attach("P", "G", "F", "r11", "r12"),
    ),
    tracked="P",
    doc="Four-bar A-B-C-D, coupler point F, third ground pivot E, dyad E-G-F, foot P on G-F (spec §1).",
)
