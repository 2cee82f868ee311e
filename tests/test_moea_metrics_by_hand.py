"""``clm moea``'s indicators on tiny hand-made fronts (PlatEMO's IGD and normalised HV), and its argument range."""

from __future__ import annotations

import moocore
import numpy as np
import pytest

from core.optimize.dcdtlz import DCDTLZ
from core.optimize.moea import hv_platemo, igd, reference_front, run

PF = np.array([[0.0, 1.0], [1.0, 0.0]])


def test_igd_averages_over_the_reference_front_not_over_the_members() -> None:
    # One member on one end of the front: the reference points are 0 and sqrt(2) from it, IGD = sqrt(2) / 2.
    # (Measured the other way round, from the member to the front, the distance would be 0.)
    assert igd(np.array([[0.0, 1.0]]), PF) == pytest.approx(np.sqrt(2.0) / 2.0)
    # Two members, three reference points: distances 0, 0.5, 0 -> 1/6.
    pf3 = np.array([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    F = np.array([[0.0, 1.0], [1.0, 0.0]])
    assert igd(F, pf3) == pytest.approx(np.hypot(0.5, 0.5) / 3.0)


def test_hv_is_zero_without_members_and_nan_without_a_front() -> None:
    assert hv_platemo(np.zeros((0, 2)), PF) == 0.0
    assert np.isnan(hv_platemo(np.array([[0.5, 0.5]]), None))


def test_hv_normalises_by_the_front_s_range_times_1_1_and_drops_points_beyond_it() -> None:
    # fmax = (1, 1), fmin = (0, 0): (0.55, 0.55) -> (0.5, 0.5), HV 0.25; (1.21, 0) -> (1.1, 0), dropped.
    assert hv_platemo(np.array([[0.55, 0.55]]), PF) == pytest.approx(0.25)
    assert hv_platemo(np.array([[0.55, 0.55], [1.21, 0.0]]), PF) == pytest.approx(0.25)
    # (1.1, 0) normalises to (1, 0): kept, and it adds nothing (its box is flat).
    assert hv_platemo(np.array([[1.1, 0.0], [0.55, 0.55]]), PF) == pytest.approx(0.25)
    # A front with other ranges per objective: fmax = (2, 4) -> (1.1, 2.2) scales (1.1, 1.1) to (0.5, 0.5).
    assert hv_platemo(np.array([[1.1, 2.2]]), np.array([[0.0, 4.0], [2.0, 0.0]])) == pytest.approx(0.25)


def test_moocore_ignores_a_point_that_does_not_dominate_the_reference() -> None:
    # Why keeping (0.5, 1.8) in the normalised set would change nothing (a point with a coordinate > 1).
    assert moocore.hypervolume(np.array([[0.5, 0.5], [0.2, 1.8]]), ref=np.ones(2)) == pytest.approx(0.25)


def test_the_smallest_population_is_four() -> None:
    # pop = 4 passes the population check and reaches the next one (a zero budget); pop = 3 does not.
    with pytest.raises(ValueError, match="--evals"):
        run("zdt1", "nsga2", 4, 0, 0)
    with pytest.raises(ValueError, match="--pop"):
        run("zdt1", "nsga2", 3, 8, 0)


@pytest.mark.parametrize("name", ["dc2dtlz1", "dc2dtlz3"])
def test_the_default_front_is_the_reference_lattice(name: str) -> None:
    # DC2 keeps DTLZ's whole front: without directions it is the same 5050-point (H = 99) lattice as clm moea's.
    kind, base = int(name[2]), int(name[-1])
    own = DCDTLZ(kind, base, 3).pareto_front()
    assert own.shape == (5050, 3)
    np.testing.assert_allclose(np.sort(own, axis=0), np.sort(reference_front(name), axis=0), atol=1e-12)
