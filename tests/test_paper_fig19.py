"""scripts/paper_fig19.py: the Fig. 19 deviations from a study's rows, by hand; a case without a pick is said."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest


def fig19():
    path = Path(__file__).parents[1] / "scripts" / "paper_fig19.py"
    spec = importlib.util.spec_from_file_location("paper_fig19", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def row(alg: str, k: int, dh6: float, dh4: float, ok: bool = True) -> dict:
    return {"status": "done", "case": f"rtclm_case{k}", "algorithm": alg,
            "metrics": {"pick": {"dh6": dh6, "dh4": dh4}, "pick_feasible": ok, "feasible_ratio": 0.5}}


def test_the_best_of_each_case_averaged_over_five_and_a_missing_case_named(monkeypatch, capsys):
    mod = fig19()
    rows = [row("a", k, 1.0, -2.0) for k in range(1, 6)] + [row("a", 1, 5.0, 5.0, ok=False)]
    rows += [row("b", k, 1.0, 1.0) for k in range(1, 5)]  # case 5 failed
    monkeypatch.setattr(mod, "read_study", lambda d: ({"study": {"labels": {"a": "A", "b": "B"}}}, rows))
    monkeypatch.setattr(mod, "current_rows", lambda study, r: r)
    mod.main("unused")
    out = capsys.readouterr().out.splitlines()
    a = next(ln for ln in out if ln.startswith("| A |")).split("|")
    assert float(a[2]) == pytest.approx(3.0)  # |1| + |-2| in each case, the worse seed of case 1 not taken
    assert float(a[3]) == pytest.approx(1000 * 1.0 / 50.0, abs=0.05)
    assert a[5].strip() == "5/6"
    assert next(ln for ln in out if ln.startswith("| B |")) == "| B | – | – | – | 4/4 (no pick in case 5) |"
