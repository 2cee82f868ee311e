"""Named designs: every legible row of the paper's Appendix B and C, plus reference walkers.

A preset is addressed as ``mechanism/row`` (``stephenson1/X3``) or by a bare name
(``jansen``). Misprints are fixed per spec §7; the fix is noted in ``source``.
"""

from __future__ import annotations

import difflib

from core.kinematics.mechanisms.stephenson import STEPHENSON1, STEPHENSON3
from core.kinematics.presets import rtclm as rtclm_presets
from core.kinematics.presets import walkers as extra_presets
from core.kinematics.presets.preset import PAPER_PANTOGRAPH, Preset

# Appendix B, Stephenson-I: b, g, x_a, y_a, r1 ... r12 (rad, mm).
_S1_ROWS: dict[str, tuple[str, str]] = {
    "X0": ("0.31 3.14 137.85 84.31 49.63 78.12 87.94 102.20 50.25 -6.13 86.79 -21.20 142.52 101.39 4.96 129.56", "B-1 X0 (Fourier predesign)"),
    "X1": ("0.49 3.22 147.39 67.92 56.55 90.12 99.70 125.27 49.75 -4.13 96.13 -32.06 132.34 93.38 2.23 117.97", "B-1 X1 (subtask 1)"),
    "X2": ("0.48 3.25 148.49 68.98 55.47 85.14 102.75 126.49 50.62 -5.88 100.09 -25.46 129.48 88.80 6.64 117.53", "B-1 X2 (subtask 2); g printed 3.52, read 3.25 (spec §7)"),
    "X3": ("0.52 3.26 150.57 66.12 56.20 88.15 99.62 128.33 51.20 -4.21 96.50 -25.13 127.65 83.21 8.09 115.54", "B-1 X3 (subtask 3)"),
    "CMOEMT-X1": ("0.49 3.25 150.14 68.86 60.58 92.40 115.97 142.60 51.98 -5.62 110.99 -24.73 148.39 97.31 24.13 114.55", "B-2"),
    "CMOEMT-X2": ("0.51 3.26 150.67 69.09 57.68 91.28 112.21 139.70 50.21 -4.77 107.98 -27.45 143.90 97.56 21.50 117.14", "B-2"),
    "CMOEMT-X3": ("0.51 3.27 151.13 67.63 58.99 93.68 115.68 145.63 50.75 -4.88 108.79 -26.68 147.84 97.18 21.82 115.20", "B-2"),
    "CMOES-X1": ("0.76 3.40 152.05 75.49 52.48 87.07 82.82 113.72 50.39 -5.64 90.00 -28.88 152.13 127.79 9.26 124.00", "B-2"),
    "CMOES-X2": ("0.70 3.38 153.95 66.97 54.82 82.93 83.76 106.93 52.56 -7.66 92.07 -28.73 145.33 122.73 13.74 114.11", "B-2"),
    "CMOES-X3": ("0.65 3.36 153.46 69.78 53.13 81.97 86.24 108.00 51.13 -7.34 91.72 -28.20 148.27 125.45 11.63 117.17", "B-2"),
    "DRLOS-EMCMO-X1": ("0.49 3.24 149.97 68.46 63.52 97.73 112.53 142.54 52.20 -5.17 110.78 -30.88 183.93 144.63 0.13 114.57", "B-2"),
    "DRLOS-EMCMO-X2": ("0.48 3.26 150.36 68.58 64.39 99.35 122.86 152.16 51.64 -5.70 121.16 -33.24 185.38 147.87 1.91 117.22", "B-2"),
    "DRLOS-EMCMO-X3": ("0.47 3.27 150.70 68.69 63.37 97.87 127.68 157.63 50.43 -5.36 123.83 -31.53 183.13 143.69 1.75 118.23", "B-2"),
    "IMTCMO-X1": ("0.55 3.30 150.94 71.05 60.41 94.27 113.28 142.11 51.77 -5.96 109.09 -26.63 153.03 104.49 23.91 116.64", "B-3; r5 printed 5177, read 51.77 (spec §7)"),
    "IMTCMO-X3": ("0.47 3.24 150.89 70.00 58.90 98.79 126.90 162.68 50.05 -3.64 119.96 -26.51 157.22 98.18 25.07 117.00", "B-3; b printed 047, read 0.47 (spec §7)"),
    "MCCMO-X1": ("1.03 3.66 155.50 77.07 51.34 81.42 74.38 98.56 50.35 -13.85 89.46 -25.14 115.72 117.23 0.01 125.56", "B-3"),
    "MCCMO-X3": ("0.59 3.30 151.54 78.10 49.57 72.49 86.15 104.08 48.04 -7.13 95.27 -19.07 123.52 104.07 3.38 126.35", "B-3"),
    "MOEAD-CMT-X1": ("0.49 3.24 150.06 68.38 62.89 95.95 113.08 142.64 52.17 -5.23 110.60 -30.14 163.10 122.17 0.70 116.50", "B-3"),
    "MOEAD-CMT-X2": ("0.49 3.19 151.70 68.56 51.99 99.08 98.69 141.71 49.78 -0.33 96.35 -30.69 183.03 133.67 3.24 116.45", "B-3; r12 printed 11.45, read 116.45 (spec §7)"),
    "MOEAD-CMT-X3": ("0.48 3.21 151.24 67.09 58.43 102.57 103.58 145.23 50.85 -1.72 99.99 -33.05 181.53 130.97 4.79 116.48", "B-3"),
    "direct-min-MSE": ("0.81 3.43 158.46 82.04 62.58 104.26 94.74 132.42 55.55 -8.38 94.68 -28.78 122.79 82.89 4.46 125.41", "B-4 single-level, smallest MSE"),
    "direct-min-h": ("0.81 3.43 162.69 81.18 63.91 103.62 98.07 132.42 53.09 -8.10 88.71 -28.68 123.35 82.85 8.39 128.43", "B-4 single-level, smallest h_s"),
    "direct-min-I": ("0.81 3.43 161.23 84.59 63.98 104.18 94.42 132.42 56.52 -8.14 94.68 -29.30 122.79 82.82 8.50 124.69", "B-4 single-level, smallest I"),
    "DP-SQP": ("-0.27 1.88 85.96 126.16 40.94 341.58 253.82 147.64 64.54 49.21 159.03 283.92 355.97 199.21 0.00 179.44", "B-5 DP+SQP"),
    "DP-GA": ("-1.60 2.95 -78.20 -66.32 75.31 431.32 379.86 382.04 136.34 40.55 328.87 -398.41 391.06 387.16 -5.75 243.03", "B-5 DP+GA"),
    "DP-GA-SQP": ("-1.28 3.07 -62.56 -79.58 90.38 498.06 303.89 458.45 136.62 32.44 263.10 -328.33 459.06 309.73 -4.60 234.60", "B-5 DP+GA+SQP"),
}
# Not legible or known wrong (spec §7): IMTCMO X2 (b "2346"), MCCMO X2 (repeats CMOEMT X2).

