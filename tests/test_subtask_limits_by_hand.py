"""Subtask limits (Eqs. 22-23) reach the right metrics, and relative limits accept their boundary values."""

from __future__ import annotations

import pytest

from core.optimize.problem import make_problem
from core.optimize.subtasks import parse_relative


@pytest.mark.parametrize("name", ["subtask2", "subtask3"])
def test_each_eq22_limit_bounds_its_own_metric(name: str) -> None:
    # Distinct values, so a limit wired to the wrong option shows.
    spec = make_problem(name, f1_max=1.5, f2_max=2.5, f3_max=3.5, n_samples=72)
    upper = {c.metric: c.upper for c in spec.constraints}
    assert (upper["f1"], upper["f2"], upper["f3"]) == (1.5, 2.5, 3.5)


def test_each_eq23_limit_bounds_its_own_metric() -> None:
    spec = make_problem("subtask3", h_s_max=7.25, I_max=21.5, n_samples=72)
    upper = {c.metric: c.upper for c in spec.constraints}
    assert (upper["h_s"], upper["I"]) == (7.25, 21.5)


def test_a_relative_limit_may_equal_the_start() -> None:
    # "start+0" and "start*1" hold the start's own value: allowed (the start stays feasible), not refused.
    assert parse_relative("start+0") == ("+", 0.0)
    assert parse_relative("start*1") == ("*", 1.0)
    assert parse_relative("start+5") == ("+", 5.0)
