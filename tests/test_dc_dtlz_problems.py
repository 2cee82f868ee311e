"""DC-DTLZ as PlatEMO defines it (core/optimize/dcdtlz.py): sizes, hand-computed values, fronts that the problem
attains, and a run through ``clm moea``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymoo.problems import get_problem

from core.cli import main
from core.optimize.dcdtlz import DCDTLZ
from core.optimize.moea import DC_DTLZ, LATTICE, problem_by_name, reference_front, run


def evaluate(p, X):
    out = p.evaluate(np.atleast_2d(np.asarray(X, dtype=float)), return_as_dictionary=True)
    return out["F"], out["G"]


@pytest.mark.parametrize(("name", "n_var", "n_constr"), [
    ("dc1dtlz1", 7, 1), ("dc1dtlz3", 12, 1), ("dc2dtlz1", 7, 2), ("dc2dtlz3", 12, 2), ("dc3dtlz1", 7, 3),
    ("dc3dtlz3", 12, 3),
])
def test_platemo_sizes_at_three_objectives(name, n_var, n_constr):
    p = problem_by_name(name.upper())
    assert (p.n_var, p.n_obj, p.n_ieq_constr) == (n_var, 3, n_constr)
    assert (p.xl == 0).all() and (p.xu == 1).all()


def test_hand_computed_values():
    # Distance variables at 0.5: g = c (k + sum(0 - cos 0)) = 0.
    F, G = evaluate(DCDTLZ(1, 1), [0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5])
    np.testing.assert_allclose(F, [[0, 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(G, [[-0.5]])  # 0.5 - cos(0)
    F, G = evaluate(DCDTLZ(1, 1), [1 / 3, 0.5] + [0.5] * 5)
    np.testing.assert_allclose(F, [[1 / 12, 1 / 12, 1 / 3]])  # 0.5 x1 x2, 0.5 x1 (1 - x2), 0.5 (1 - x1)
    np.testing.assert_allclose(G, [[1.5]])  # 0.5 - cos(pi)
    F, G = evaluate(DCDTLZ(3, 3), [1 / 3, 0] + [0.5] * 10)
    np.testing.assert_allclose(F, [[np.cos(np.pi / 6), 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(G, [[1.5, -0.5, -0.5]])
    # One distance variable at 0: (-0.5)^2 - cos(-10 pi) = -0.75, the nine others -1: g = 10 (10 - 9.75) = 2.5,
    # DTLZ3's factor 10 (PlatEMO's DC versions), where DTLZ3 itself has 100.
    X = [0.5, 0.5, 0] + [0.5] * 9
    F, G = evaluate(DCDTLZ(2, 3), X)
    np.testing.assert_allclose(G, [[0.5 - np.cos(7.5 * np.pi), 0.5 - np.exp(-2.5)]], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(F), 3.5)  # (1 + g) on the unit sphere
    F, G = evaluate(DCDTLZ(3, 1), [0.5, 0.5, 0] + [0.5] * 4)  # g = 100 (5 - 4.75) = 25: 0.5 - cos(75 pi) = 1.5
    np.testing.assert_allclose(G, [[0.5 - np.cos(1.5 * np.pi), 0.5 - np.cos(1.5 * np.pi), 1.5]], atol=1e-12)
    np.testing.assert_allclose(F.sum(), 13.0)  # 0.5 (1 + g) on the simplex


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from([1, 2, 3]))
def test_objectives_are_dtlz1_and_dtlz3_with_a_tenth_of_its_g(seed, kind):
    X = np.random.default_rng(seed).random((20, 7))
    np.testing.assert_allclose(evaluate(DCDTLZ(kind, 1), X)[0], get_problem("dtlz1", n_var=7, n_obj=3).evaluate(X),
                               rtol=1e-12)
    X = np.random.default_rng(seed).random((20, 12))
    p = DCDTLZ(kind, 3)
    g = p.g(X)
    unit = get_problem("dtlz2", n_var=12, n_obj=3).evaluate(np.hstack([X[:, :2], np.full((20, 10), 0.5)]))
    np.testing.assert_allclose(evaluate(p, X)[0], (1 + g)[:, None] * unit, rtol=1e-12)
    np.testing.assert_allclose(get_problem("dtlz3", n_var=12, n_obj=3).evaluate(X), (1 + 10 * g)[:, None] * unit,
                               rtol=1e-9)


@pytest.mark.parametrize("name", DC_DTLZ)
def test_the_front_is_attained_and_feasible_and_what_it_leaves_out_is_not(name):
    # Each lattice point of DTLZ's front is made from its position variables (distance variables at 0.5, g = 0):
    # the problem gives back the point, feasible when it is on the reference front, infeasible otherwise.
    p = problem_by_name(name)
    pf = reference_front(name)
    whole = reference_front("dtlz1" if name.endswith("1") else "dtlz2")
    assert pf.shape[1] == 3 and len(whole) == LATTICE
    X = np.hstack([p.positions(whole), np.full((len(whole), p.n_var - 2), 0.5)])
    F, G = evaluate(p, X)
    np.testing.assert_allclose(F, whole, atol=1e-12)
    kept = (whole[:, None, :] == pf[None, :, :]).all(axis=2).any(axis=1)
    assert kept.sum() == len(pf)
    assert (G[kept] <= 1e-12).all()
    assert (G[~kept].max(axis=1) > 0).all()
    # Sizes counted independently with exact fractions on the lattice (the DTLZ1 variants) and against PlatEMO's
    # formulas (the DTLZ3 ones, whose boundary points are 2e-4 away in cos(3 pi x) from 0.5).
    assert len(pf) == {"dc1dtlz1": 1619, "dc1dtlz3": 2033, "dc2dtlz1": LATTICE, "dc2dtlz3": LATTICE,
                       "dc3dtlz1": 551, "dc3dtlz3": 696}[name]


def test_a_corner_whose_free_variable_can_be_feasible_is_on_the_front():
    # DC3-DTLZ1's corner (0, 0, 1/2) is x1 = 0 with x2 free: feasible with x2 = 0. A positions() that gave a free
    # variable an infeasible value would lose it (and the round trip above would not notice).
    pf = reference_front("dc3dtlz1")
    assert (np.abs(pf - [0.0, 0.0, 0.5]).max(axis=1) < 1e-15).any()


def test_lattice_points_on_the_constraints_boundary_are_on_the_front():
    # x1 = 7/9 (f3 = 0.5 (1 - x1) = 1/9 on DC1-DTLZ1's half simplex) is on the boundary cos(3 pi x1) = 0.5:
    # feasible, and the 99-step lattice has points there; rounding alone must not drop them.
    pf = reference_front("dc1dtlz1")
    on = np.isclose(pf[:, 2], 1 / 9, atol=1e-12)
    assert on.sum() == 78  # the lattice's whole row R3 = 2 f3 = 22/99 (R1 + R2 = 77/99: 78 points); DC1 cuts on x1 only
    assert (pf[:, 2] >= 1 / 9 - 1e-12).all()


def test_pymoos_classes_of_the_same_names_are_other_problems():
    # The reason for our own: pymoo 0.6.2's DC1 cuts at cos(5 pi x1) >= 0.95, PlatEMO's at cos(3 pi x1) >= 0.5.
    x = np.array([[0.1] + [0.5] * 6])
    assert evaluate(DCDTLZ(1, 1), x)[1][0, 0] < 0 < get_problem("dc1dtlz1", n_var=7).evaluate(x, return_values_of=["G"])


def test_unknown_kinds_are_refused():
    with pytest.raises(ValueError, match="not a DC-DTLZ problem"):
        DCDTLZ(4, 1)
    with pytest.raises(ValueError, match="not a DC-DTLZ problem"):
        DCDTLZ(1, 2)


def test_nsga2_converges_on_dc1dtlz1_and_the_cli_runs_dc1dtlz3(capsys):
    # NSGA-II gets to ~0.015 at this budget; DTLZ1's multimodal g leaves a population that has not converged at
    # 0.1 or more, and a front with the wrong gaps is off by the gaps' width.
    r = run("dc1dtlz1", "nsga2", 100, 20_000, 1)
    assert r["feasible"] == r["size"] == 100 and r["reference_points"] == len(reference_front("dc1dtlz1"))
    assert r["igd"] < 0.04
    assert main(["moea", "--problem", "dc1dtlz3", "--algorithm", "nsga2", "--pop", "20", "--evals", "400"]) == 0
    assert "dc1dtlz3" in capsys.readouterr().out
