"""DC-DTLZ (Li, Chen, Fu, Yao, C-TAEA, 2018): DTLZ1 and DTLZ3 with constraints in decision space, as PlatEMO
defines them (``DC1_DTLZ1.m`` … ``DC3_DTLZ3.m``), the versions the spec's algorithms were compared on.

pymoo 0.6.2's ``DC*DTLZ*`` classes are other problems: DC1 cuts at cos(5 pi x1) >= 0.95, DC2 at
cos(3 pi g / 100) >= 0.9 and exp(-g / 100) >= 0.9, DC3 at cos(5 pi x) >= 0.5, their DTLZ3 variants keep DTLZ3's
100 g where PlatEMO's take 10 g, and none has a constrained Pareto front. Here, with G <= 0 feasible:

- DC1: ``0.5 - cos(3 pi x1)``: the front is the parts of DTLZ's front whose x1 is feasible;
- DC2: ``0.5 - cos(3 pi g)`` and ``0.5 - exp(-g)``: g = 0 meets both, the front is DTLZ's whole front;
- DC3: ``0.5 - cos(3 pi x_j)`` for j < M and ``0.5 - cos(3 pi g)``: the parts where every x_j is feasible.

Variables in [0, 1]; n_var = M + 4 (DTLZ1) or M + 9 (DTLZ3); g = 100 (DTLZ1) or 10 (DTLZ3) times
``k + sum((x - 0.5)^2 - cos(20 pi (x - 0.5)))`` over the last k = n_var - M + 1 variables.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from pymoo.core.problem import Problem

F64 = NDArray[np.float64]


def feasible_angle(x: F64, tol: float = 1e-12) -> NDArray[np.bool_]:
    """``cos(3 pi x) >= 0.5``: x in [0, 1/9] or [5/9, 7/9] (the DC constraint on a position variable or g), up to
    ``tol``: the Das-Dennis lattice of 99 steps has points exactly on x = 1/9, 5/9, 7/9 (the constraint's
    boundary, feasible), where rounding alone would decide."""
    return np.cos(3 * np.pi * x) >= 0.5 - tol


class DCDTLZ(Problem):
    """DC``kind``-DTLZ``base`` (kind 1, 2 or 3; base 1 or 3) with ``n_obj`` objectives, PlatEMO's definition."""

    def __init__(self, kind: int, base: int, n_obj: int = 3) -> None:
        if kind not in (1, 2, 3) or base not in (1, 3):
            raise ValueError(f"DC{kind}-DTLZ{base} is not a DC-DTLZ problem (DC1-3, DTLZ1 or DTLZ3)")
        if n_obj < 2:
            raise ValueError(f"DC-DTLZ needs at least 2 objectives, got {n_obj}")
        self.kind, self.base = kind, base
        n_constr = {1: 1, 2: 2, 3: n_obj}[kind]
        super().__init__(n_var=n_obj + (4 if base == 1 else 9), n_obj=n_obj, n_ieq_constr=n_constr, xl=0.0, xu=1.0,
                         vtype=float)

    def g(self, X: F64) -> F64:
        """``(n,)`` the distance function of the last k variables (0 on the front)."""
        Xm = X[:, self.n_obj - 1:] - 0.5
        return (100.0 if self.base == 1 else 10.0) * (Xm.shape[1] + (Xm**2 - np.cos(20 * np.pi * Xm)).sum(axis=1))

    def _evaluate(self, X, out, *args, **kwargs):
        X = np.asarray(X, dtype=np.float64)
        g = self.g(X)
        P = X[:, : self.n_obj - 1]
        one = np.ones((len(X), 1))
        if self.base == 1:  # f_i = 0.5 (1 + g) x_1 ... x_{M-i} (1 - x_{M-i+1})
            lead = np.cumprod(np.hstack([one, P]), axis=1)[:, ::-1]
            tail = np.hstack([one, 1.0 - P[:, ::-1]])
            out["F"] = 0.5 * (1.0 + g)[:, None] * lead * tail
        else:  # f_i = (1 + g) cos(x_1 pi/2) ... cos(x_{M-i} pi/2) sin(x_{M-i+1} pi/2)
            lead = np.cumprod(np.hstack([one, np.cos(P * np.pi / 2)]), axis=1)[:, ::-1]
            tail = np.hstack([one, np.sin(P[:, ::-1] * np.pi / 2)])
            out["F"] = (1.0 + g)[:, None] * lead * tail
        cut = 0.5 - np.cos(3 * np.pi * g)
        if self.kind == 1:
            out["G"] = (0.5 - np.cos(3 * np.pi * X[:, 0]))[:, None]
        elif self.kind == 2:
            out["G"] = np.column_stack([cut, 0.5 - np.exp(-g)])
        else:
            out["G"] = np.column_stack([0.5 - np.cos(3 * np.pi * P), cut])

    def positions(self, R: F64) -> F64:
        """``(n, M - 1)`` the position variables x_1 … x_{M-1} of front points R (g = 0). A variable that does not
        move the point (a corner or an edge, where an earlier factor is 0) is given 0, which is feasible."""
        R = np.asarray(R, dtype=np.float64)
        M = self.n_obj
        x = np.zeros((len(R), M - 1))
        for j in range(M - 1):  # x_{j+1} from f_{M-j} against the coordinates before it
            head = R[:, : M - 1 - j]
            if self.base == 1:  # simplex: x_{j+1} = S_{M-j-1} / S_{M-j}, S_k = R_1 + ... + R_k
                whole = head.sum(axis=1) + R[:, M - 1 - j]
                with np.errstate(invalid="ignore", divide="ignore"):
                    x[:, j] = np.where(whole > 0, head.sum(axis=1) / whole, 0.0)
            else:  # sphere: x_{j+1} = (2 / pi) atan2(R_{M-j}, |R_1 .. R_{M-j-1}|)
                x[:, j] = np.arctan2(R[:, M - 1 - j], np.linalg.norm(head, axis=1)) * 2 / np.pi
        return x

    def _calc_pareto_front(self, ref_dirs: F64 | None = None) -> F64:
        """The front on the given directions (Das-Dennis, rows summing to 1): DTLZ1's half simplex or DTLZ3's unit
        sphere, less the points whose position variables are infeasible (DC1: x_1, DC3: every one)."""
        if ref_dirs is None:
            from math import comb

            from core.optimize.evolve.weights import simplex_lattice

            H = 99 if self.n_obj == 3 else 12
            ref_dirs = simplex_lattice(comb(H + self.n_obj - 1, self.n_obj - 1), self.n_obj)
        R = np.asarray(ref_dirs, dtype=np.float64)
        R = R / 2 if self.base == 1 else R / np.linalg.norm(R, axis=1, keepdims=True)
        if self.kind == 2:
            return R
        x = self.positions(R)
        ok = feasible_angle(x[:, 0]) if self.kind == 1 else feasible_angle(x).all(axis=1)
        return R[ok]
