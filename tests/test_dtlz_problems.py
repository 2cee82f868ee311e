"""DTLZ and constrained DTLZ in ``clm moea``: PlatEMO's sizes, reference fronts from the definitions, and a run."""

from __future__ import annotations

import numpy as np
import pytest
from pymoo.problems.many.cdtlz import constraint_c2, constraint_c3_spherical

from core.cli import main
from core.optimize.moea import DTLZ, LATTICE, igd, problem_by_name, reference_front, run

SPHERES = ("dtlz2", "dtlz3", "dtlz4", "c1dtlz3", "c2dtlz2")


@pytest.mark.parametrize(("name", "n_var", "n_constr"), [
    ("dtlz1", 7, 0), ("dtlz2", 12, 0), ("dtlz3", 12, 0), ("dtlz4", 12, 0),
    ("c1dtlz1", 7, 1), ("c1dtlz3", 12, 1), ("c2dtlz2", 12, 1), ("c3dtlz4", 7, 3),
])
def test_platemo_sizes_at_three_objectives(name, n_var, n_constr):
    p = problem_by_name(name.upper())
    assert (p.n_var, p.n_obj, p.n_ieq_constr) == (n_var, 3, n_constr)


def test_dtlz1_fronts_lie_on_the_half_simplex():
    for name in ("dtlz1", "c1dtlz1"):
        pf = reference_front(name)
        assert pf.shape == (LATTICE, 3)
        np.testing.assert_allclose(pf.sum(axis=1), 0.5, atol=1e-12)
        assert pf.min() == 0.0 and pf.max() == 0.5  # the corners are on the lattice


@pytest.mark.parametrize("name", SPHERES)
def test_sphere_fronts_lie_on_the_unit_sphere(name):
    pf = reference_front(name)
    np.testing.assert_allclose(np.linalg.norm(pf, axis=1), 1.0, atol=1e-12)
    assert (pf >= 0).all()


def test_c2dtlz2_front_is_the_feasible_part_of_the_sphere():
    # r = 0.4 at three objectives: on the unit sphere a corner cap is f_i >= 0.92 and the middle cap
    # sum f >= 0.92 sqrt(3); together ~56 % of the octant's area.
    pf, sphere = reference_front("c2dtlz2"), reference_front("dtlz2")
    assert (constraint_c2(pf, 0.4) <= 0).all()
    assert 0.4 * LATTICE < len(pf) < 0.7 * LATTICE
    left_out = sphere[~(sphere[:, None, :] == pf[None, :, :]).all(axis=2).any(axis=1)]
    assert len(left_out) == LATTICE - len(pf) and (constraint_c2(left_out, 0.4) > 0).all()
    corner = (pf.max(axis=1) >= 0.92 - 1e-9)
    middle = pf.sum(axis=1) >= 0.92 * np.sqrt(3) - 1e-9
    assert (corner | middle).all()


def test_c3dtlz4_front_meets_its_constraints_with_one_active():
    # c_j = f_j^2 / 4 + sum_{i != j} f_i^2 - 1 >= 0 for every j: the front is the sphere pushed out until the
    # tightest one is met with equality; the corners go out to 2.
    pf = reference_front("c3dtlz4")
    G = constraint_c3_spherical(pf)  # pymoo: G <= 0 is feasible
    assert (G <= 1e-12).all()
    np.testing.assert_allclose(G.max(axis=1), 0.0, atol=1e-12)
    assert pf.max() == pytest.approx(2.0)


def test_a_front_is_at_distance_zero_from_itself():
    for name in DTLZ:
        pf = reference_front(name)
        assert igd(pf, pf) == 0.0


def test_nsga2_converges_on_dtlz2_and_stays_feasible_on_c2dtlz2():
    # PlatEMO's NSGA-II reaches an IGD of ~0.06-0.07 on DTLZ2 at this budget; a front far from the sphere (a
    # wrong reference front, or an algorithm that does not converge) is well above 0.1.
    r = run("dtlz2", "nsga2", 100, 20_000, 1)
    assert r["igd"] < 0.1 and r["feasible"] == 100
    r = run("c2dtlz2", "nsga2", 100, 20_000, 1)
    assert r["igd"] < 0.1 and r["feasible"] == r["size"] == 100


def test_the_cli_counts_the_population_the_algorithm_keeps(capsys):
    # MOEA/D-CMT keeps the Das-Dennis N (91 for 100 at three objectives): the line says "of 91", not "of 100".
    assert main(["moea", "--problem", "c1dtlz1", "--algorithm", "moead_cmt", "--pop", "100", "--evals", "2000"]) == 0
    out = capsys.readouterr().out
    assert "(pop 100, seed 1)" in out and " of 91 feasible" in out


def test_unknown_problem_names_the_dtlz_family(capsys):
    assert main(["moea", "--problem", "dtlz9"]) == 2
    assert "dtlz1..dtlz4" in capsys.readouterr().err
