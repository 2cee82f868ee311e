"""Where a designer reads the ground clearance and the RTCLM's other mode: the studio's Metrics rows (and the line
above the table) and `clm evaluate`, each against numbers computed here from core."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from core.analysis.clearance import ground_clearance
from core.analysis.evaluate import evaluate
from core.kinematics.design import Design
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY
from core.kinematics.presets import get
from core.optimize.rtclm import mode_clearance
from studio.metrics import Row, metrics_html
from studio.state import build_view
from studio.target import TargetSpec


def rows(preset: str) -> dict[str, Row]:
    view = build_view(get(preset).design(), preset, TargetSpec())
    return {r.key: r for r in view.rows}


def test_an_upside_down_leg_is_said_in_red_above_the_metrics() -> None:
    r = rows("rtclm/case1-CMOES")["clearance"]
    ev = evaluate(get("rtclm/case1-CMOES").design())
    assert r.value == pytest.approx(float(ev.clearance[0]), abs=1e-9) and r.severe
    # B (the crank tip) is the lowest, at the value shown; the frame pivot A below the ground is said too.
    assert r.warn.startswith(f"B is lowest, {-r.value:.1f} mm below the ground the foot stands on; A (fixed) sits "
                             "108.9 mm below the ground the foot stands on")
    view = build_view(get("rtclm/case1-CMOES").design(), "rtclm/case1-CMOES", TargetSpec())
    banner = metrics_html(view.rows).split("<table")[0]
    assert "Ground clearance" in banner and "A (fixed) sits 108.9 mm" in banner


def test_a_leg_standing_on_its_foot_has_an_unmarked_row_and_a_pantograph_has_none() -> None:
    r = rows("jansen")["clearance"]
    assert r.value == pytest.approx(float(evaluate(get("jansen").design()).clearance[0]), abs=1e-9)
    assert r.warn == "" and "T" in r.note
    assert "clearance" not in rows("stephenson1/X3") and "other_mode" not in rows("stephenson1/X3")


def test_the_rtclm_shows_its_other_mode_in_one_row() -> None:
    primary = get("rtclm/case4").design()
    aux = Design(RTCLM_AUXILIARY, primary.params)
    here, there = evaluate(primary), evaluate(aux)
    r = rows("rtclm/case4")["other_mode"]
    shift = float(here.y_min[0] - there.y_min[0])
    mu = float(there.transmission[0])
    assert r.label == "Auxiliary mode"
    # Its crossing height first: the h4 an RTCLM case is judged on (rehearsal 6 loaded a study's design and saw h6).
    # Both legs' clearance (review of session 30: the right leg's alone passed only because case 4's left B and C
    # are not its lowest joints).
    both = mode_clearance(ground_clearance(aux.solve(360), aux.mechanism, aux.output), aux.mechanism, aux.params)
    assert r.value == (f"h4 {float(there.h_m[0]):.1f} mm, μ {mu:.1f}°, clearance {float(both.value[0]):.0f} mm, "
                       f"stance {abs(shift):.0f} mm {'lower' if shift > 0 else 'higher'}")
    assert (r.warn != "") == (mu < 40.0)
    # The other way round: the auxiliary preset names the primary mode, with the opposite shift.
    back = rows("rtclm/case4/auxiliary")["other_mode"]
    assert back.label == "Primary mode" and str(back.value).startswith(f"h6 {float(here.h_m[0]):.1f} mm, ")
    assert f"stance {abs(shift):.0f} mm {'higher' if shift > 0 else 'lower'}" in str(back.value)


def test_an_other_mode_that_does_not_assemble_is_red() -> None:
    # The paper's case-1 IMTCMO row: its primary mode assembles, its auxiliary mode does not.
    params = get("rtclm/case1-IMTCMO").design().params
    assert evaluate(Design(RTCLM_AUXILIARY, params)).violation[0] > 0
    r = rows("rtclm/case1-IMTCMO")["other_mode"]
    assert r.value == "does not assemble" and r.severe


def clm(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "core.cli", *args], capture_output=True, text=True, timeout=300)


def test_clm_evaluate_prints_and_writes_the_clearance(tmp_path: Path) -> None:
    out = clm("evaluate", "--preset", "rtclm/case1-CMOES")
    assert out.returncode == 0, out.stderr
    line = next(ln for ln in out.stdout.splitlines() if ln.strip().startswith("ground clearance"))
    value = float(evaluate(get("rtclm/case1-CMOES").design()).clearance[0])
    assert f"{value:.1f}  mm: B is lowest, {-value:.1f} mm below" in line and "A (fixed) sits 108.9 mm below" in line
    data = json.loads(clm("evaluate", "--preset", "jansen", "--json").stdout)
    assert data["clearance"] == pytest.approx(float(evaluate(get("jansen").design()).clearance[0]), abs=1e-9)
    assert data["clearance_note"].endswith("(lowest point after the foot: T)")
    x3 = json.loads(clm("evaluate", "--preset", "stephenson1/X3", "--json").stdout)
    assert x3["clearance"] is None and x3["clearance_note"] is None  # a pantograph's bars are not modelled
    assert not any("ground clearance" in ln for ln in clm("evaluate", "--preset", "stephenson1/X3").stdout.splitlines())


def test_clm_evaluate_of_an_rtclm_run_names_the_runs_h4(tmp_path: Path) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text('name = "t"\nmechanism = "rtclm_primary"\nseed = 1\n[rtclm]\nh6 = 50.0\nh4 = 255.0\n'
                   '[algorithm]\nname = "nsga2"\npop_size = 12\n'
                   '[[stages]]\nname = "rtclm1"\nbox = "global"\nn_gen = 2\npick = "best:dh6"\n'
                   '[[stages]]\nname = "rtclm2"\nbox = "global"\nn_gen = 2\npick = "best:dh4"\n')
    run = clm("design", str(cfg), "--out", str(tmp_path / "run"))
    assert run.returncode == 0, run.stderr
    out = clm("evaluate", "--design", str(tmp_path / "run"), "--mode", "auxiliary")
    assert out.returncode == 0, out.stderr
    h_m = next(ln for ln in out.stdout.splitlines() if "h_m = h4" in ln)
    assert "target 255 mm (the run's)" in h_m and "220 / 240" not in h_m


def test_the_other_mode_row_says_no_stance_shift_when_this_mode_does_not_assemble() -> None:
    # Review of session 30: it read "stance level the same" and "lies nan mm above" when this mode (the one on
    # screen) does not assemble, so its stance level is NaN.
    from core.analysis.clearance import ground_clearance
    from studio.metrics import evaluate_solution, other_mode_row

    aux = Design(RTCLM_AUXILIARY, get("rtclm/case4").design().params)
    sol = aux.solve(360)
    ev = evaluate_solution(sol, TargetSpec().target(), 2.0)
    r = other_mode_row("Auxiliary mode", sol, ev, ground_clearance(sol, aux.mechanism, aux.output), float("nan"))
    assert "stance not comparable" in str(r.value) and "nan" not in r.note.lower()
    shifted = other_mode_row("Auxiliary mode", sol, ev, ground_clearance(sol, aux.mechanism, aux.output), 12.0)
    assert "stance 12 mm lower" in str(shifted.value) and "the trunk rises by that much" in shifted.note
