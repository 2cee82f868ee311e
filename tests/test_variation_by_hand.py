"""PlatEMO's SBX, GA/GAhalf and DE/rand/1 (spec §1.5) on single children computed by hand from given random
numbers: which power of u, which branch, which sign, which child comes first, and the default mutation rate."""

from __future__ import annotations

import math

import numpy as np

from core.optimize.evolve.variation import de_rand_1, ga, sbx


class Draws:
    """A stand-in Generator whose ``random`` hands out prepared arrays, in order (their shapes checked)."""

    def __init__(self, *arrays) -> None:
        self.arrays = [np.asarray(a, dtype=float) for a in arrays]

    def random(self, shape=None):
        a = self.arrays.pop(0)
        assert a.shape == (() if shape is None else np.empty(shape).shape)
        return a


ETA = 20.0
B_LOW = 0.5 ** (1 / (ETA + 1))  # beta for u = 0.25: (2u)^(1/(eta+1))
B_HIGH = 0.5 ** (-1 / (ETA + 1))  # beta for u = 0.75: (2 - 2u)^(-1/(eta+1))

# One pair, p1 = 0.2 and p2 = 0.8 in every variable (mid 0.5, (p1 - p2)/2 = -0.3), four variables:
#   0: u 0.25 (beta below 1), sign 0.7 (kept positive), recombined (var 0.1 < 0.5);
#   1: u 0.75 (beta above 1), sign 0.2 (negated), recombined;
#   2: u 0.25, sign 0.2 (negated), recombined;
#   3: var 0.9 >= 0.5: not recombined, the parents as they are.
P1, P2 = np.full((1, 4), 0.2), np.full((1, 4), 0.8)
U, SIGN, VAR, PAIR = [[0.25, 0.75, 0.25, 0.6]], [[0.7, 0.2, 0.2, 0.7]], [[0.1, 0.3, 0.4, 0.9]], [0.0]
C1 = [0.5 - 0.3 * B_LOW, 0.5 + 0.3 * B_HIGH, 0.5 + 0.3 * B_LOW, 0.2]  # c1 = mid + beta (p1 - p2) / 2
C2 = [0.5 + 0.3 * B_LOW, 0.5 - 0.3 * B_HIGH, 0.5 - 0.3 * B_LOW, 0.8]  # c2 = mid - beta (p1 - p2) / 2


def test_sbx_children_of_one_pair_by_hand():
    c1, c2 = sbx(P1, P2, np.zeros(4), np.ones(4), Draws(U, SIGN, VAR, PAIR))  # type: ignore[arg-type]
    np.testing.assert_allclose(c1, [C1], rtol=1e-14)
    np.testing.assert_allclose(c2, [C2], rtol=1e-14)
    # a pair that fails the crossover probability keeps its parents in every variable
    c1, c2 = sbx(P1, P2, np.zeros(4), np.ones(4), Draws(U, SIGN, VAR, [0.95]), prob=0.9)  # type: ignore[arg-type]
    assert c1.tolist() == P1.tolist() and c2.tolist() == P2.tolist()


def test_sbx_children_are_clipped_to_the_bounds():
    # beta (2 - 2u)^(-1/21) at u = 1 - 1e-12 is ~3.7: the children leave [0, 1] and are put back on its edges
    c1, c2 = sbx(np.array([[0.1]]), np.array([[0.9]]), np.zeros(1), np.ones(1),
                 Draws([[1 - 1e-12]], [[0.7]], [[0.0]], [0.0]))  # type: ignore[arg-type]
    beta = (2e-12) ** (-1 / 21)
    assert 0.5 - 0.4 * beta < 0 and c1.tolist() == [[0.0]] and c2.tolist() == [[1.0]]


def test_ga_half_keeps_the_first_child_with_eta_c_20():
    # GA: SBX (eta_c 20), then polynomial mutation (site numbers 0.99: no variable mutated); GAhalf keeps c1.
    no_site = np.full((1, 4), 0.99)
    half = ga(P1, P2, np.zeros(4), np.ones(4), Draws(U, SIGN, VAR, PAIR, no_site, no_site), half=True)  # type: ignore[arg-type]
    np.testing.assert_allclose(half, [C1], rtol=1e-14)
    both = ga(P1, P2, np.zeros(4), np.ones(4), Draws(U, SIGN, VAR, PAIR, np.full((2, 4), 0.99),
                                                     np.full((2, 4), 0.5)))  # type: ignore[arg-type]
    np.testing.assert_allclose(both, [C1, C2], rtol=1e-14)


def _pm_lower(x: float, u: float, eta: float = 20.0) -> float:
    """Deb's bounded polynomial mutation in [0, 1], u <= 0.5: x + (2u + (1 - 2u)(1 - x)^(eta+1))^(1/(eta+1)) - 1."""
    return x + (2 * u + (1 - 2 * u) * (1 - x) ** (eta + 1)) ** (1 / (eta + 1)) - 1


def test_de_rand_1_mutates_each_variable_with_probability_one_over_d_by_default():
    # d = 4: pm = 1/4. A site number of 0.22 (< 1/4, > 1/5) mutates; 0.26 does not. DE's CR numbers first
    # (r < CR = 1 everywhere), then the mutation's site numbers, then its u.
    x1, x2, x3 = np.full((1, 4), 0.4), np.full((1, 4), 0.5), np.full((1, 4), 0.3)
    r, site, u = np.full((1, 4), 0.5), [[0.22, 0.26, 0.9, 0.9]], [[0.25, 0.25, 0.25, 0.25]]
    got = de_rand_1(x1, x2, x3, np.zeros(4), np.ones(4), Draws(r, site, u))  # type: ignore[arg-type]
    base = 0.4 + 0.5 * (0.5 - 0.3)  # x1 + F (x2 - x3), F = 0.5
    np.testing.assert_allclose(got, [[_pm_lower(base, 0.25), base, base, base]], rtol=1e-13)
    # per-child F and CR (the numpy path): the same default rate
    got = de_rand_1(x1, x2, x3, np.zeros(4), np.ones(4), Draws(r, site, u), F=np.array([[0.5]]),  # type: ignore[arg-type]
                    CR=np.array([[1.0]]))
    np.testing.assert_allclose(got, [[_pm_lower(base, 0.25), base, base, base]], rtol=1e-13)
    assert math.isclose(_pm_lower(0.5, 0.5), 0.5)  # u = 0.5 leaves x where it is: the formula's own check