_S3_PAPER = "1.12 3.50 57.03 -151.91 82.02 371.54 226.37 259.41 384.43 -324.09 343.95 -22.07 395.95 361.26 411.72 -355.19"


def _values(text: str) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split())


def _paper_presets() -> dict[str, Preset]:
    out = {
        f"stephenson1/{k}": Preset(f"stephenson1/{k}", STEPHENSON1, _values(v), PAPER_PANTOGRAPH, f"paper Appendix {src}")
        for k, (v, src) in _S1_ROWS.items()
    }
    out["stephenson3/paper"] = Preset(
        "stephenson3/paper", STEPHENSON3, _values(_S3_PAPER), PAPER_PANTOGRAPH, "paper Appendix B-1, Stephenson-III"
    )
    return out


def _all_presets() -> dict[str, Preset]:
    return {**_paper_presets(), **extra_presets.PRESETS, **rtclm_presets.PRESETS}


PRESETS: dict[str, Preset] = _all_presets()


def get(name: str) -> Preset:
    """The preset of that name; ValueError naming the nearest names otherwise (listing all ~150 in one line read as
    noise: 'clm presets' lists them)."""
    if name not in PRESETS:
        # Another case ("rtclm/case1-cmoes") first; then the row name alone ("X3", as the paper prints it), not a
        # full name's last part (".../auxiliary" named three other cases' auxiliary presets); then the nearest.
        lower = {k.lower(): k for k in PRESETS}
        near = [lower[name.lower()]] if name.lower() in lower else []
        if not near and "/" not in name:
            near = [k for k in PRESETS if k.split("/")[-1].lower() == name.lower()][:3]
        near = near or [lower[k] for k in difflib.get_close_matches(name.lower(), lower, n=3, cutoff=0.6)]
        hint = f"; did you mean {', '.join(near)}?" if near else ""
        raise ValueError(f"unknown preset {name!r}{hint} ('clm presets' lists all {len(PRESETS)})")
    return PRESETS[name]


__all__ = ["PAPER_PANTOGRAPH", "PRESETS", "Preset", "get"]
