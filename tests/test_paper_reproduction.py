"""Appendix B-1, Stephenson-I X0-X3: our S and MSE against the printed values.

The paper's S divides h_s by the nominal 300 mm (spec §4), so its printed S is compared with
our h_s / 300; our S (h_s / l_s) reads ~3 % higher and is checked against h_s / l_s itself. The
printed values live in benchmarks/reproduce_paper.py, which also writes docs/paper-reproduction.md.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from core.analysis.evaluate import evaluate
from core.kinematics.presets import get

_spec = importlib.util.spec_from_file_location(
    "reproduce_paper", Path(__file__).resolve().parents[1] / "benchmarks" / "reproduce_paper.py"
)
assert _spec is not None and _spec.loader is not None
repro = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(repro)


@pytest.mark.parametrize("name", repro.ACCEPTANCE)
def test_straightness_and_shape_error_match_the_paper(name: str) -> None:
    paper_s, _, paper_mse, paper_hs = repro.PAPER[name]
    ev = evaluate(get(name).design(), repro.N_SAMPLES, backend="numpy")
    assert ev.feasible[0]
    assert 100.0 * ev.h_s[0] / 300.0 == pytest.approx(paper_s, abs=repro.S_TOL)
    assert ev.mse[0] == pytest.approx(paper_mse, abs=repro.MSE_TOL)
    assert ev.h_s[0] == pytest.approx(paper_hs, abs=3.0 * repro.S_TOL)  # 0.3 % of 300 mm
    assert ev.S[0] == pytest.approx(100.0 * ev.h_s[0] / ev.l_s[0])
    assert 280.0 < ev.l_s[0] < 300.0  # why the paper's S reads lower: l_s is a little under 300 mm
