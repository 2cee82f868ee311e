"""The test problems ``clm moea`` and ``benchmarks/algorithms.py`` run, by name: one list that
:mod:`core.optimize.moea`, the CLI's help and the benchmark's errors all read."""

from __future__ import annotations

# DTLZ and constrained DTLZ at 3 objectives with PlatEMO's numbers of variables (M + 4 for the DTLZ1 family and
# C3-DTLZ4, M + 9 for DTLZ2-4, C1-DTLZ3 and C2-DTLZ2); pymoo's defaults differ for DTLZ2-4 and C1-DTLZ1.
DTLZ = {"dtlz1": 7, "dtlz2": 12, "dtlz3": 12, "dtlz4": 12, "c1dtlz1": 7, "c1dtlz3": 12, "c2dtlz2": 12, "c3dtlz4": 7}
# DC-DTLZ as PlatEMO defines it (core/optimize/dcdtlz.py; pymoo's classes of these names are other problems).
DC_DTLZ = tuple(f"dc{kind}dtlz{base}" for kind in (1, 2, 3) for base in (1, 3))
PROBLEMS = (*(f"mw{i}" for i in range(1, 15)), *(f"ctp{i}" for i in range(1, 9)),
            *(f"dascmop{i}" for i in range(1, 10)), "zdt1", "zdt2", "zdt3", *DTLZ, *DC_DTLZ)
KNOWN = ("mw1..mw14, ctp1..ctp8, dascmop1..dascmop9, zdt1..zdt3, dtlz1..dtlz4, c1dtlz1, c1dtlz3, c2dtlz2, c3dtlz4, "
         "dc1dtlz1, dc1dtlz3, dc2dtlz1, dc2dtlz3, dc3dtlz1, dc3dtlz3")
"""PROBLEMS as a person reads them, for help texts and error messages."""
