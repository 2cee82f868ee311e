"""The four-bar linkage with a coupler point (also the paper's Watt-II stand-in, §3.4.1).

Spec notation (``rot90(v) = (-v_y, v_x)``, ``u = (cos phi, sin phi)``, ``phi = g + theta``):

- A = (x_a, y_a) crank pivot; D = A + r4 (cos b, sin b) rocker pivot.
- B = A + r1 u (crank AB).
- C = dyad(B, D, r2, r3, +1) (coupler BC, rocker DC).
- e = unit(C - B); P = B + r5 e + r6 rot90(e) -- the tracked coupler point.

The crank turns fully iff the loop is Grashof with the crank shortest
(``Solution.crank_margin > 0``).
"""

from __future__ import annotations

from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.params import CRANK_LOOP, offset

FOURBAR = Mechanism(
    name="fourbar",
    title="Four-bar with coupler point",
    params=CRANK_LOOP
    + (
        offset("r5", "coupler point P, along BC"),
        offset("r6", "coupler point P, across BC (left of B->C)"),
    ),
    steps=(
        Ground("A", "x_a", "y_a"),
        Ground("D", "r4", 0.0, origin="A", angle="b"),
        Crank("B", "A", "r1", 0.0, phase="g"),
        Dyad("C", "B", "D", "r2", "r3", +1),
        Attach("P", "B", "C", "r5", "r6"),
    ),
    tracked="P",
    doc="Crank AB, coupler BC carrying the foot P at (r5, r6) in the frame B->C, rocker DC, ground AD.",
)
