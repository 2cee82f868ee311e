"""Search boxes computed by hand (spec §6): x ± max(s|x|, d), angles d = s·π, clipped; the crank phase wraps."""

from __future__ import annotations

import numpy as np
import pytest

from core.kinematics.mechanisms.stephenson import STEPHENSON1
from core.kinematics.presets import PRESETS
from core.optimize.box import search_box

# b = 0.48, g = 3.25, ..., r1 = 55.47, ..., r4 = 126.49, r5 = 50.62, r6 = -5.88
X2 = np.array(PRESETS["stephenson1/X2"].values)
IDX = {n: i for i, n in enumerate(STEPHENSON1.param_names)}


def test_subtask2_box_around_x2_by_hand() -> None:
    box = search_box(STEPHENSON1, X2, 0.1, 10.0)
    expect = {
        "r4": (126.49 - 12.649, 126.49 + 12.649),  # 10 % of 126.49 beats 10 mm
        "r1": (45.47, 65.47),  # 10 mm beats 10 % of 55.47
        "r6": (-15.88, 4.12),  # an offset of -5.88: 10 mm beats 0.588
        "b": (0.48 - 0.1 * np.pi, 0.48 + 0.1 * np.pi),  # an angle: d = s·π
        # g = 3.25 wraps to 3.25 - 2π and its box crosses -π (not clipped).
        "g": (3.25 - 2 * np.pi - 0.1 * np.pi, 3.25 - 2 * np.pi + 0.1 * np.pi),
    }
    for name, (lo, hi) in expect.items():
        assert (box.lower[IDX[name]], box.upper[IDX[name]]) == pytest.approx((lo, hi), abs=1e-12), name


def test_a_wide_rule_clips_lengths_at_their_bounds_and_gives_a_phase_exactly_one_turn() -> None:
    # s = 1.5, d = 100: r5 = 50.62 -> 50.62 ± 100 clipped to [30, 150.62]; g's half-width 1.5·π > π is held at π.
    box = search_box(STEPHENSON1, X2, 1.5, 100.0)
    assert box.lower[IDX["r5"]] == 30.0
    assert box.upper[IDX["r5"]] == pytest.approx(150.62)
    for name in ("b", "g"):
        assert box.upper[IDX[name]] - box.lower[IDX[name]] == pytest.approx(2 * np.pi, abs=1e-12), name


def test_contains_takes_the_bounds_themselves_and_refuses_a_moved_fixed_parameter() -> None:
    box = search_box(STEPHENSON1, X2, 0.1, 10.0, fixed=("x_a",))
    # The box's own corners are in it.
    assert box.contains(box.decode(box.xu[None])).all()
    assert box.contains(box.decode(box.xl[None])).all()
    # Just past the upper bound of r1 is not.
    p = box.decode(box.xu[None])
    p[0, IDX["r1"]] += 1e-6
    assert not box.contains(p).any()
    # A fixed parameter moved either way is not in the box.
    for delta in (-1.0, 1.0):
        q = X2.copy()[None]
        q[0, IDX["x_a"]] += delta
        assert not box.contains(q).any(), delta
    assert box.contains(X2[None]).all()
