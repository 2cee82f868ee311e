"""Presets of the four-bar, Watt-I and the reference walkers (merged into ``core.kinematics.presets.PRESETS``).

Sources are in each preset's ``source`` and in ``docs/mechanisms.md``.
"""

from __future__ import annotations

import numpy as np

from core.kinematics.mechanisms.fourbar import FOURBAR
from core.kinematics.mechanisms.walkers import JANSEN, KLANN
from core.kinematics.mechanisms.watt import WATT1
from core.kinematics.model import OutputStage
from core.kinematics.presets.preset import PAPER_PANTOGRAPH, Preset

# Appendix B-1, Watt-I column: b, g, x_a, y_a, r1 ... r12 (rad, mm).
_WATT1_PAPER = (6.10, 2.46, 64.59, 148.82, 90.88, 177.77, 180.98, 191.94, 214.01, -177.72, 62.41, -50.08,
                200.26, 209.76, -239.21, 29.84)

# Chebyshev's lambda (Hoekens) proportions crank : coupler : rocker : ground = 1 : 2.5 : 2.5 : 2, the foot on
# the coupler's extension at 5 crank lengths from the crank pin; crank 60 mm. The linkage hangs below its
# crank axle (b = pi); like the paper's legs, a pantograph k = -1 about the axle turns the path over so the
# straight stretch (nearest the pivots) becomes the stance at the bottom of the leg frame. Its foot goes round
# clockwise, so the leg frame is also mirrored (stance moving +x, the spec's convention).
_CHEBYSHEV = (np.pi, 0.0, 0.0, 0.0, 60.0, 150.0, 150.0, 120.0, 300.0, 0.0)
_AXLE_PANTOGRAPH = OutputStage(k=-1.0, ox=0.0, oy=0.0, mirror=True)
# Klann's foot also goes round clockwise: its leg frame is the mirror image about the crank axle.
_AXLE_MIRROR = OutputStage(mirror=True)

# Jansen's "holy numbers" a..m (strandbeest.com), crank axle at the origin.
_JANSEN = (0.0, 0.0, 0.0, 38.0, 41.5, 39.3, 40.1, 55.8, 39.4, 36.7, 65.7, 49.0, 50.0, 61.9, 7.8, 15.0)

# Klann: joint coordinates of the mekanizmalar.com "mechanical spider" figure (leg retracted), as tabulated
# with the Stanford ME112 linkage examples: crank axle, lower and upper rocker pivots, crank pin C,
# lower-rocker joint H, knee F, hip joint E, foot G.
_KLANN_JOINTS = {
    "A": (41.395, 26.641), "B": (27.690, 19.705), "D": (27.690, 31.092), "C": (46.756, 27.872),
    "H": (32.223, 24.547), "F": (21.602, 24.375), "E": (23.149, 38.227), "G": (23.771, 0.003),
}
# Scaled x3 to mm and mirrored (x -> -x) so the pivots sit right of the crank: under our counter-clockwise
# crank the mirror image runs Klann's intended (clockwise) gait, seen from the other side.
_KLANN_SCALE = 3.0


def _klann_values() -> tuple[float, ...]:
    p = {k: _KLANN_SCALE * np.array([-(x - _KLANN_JOINTS["A"][0]), y - _KLANN_JOINTS["A"][1]])
         for k, (x, y) in _KLANN_JOINTS.items()}

    def dist(a: str, b: str) -> float:
        return float(np.linalg.norm(p[a] - p[b]))

    def local(o: str, q: str, x: str) -> tuple[float, float]:
        e = (p[q] - p[o]) / dist(o, q)
        r = p[x] - p[o]
        return float(r @ e), float(r @ np.array([-e[1], e[0]]))

    phase = float(np.arctan2(p["C"][1], p["C"][0]))
    return (phase, 0.0, 0.0, *map(float, p["B"]), *map(float, p["D"]), dist("A", "C"), dist("C", "H"),
            dist("B", "H"), *local("C", "H", "F"), dist("D", "E"), dist("E", "F"), *local("E", "F", "G"))


PRESETS: dict[str, Preset] = {
    "watt1/paper": Preset(
        "watt1/paper", WATT1, _WATT1_PAPER, PAPER_PANTOGRAPH,
        "paper Appendix B-1, Watt-I (our parametrization; does not reproduce the reported MSE, see docs)",
    ),
    "fourbar/chebyshev": Preset(
        "fourbar/chebyshev", FOURBAR, _CHEBYSHEV, _AXLE_PANTOGRAPH,
        source="Chebyshev lambda / Hoekens proportions 1:2.5:2.5:2, P at 5",
    ),
    "jansen": Preset("jansen", JANSEN, _JANSEN, source="Theo Jansen's holy numbers (strandbeest.com)"),
    "klann": Preset(
        "klann", KLANN, _klann_values(), _AXLE_MIRROR,
        source="Klann mechanical spider joint coordinates (mekanizmalar.com), x3 mm, mirrored; leg frame mirrored",
    ),
}
