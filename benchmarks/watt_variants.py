"""Which Watt-I construction does the paper's Appendix B-1 row belong to? (not a test; a few seconds)

Enumerates the discrete family of constructions with the link assignment of ``core/kinematics/mechanisms/watt.py``
(r1 AB, r2 BC, r3 DC, r4 AD; E on the coupler by (r5, r6); F on the rocker by (r7, r8); dyad E-G-F with
EG, FG = r9, r10; foot on link F-G by (r11, r12)) and prints the variants whose design-frame path comes
closest to the compound cycloid (spec §3): per attachment the frame origin (either end of its link,
pointing at the other end) and the sign of each offset, the side of the dyad G, and the crank direction.

    python benchmarks/watt_variants.py [--top 10]
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from core.analysis.shape import mse  # noqa: E402
from core.analysis.targets import compound_cycloid  # noqa: E402
from core.kinematics.mechanisms.watt import WATT1  # noqa: E402
from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism  # noqa: E402
from core.kinematics.params import offset  # noqa: E402
from core.kinematics.presets import PAPER_PANTOGRAPH  # noqa: E402
from core.kinematics.solver import solve  # noqa: E402

ROW = (6.10, 2.46, 64.59, 148.82, 90.88, 177.77, 180.98, 191.94, 214.01, -177.72, 62.41, -50.08,
       200.26, 209.76, -239.21, 29.84)
PARAMS = tuple(offset(n) for n in WATT1.param_names) + (offset("mg"),)  # mg = -g: the crank turned back


def attach(name: str, ends: tuple[str, str], origin: int, u: str, v: str, su: int, sv: int) -> Attach:
    p, q = ends if origin == 0 else ends[::-1]
    return Attach(name, p, q, ("" if su > 0 else "-") + u, ("" if sv > 0 else "-") + v)


def variants() -> list[tuple[tuple[int, ...], Mechanism]]:
    out = []
    signs = (1, -1)
    for key in itertools.product((0, 1), signs, signs, (0, 1), signs, signs, signs, (0, 1), signs, signs, signs):
        eo, eu, ev, fo, fu, fv, side, po, pu, pv, crank = key
        steps = (
            Ground("A", "x_a", "y_a"),
            Ground("D", "r4", 0.0, origin="A", angle="b"),
            Crank("B", "A", "r1", 0.0, phase="g" if crank > 0 else "mg"),
            Dyad("C", "B", "D", "r2", "r3", +1),
            attach("E", ("B", "C"), eo, "r5", "r6", eu, ev),
            attach("F", ("D", "C"), fo, "r7", "r8", fu, fv),
            Dyad("G", "E", "F", "r9", "r10", side),
            attach("P", ("F", "G"), po, "r11", "r12", pu, pv),
        )
        out.append((key, Mechanism("watt-variant", "", PARAMS, steps, "P")))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args(argv)
    n = 360
    target, _ = compound_cycloid(n)
    x = np.array([ROW + (-ROW[1],)])
    rows = []
    for key, m in variants():
        sol = solve(m, x, n, joints=False, backend="numpy")
        p = sol.point[0]
        if key[-1] < 0:  # crank turned clockwise: sample i is at -theta_i
            p = np.concatenate([p[:1], p[:0:-1]])
        if sol.violation[0] > 0:
            continue
        rows.append((float(mse(p, target)[0]), np.ptp(p[:, 0]), p[:, 1].min(), key))
    rows.sort(key=lambda r: r[0])
    print("key = (E origin, E su, E sv, F origin, F su, F sv, G side, P origin, P su, P sv, crank dir)")
    print("origin 0: first end of (B,C) / (D,C) / (F,G); su, sv: signs of the along / across offsets")
    print(f"{'MSE':>8} {'width':>8} {'y_min':>8}  key")
    for e, w, y, key in rows[: args.top]:
        print(f"{e:8.2f} {w:8.2f} {y:8.2f}  {key}")
    print(f"paper: MSE 5.29 mm (S 0.75 %, I 14.31 mm/s) with the pantograph {PAPER_PANTOGRAPH.to_dict()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
