"""Studies: a grid of (algorithm, case, seed) runs on Dask, kept in SQLite, summarised as a report.

A study file (``core.formats.study``) names design configs as cases, algorithms and seeds; ``cell`` runs one grid
cell self-contained; ``store`` keeps finished rows; ``runner`` schedules cells; ``report`` compares.
May import ``core.formats``, ``core.optimize``, ``core.analysis`` and ``core.kinematics``; never ``core.cli``.
"""
