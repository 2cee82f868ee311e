"""Colours shared by the 3-D scene and the plotly figures (RGB 0-255)."""

from __future__ import annotations

RGB = tuple[int, int, int]

LINK: RGB = (22, 36, 72)
CRANK: RGB = (148, 103, 189)
GROUND: RGB = (150, 150, 150)
JOINT: RGB = (22, 36, 72)
PIVOT: RGB = (20, 20, 20)
FOOT: RGB = (214, 39, 40)
PATH: RGB = (31, 119, 180)
STANCE: RGB = (31, 119, 180)
SWING: RGB = (44, 160, 44)
TARGET: RGB = (255, 127, 14)
FRAME: RGB = (205, 205, 205)
GRID: RGB = (236, 236, 236)
FEASIBLE: RGB = (178, 178, 178)  # dominated feasible members: grey, far from the front's blue
INFEASIBLE: RGB = (214, 39, 40)
KNEE: RGB = (255, 127, 14)
BEST: RGB = (44, 160, 44)
PASSED: RGB = (148, 103, 189)
OBSTACLE_CLEAR: RGB = (44, 160, 44)
OBSTACLE_HIT: RGB = (214, 39, 40)
TRUNK: RGB = (60, 60, 60)
LEGS: tuple[RGB, ...] = ((31, 119, 180), (255, 127, 14), (148, 103, 189), (140, 86, 75))


def css(c: RGB, alpha: float = 1.0) -> str:
    """``rgba(r,g,b,a)`` for plotly."""
    return f"rgba({c[0]},{c[1]},{c[2]},{alpha:g})"
