"""Analysis: feature points, BT -> WT gaits, metrics and their kernel, targets, Fourier descriptors, `evaluate`.

Turns solved paths into the paper's performance measures for whole populations.
May import ``core.kinematics``; never ``core.optimize``, ``core.formats`` or ``core.cli``.
"""
