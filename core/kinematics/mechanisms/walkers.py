"""Reference walkers: Theo Jansen's eight-bar leg and Joe Klann's six-bar leg.

Both are written in the generic construction model with named lengths and pivot positions,
so they can be optimised like the paper's linkages. The crank turns counter-clockwise
(theta increasing); both legs are laid out so that the foot moves +x during stance, the
lowest half of its path (the spec's leg-frame convention). Figures: ``docs/mechanisms.md``.
"""

from __future__ import annotations

from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism
from core.kinematics.params import Param, angle, length, offset, position


def _len(name: str, doc: str) -> Param:
    # Walker links are short (Jansen's crank is 15): the paper's 30 mm floor does not fit.
    return length(name, doc, lo=5.0)


JANSEN = Mechanism(
    name="jansen",
    title="Theo Jansen leg",
    params=(
        angle("phase", "crank phase at sample 0"),
        position("x_o", "crank axle O, x"),
        position("y_o", "crank axle O, y"),
        offset("a", "ground pivot Q, distance left of O (Q = O + (-a, -l))"),
        _len("b", "link QU"),
        _len("c", "link QK"),
        _len("d", "link QV (upper triangle Q-U-V)"),
        _len("e", "link UV (upper triangle Q-U-V)"),
        _len("f", "link VT"),
        _len("g", "link TK (foot triangle K-T-F)"),
        _len("h", "link TF (foot triangle K-T-F)"),
        _len("i", "link KF (foot triangle K-T-F)"),
        _len("j", "link XU"),
        _len("k", "link XK"),
        offset("l", "ground pivot Q, distance below O"),
        _len("m", "crank OX"),
    ),
    steps=(
        Ground("O", "x_o", "y_o"),
        Ground("Q", "-a", "-l", origin="O"),
        Crank("X", "O", "m", 0.0, phase="phase"),
        Dyad("U", "Q", "X", "b", "j", +1),
        Dyad("V", "U", "Q", "e", "d", -1),
        Dyad("K", "X", "Q", "k", "c", +1),
        Dyad("T", "V", "K", "f", "g", -1),
        Dyad("F", "T", "K", "h", "i", -1),
    ),
    tracked="F",
    doc=(
        "Crank OX, upper loop X-U-Q with the rigid triangle Q-U-V, lower loop X-K-Q, "
        "link V-T and the rigid foot triangle K-T-F; parameters are Jansen's letters a..m."
    ),
)

KLANN = Mechanism(
    name="klann",
    title="Klann leg",
    params=(
        angle("phase", "crank phase at sample 0"),
        position("x_a", "crank axle A, x"),
        position("y_a", "crank axle A, y"),
        offset("x_b", "lower rocker pivot B, x relative to A"),
        offset("y_b", "lower rocker pivot B, y relative to A"),
        offset("x_d", "upper rocker pivot D, x relative to A"),
        offset("y_d", "upper rocker pivot D, y relative to A"),
        _len("AC", "crank AC"),
        _len("CH", "connecting arm, crank pin C to lower-rocker joint H"),
        _len("BH", "lower rocker BH"),
        offset("u_f", "knee F on the arm, along C->H"),
        offset("v_f", "knee F on the arm, across C->H"),
        _len("DE", "upper rocker DE"),
        _len("EF", "leg, hip joint E to knee F"),
        offset("u_g", "foot G on the leg, along E->F"),
        offset("v_g", "foot G on the leg, across E->F"),
    ),
    steps=(
        Ground("A", "x_a", "y_a"),
        Ground("B", "x_b", "y_b", origin="A"),
        Ground("D", "x_d", "y_d", origin="A"),
        Crank("C", "A", "AC", 0.0, phase="phase"),
        Dyad("H", "C", "B", "CH", "BH", +1),
        Attach("F", "C", "H", "u_f", "v_f"),
        Dyad("E", "F", "D", "EF", "DE", -1),
        Attach("G", "E", "F", "u_g", "v_g"),
    ),
    tracked="G",
    doc=(
        "Crank AC, ternary connecting arm C-H-F held by the lower rocker BH, leg E-F-G held by "
        "the upper rocker DE; the foot G is the far end of the leg."
    ),
)
