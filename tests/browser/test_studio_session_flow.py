"""A whole session as a designer does it, in the browser: the state never lies (issue 13, items 1, 2, 3, 5).

Run subtask 2 from X0 (no member meets its constraints), see it said in the status, the Stages, Pick and
Metrics panels, pass the infeasible pick on only after confirming, switch topology (a new pipeline; the old
one kept as a branch labelled by its values), restore that branch (its design comes back with it), delete a
branch after confirming, and reload the page: it shows the same state.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import SUBTASK3, choose, expand, field, settle, wait_for

from studio.panels.stages import FROM_PICK

SUBTASK2 = "Subtask 2 → X2 (h_s, I)"


def verdict(page: Any, panel_text: str) -> Any:
    return page.locator(".clm-verdict", has_text=panel_text)


def test_a_whole_session_keeps_its_state_straight(page, studio, ready):
    # Start from X0: subtask 2's small box around it cannot reach f1 = MSE <= 6 mm.
    choose(page, "Preset", "X0")
    wait_for(lambda: studio.session.view.preset == "stephenson1/X0", "X0 in the editor")
    choose(page, "Stage", SUBTASK2)
    expect(page.get_by_text(re.compile(r"Constraints of subtask2: assembles · f1 = MSE \(mm\) ≤ 6"))).to_be_visible()
    settle(page, studio, "subtask2", 8, 2)
    page.get_by_role("button", name="Run", exact=True).click()

    # Item 3: the status names the unmet constraints; Pick and Metrics judge against the stage's constraints.
    # By the problem's label for f1, as the Pick table names it (session 30).
    unmet = re.compile(r"Last run: subtask2 complete — no feasible member: .*f1 = MSE \(mm\) [\d.]+ > 6")
    expect(page.get_by_text(unmet)).to_be_visible(timeout=60_000)
    r = studio.session.study.result("subtask2")
    assert r is not None and not r.feasible.any()
    # The editor took the least violating member: said, and its Undo step named so (rehearsal 4).
    expect(page.get_by_text(re.compile(r"the editor shows its least violating member \(Undo: the design before\)")))\
        .to_be_visible()
    assert studio.session.change_names("undo").startswith("subtask2's least violating member")
    shown = studio.session.study.shown_member("subtask2")
    expect(page.locator('.clm-verdict[data-feasible="false"]').first).to_contain_text(
        f"#{shown} does not meet subtask2's constraints")
    assert page.locator('.clm-verdict[data-feasible="false"]').count() == 2  # Pick panel and Metrics panel

    # Passing it on asks first; Cancel passes nothing on.
    page.get_by_role("button", name="Use for next stage").click()
    dialog = page.get_by_role("dialog")
    expect(dialog).to_contain_text("does not meet subtask2's constraints")
    dialog.get_by_role("button", name="Cancel").click()
    expect(dialog).to_have_count(0)
    assert studio.session.study.result("subtask2").picked == r.picked and not studio.session.study.from_pick
    page.get_by_role("button", name="Use for next stage").click()
    page.get_by_role("dialog").get_by_role("button", name="Pass it on").click()
    wait_for(lambda: studio.session.study.from_pick and studio.session.study.next_stage == "subtask3",
             "the pick passed on to subtask 3")
    passed = studio.session.study.result("subtask2").picked
    design_passed, target_ran = studio.session.view.design, studio.session.view.target

    # Item 1: another topology starts a new pipeline; the old one becomes a branch labelled by its values.
    choose(page, "Topology", "Theo Jansen leg")
    wait_for(lambda: studio.session.view.design.mechanism.name == "jansen", "Jansen in the editor")
    expect(page.get_by_text("No stage has run yet.")).to_be_visible()
    # ... and the previous run's trace chart goes with its Pareto chart.
    expect(page.locator(".js-plotly-plot", has=page.locator(".gtitle", has_text="trace"))).not_to_be_visible()
    assert studio.session.study.pipeline is None
    # Item 8: Jansen brings a target of its own size, and the Target panel says so.
    assert "scaled to the jansen path" in studio.session.view.target.label()
    expect(page.get_by_text(re.compile(r"Target: curve cycloid \d+ x \d+ mm on jansen"))).to_be_attached()
    labels = [b.label for b in studio.session.study.branches]
    assert len(labels) == 1 and f"subtask2 #{passed}" in labels[0] and " · h_s " in labels[0]

    # Item 2: restoring the branch brings back its design, mechanism and pick.
    restore = page.get_by_role("button", name="Restore branch")
    if not restore.is_visible():
        expand(page, "History")
    restore.click()
    wait_for(lambda: studio.session.view.design.mechanism.name == "stephenson1", "the branch's mechanism")
    assert np.allclose(studio.session.view.design.params, design_passed.params)
    assert studio.session.study.result("subtask2").picked == passed
    expect(page.get_by_text(re.compile(r"Last run: subtask2|subtask2 · complete")).first).to_be_visible()
    # ... with its target, and the Stages panel as it was left: subtask 3, from the pick passed on.
    assert studio.session.view.target.option() == target_ran.option()
    expect(field(page, "Stage")).to_have_value(SUBTASK3)
    expect(field(page, "Start from")).to_have_value(FROM_PICK)

    # Item 5: a new start keeps the restored pipeline as a branch; deleting it asks first.
    assert not studio.session.study.branches  # the empty Jansen pipeline was not kept
    choose(page, "Stage", SUBTASK2)
    choose(page, "Start from", "the design in the editor")
    settle(page, studio, "subtask2", 8, 2)
    page.get_by_role("button", name="Run", exact=True).click()
    wait_for(lambda: len(studio.session.study.branches) == 1 and not studio.session.study.status.running,
             "the restored pipeline kept as a branch")
    delete = page.get_by_role("button", name="Delete branch")
    expect(delete).to_be_enabled()
    delete.click()
    page.get_by_role("dialog").get_by_role("button", name="Cancel").click()
    expect(page.get_by_role("dialog")).to_have_count(0)
    assert len(studio.session.study.branches) == 1
    delete.click()
    page.get_by_role("dialog").get_by_role("button", name="Delete branch").click()
    wait_for(lambda: not studio.session.study.branches, "the branch to go")
    expect(page.get_by_role("dialog")).to_have_count(0)
    expect(delete).to_be_disabled()

    # A reload shows the same state: the restored pipeline, its infeasible pick judged as such.
    page.reload()
    ready(page)
    expect(page.locator('.clm-verdict[data-feasible="false"]').first).to_be_visible()
    assert studio.session.view.design.mechanism.name == "stephenson1"
