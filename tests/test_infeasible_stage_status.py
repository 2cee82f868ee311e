"""A stage that ends with no feasible member says so, naming what its least violating member misses."""

from __future__ import annotations

import numpy as np

from core.kinematics.presets import get
from core.optimize import AlgorithmSpec, Stage, StageSpec, make_problem
from studio.study import status_text

X2 = get("stephenson1/X2").design()


def test_no_feasible_member_is_named_with_the_unmet_constraint_and_its_values():
    # Eq. 23 with an impossible h_s limit: no member can meet it.
    prob = make_problem("subtask3", n_samples=72, h_s_max=0.01)
    res = Stage(StageSpec("subtask3", prob, s=0.05, d=5.0, algorithm=AlgorithmSpec("nsga2", 12), n_gen=2,
                          seed=1), X2).run()
    assert not res.feasible.any()
    text = status_text(res)
    assert text.startswith("complete — no feasible member: ")
    i = int(np.argmin(res.cv))
    h_s = float(res.metrics["h_s"][i])
    assert f"h_s {h_s:.3g} > 0.01" in text


def test_a_stage_with_feasible_members_just_says_complete():
    prob = make_problem("subtask3", n_samples=72)
    res = Stage(StageSpec("subtask3", prob, s=0.05, d=5.0, algorithm=AlgorithmSpec("nsga2", 12), n_gen=2,
                          seed=1), X2).run()
    assert res.feasible.any() and status_text(res) == "complete"
