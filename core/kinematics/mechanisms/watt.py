"""Watt-I six-bar leg: our parametrization (spec §1 leaves it open), chosen to fit the paper's row.

Spec notation (``rot90(v) = (-v_y, v_x)``, ``u = (cos phi, sin phi)``, ``phi = g + theta``):

- A = (x_a, y_a); D = A + r4 (cos b, sin b) (binary ground link AD).
- B = A + r1 u (crank AB); C = dyad(B, D, r2, r3, +1) (coupler BC, rocker DC).
- e = unit(B - C); E = B + r5 e - r6 rot90(e) (ternary coupler C-B-E; E lies beyond B).
- f = unit(D - C); F = C + r7 f + r8 rot90(f) (ternary rocker D-C-F).
- G = dyad(E, F, r9, r10, -1) (dyad E-G-F).
- w = unit(F - G); P = F + r11 w + r12 rot90(w) -- the foot, on link G-F.

Of the discrete family of frames and signs we searched (``docs/mechanisms.md``), this one
brings the paper's Appendix B-1 Watt-I row closest to its reported trajectory; it does not
reproduce the reported MSE (see the docs for the numbers).
"""

from __future__ import annotations

from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.params import CRANK_LOOP, length, offset

WATT1 = Mechanism(
    name="watt1",
    title="Watt-I six-bar",
    params=CRANK_LOOP
    + (
        offset("r5", "coupler point E, along C->B measured from B"),
        offset("r6", "coupler point E, across C->B (E = B + r5 e - r6 rot90(e))"),
        offset("r7", "rocker point F, along C->D measured from C"),
        offset("r8", "rocker point F, across C->D"),
        length("r9", "link EG"),
        length("r10", "link FG"),
        offset("r11", "foot P, along G->F measured from F"),
        offset("r12", "foot P, across G->F"),
    ),
    steps=(
        Ground("A", "x_a", "y_a"),
        Ground("D", "r4", 0.0, origin="A", angle="b"),
        Crank("B", "A", "r1", 0.0, phase="g"),
        Dyad("C", "B", "D", "r2", "r3", +1),
        # Attach(X, P, Q, u, v) = P + u unit(Q - P) + v rot90(unit(Q - P)); the negated operands
        # turn the frame around so that it points from C to B (E) and from G to F (P).
        Attach("E", "B", "C", "-r5", "r6"),
        Attach("F", "C", "D", "r7", "r8"),
        Dyad("G", "E", "F", "r9", "r10", -1),
        Attach("P", "F", "G", "-r11", "-r12"),
    ),
    tracked="P",
    doc="Binary ground AD, crank AB, ternary coupler C-B-E, ternary rocker D-C-F, dyad E-G-F, foot P on G-F.",
)
