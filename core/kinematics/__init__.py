"""Kinematics: the step model, every mechanism and its presets, and the batch solver.

`solver.solve` runs a compiled mechanism over whole populations (numpy `reference` or numba `kernel`).
Imports numpy, scipy and numba only; nothing else in ``core`` (the lowest layer).
"""
