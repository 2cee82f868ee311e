"""Stages, the Pareto chart, picks, sessions and exports in a real (headless) browser.

Runs use tiny populations and few generations typed into the Stages panel. viser runs GUI
callbacks in a thread pool, so a test waits until the server holds a typed setting before it
clicks Run (as a person would see the field settle before clicking).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import expect

from benchmarks.studio import choose, download, field
from core.formats.design import design_from_dict
from studio.candidates import candidates
from studio.chains import chain_for, find
from studio.exports import parse_trajectories_csv

SUBTASK2 = "Subtask 2 → X2 (h_s, I)"
SUBTASK3 = "Subtask 3 → X3 (fine-tuning)"
# The tests run subtasks 2 and 3 from the opening X3 design: two objectives (h_s, I), so the
# chart is 2-D SVG (cheap for software rendering, and its points are countable). The 3-D chart
# of subtask 1's three objectives is covered by tests/test_studio_pareto_and_picks.py.


def wait_for(predicate: Any, what: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def expand(page: Any, folder: str) -> None:
    """Open a GUI folder unless it is open already (clicking its title toggles it; the page is shared between
    tests, so an earlier one may have opened it). A folder's second child is its content, 0 px tall when shut."""
    title = page.get_by_text(folder, exact=True)
    title.scroll_into_view_if_needed()
    if not title.evaluate("e => e.parentElement.children[1].getBoundingClientRect().height > 0"):
        title.click()


def settle(page: Any, studio: Any, stage: str, pop: int, gens: int) -> None:
    """Type a population and a number of generations and wait until the server has them.

    First wait until the panel shows the chosen stage's own settings, so the server's mirror of
    them cannot overwrite what is typed next. Then one field at a time, each until the server has it:
    viser's page sends the whole panel's input through one sender that passes a message at most every
    50 ms and keeps only the newest one waiting, so a field typed within 50 ms of another message and
    followed by a second field within the same 50 ms is never sent (the Population lost while the
    Generations arrived, in about one CI run in three). A person never types that fast; a test does.
    """
    wait_for(lambda: studio.session.study.next_stage == stage, f"{stage} to be chosen")
    default = studio.session.study.settings_for(find(chain_for(studio.session.view.design.mechanism), stage))
    expect(field(page, "Population")).to_have_value(str(default.pop_size))
    expect(field(page, "Generations")).to_have_value(str(default.n_gen))
    field(page, "Population").fill(str(pop))
    reached(page, studio, stage, lambda s: s.pop_size == pop)
    field(page, "Generations").fill(str(gens))
    reached(page, studio, stage, lambda s: (s.pop_size, s.n_gen) == (pop, gens))


def reached(page: Any, studio: Any, stage: str, holds: Any) -> None:
    """Wait until the server's settings of ``stage`` (still the chosen one) satisfy ``holds``."""

    def ready() -> bool:
        st = studio.session.study
        s = st.settings.get(stage)
        return st.next_stage == stage and s is not None and bool(holds(s))

    deadline = time.monotonic() + 30.0
    while not ready():
        if time.monotonic() > deadline:  # what the page showed tells a lost edit from a slow page (seen once)
            shown = {name: field(page, name).input_value() for name in ("Population", "Generations")}
            notes = page.locator(".mantine-Notification-root").all_inner_texts()
            raise AssertionError(f"{stage} settings did not reach the server in 30 s: the page shows {shown}, "
                                 f"notifications {notes}, the server holds {studio.session.study.settings.get(stage)}")
        time.sleep(0.05)


def run_stage(page: Any, studio: Any, title: str, stage: str, pop: int = 8, gens: int = 3,
              double: bool = False) -> Any:
    """Choose a stage, type tiny settings, press Run (or double-click it) and wait for the result."""
    choose(page, "Stage", title)
    settle(page, studio, stage, pop, gens)
    run = page.get_by_role("button", name="Run", exact=True)
    if double:
        run.dblclick()
    else:
        run.click()
    expect(page.get_by_text(f"Last run: {stage} complete")).to_be_visible(timeout=60_000)
    return studio.session.study.result(stage)


def pareto_plot(page: Any, title: str) -> Any:
    """The Pareto chart whose title contains ``title`` (``subtask2 · complete``)."""
    return page.locator(".js-plotly-plot", has=page.locator(".gtitle", has_text=title))


def pareto_points(page: Any, title: str) -> Any:
    """The drawn members of a 2-D Pareto chart (3-D charts draw in WebGL)."""
    return pareto_plot(page, title).locator(".scatterlayer .point")


def param_values(page: Any) -> dict[str, str]:
    return page.evaluate("""() => {
      const got = {};
      for (const l of document.querySelectorAll('label[for]')) {
        // A text input is not the label's target: take the input in the label's row.
        const el = l.closest('.mantine-Flex-root')?.querySelector('input:not([type="hidden"])');
        if (el && l.textContent.endsWith('[mm]')) got[l.textContent] = el.value;
      }
      return got;
    }""")


def expect_params(page: Any, design: Any) -> None:
    """Wait until the page's mm inputs show the design (the inputs round to their 0.01 mm step)."""
    want = {f"{p.name} [{p.unit}]": float(v) for p, v in zip(design.mechanism.params, design.params[0], strict=True)
            if p.unit == "mm"}

    def shows() -> bool:
        got = param_values(page)
        try:
            return all(abs(float(got[k]) - v) <= 0.0051 for k, v in want.items())
        except (KeyError, ValueError):
            return False

    wait_for(shows, "the page to show the design")


def pass_on(page: Any, studio: Any, stage: str) -> None:
    """Press "Use for next stage"; a shown member that misses the next stage's constraints, which another member
    of its stage meets, is passed on through the prompt that asks first (it names them)."""
    nxt, missed, avoidable = studio.next_unmet(stage)
    page.get_by_role("button", name="Use for next stage", exact=True).click()
    if missed and avoidable:
        dialog = page.get_by_role("dialog")
        expect(dialog).to_contain_text(f"misses {nxt}'s constraints")
        expect(dialog).to_contain_text(missed[0])
        dialog.get_by_role("button", name="Pass it on").click()


def load_session(page: Any, studio: Any, path: Path) -> None:
    """Upload a session file; over a session that holds work the page asks first, and it is loaded."""
    asks = studio.session.holds_work()
    upload = page.locator('input[type="file"][accept="application/json"]')
    upload.evaluate("e => { e.value = ''; }")  # as viser's button does before it opens the file dialog
    upload.set_input_files(str(path))
    if asks:
        dialog = page.get_by_role("dialog")
        expect(dialog).to_contain_text("It replaces the current session")
        dialog.get_by_role("button", name="Load it").click()


def notification(page: Any, title: str, reason: str) -> Any:
    return page.locator(".mantine-Notification-root").filter(has_text=title).filter(has_text=reason).first


def test_a_short_subtask_runs_once_on_a_double_click_and_the_pareto_chart_fills(page: Any, studio: Any,
                                                                                 blocked: list[str]) -> None:
    # Subtask 2 (h_s, I) from the editor's X3: a 2-D chart whose points are SVG elements.
    r = run_stage(page, studio, SUBTASK2, "subtask2", pop=12, gens=3, double=True)
    assert r.status == "complete" and r.pop == 12 and r.generation == 3
    assert studio.session.study.branches == []  # a second run would have kept the first as a branch
    points = pareto_points(page, "subtask2 · complete")
    expect(points.first).to_be_attached()
    n_drawn = int(np.isfinite(r.F).all(axis=1).sum())
    wait_for(lambda: points.count() >= n_drawn, "every member in the chart")
    plot = pareto_plot(page, "subtask2 · complete")
    expect(plot.locator(".legendtext", has_text="knees")).to_be_attached()
    expect(plot.locator(".xtitle")).to_have_text("f4 = h_s (mm)")
    expect(plot.locator(".ytitle")).to_have_text("f5 = I (mm/s)")
    # The run's pick (its first knee) is animated in the editor.
    np.testing.assert_array_equal(studio.session.view.design.params[0], r.X[r.picked])
    expect_params(page, studio.session.view.design)
    assert blocked == []


def test_controls_are_disabled_while_a_stage_runs_and_stop_keeps_the_partial_result(page: Any, studio: Any) -> None:
    choose(page, "Stage", SUBTASK2)
    settle(page, studio, "subtask2", pop=8, gens=5000)
    page.get_by_role("button", name="Run", exact=True).click()
    expect(page.get_by_role("button", name="Run", exact=True)).to_be_disabled()
    expect(field(page, "Population")).to_be_disabled()
    # The design too: the run's pick replaces it when it ends (a parameter typed meanwhile was silently lost).
    expect(field(page, "r4 [mm]")).to_be_disabled()
    expect(page.get_by_label("Topology", exact=True)).to_be_disabled()
    expect(page.get_by_label("Preset", exact=True)).to_be_disabled()
    stop = page.get_by_role("button", name="Stop", exact=True)
    expect(stop).to_be_enabled()
    stop.click()
    wait_for(lambda: not studio.runner.busy, "the run to stop")
    expect(page.get_by_text("Last run: subtask2 stopped at generation")).to_be_visible()
    r = studio.session.study.result("subtask2")
    assert r.status == "cancelled" and 0 < r.generation < 5000
    expect(page.get_by_role("button", name="Run", exact=True)).to_be_enabled()
    expect(field(page, "r4 [mm]")).to_be_enabled()
    expect(page.get_by_label("Topology", exact=True)).to_be_enabled()


def test_picking_a_candidate_animates_it_and_use_for_next_stage_starts_there(page: Any, studio: Any) -> None:
    r2 = run_stage(page, studio, SUBTASK2, "subtask2", pop=16, gens=15)
    canvas = page.locator("canvas").first
    before = canvas.screenshot()
    other = next(c for c in candidates(r2) if c.member != r2.picked)
    choose(page, "Candidate", other.label)
    wait_for(lambda: np.array_equal(studio.session.view.design.params[0], r2.X[other.member]),
             "the pick to reach the server")
    assert studio.session.study.shown_member("subtask2") == other.member
    expect_params(page, studio.session.view.design)
    wait_for(lambda: canvas.screenshot() != before, "the scene to show the picked candidate")
    assert studio.session.study.result("subtask2").picked == r2.picked  # shown, not yet passed on

    pass_on(page, studio, "subtask2")
    expect(page.get_by_label("Stage", exact=True)).to_have_value(SUBTASK3)
    expect(page.get_by_label("Start from", exact=True)).to_have_value("the previous stage's pick")
    assert studio.session.study.result("subtask2").picked == other.member
    expand(page, "Search box")
    centre = page.locator('table.clm-box tr[data-param="r4"]')
    expect(centre).to_have_attribute("data-center", repr(float(r2.X[other.member][7])))

    settle(page, studio, "subtask3", pop=8, gens=2)
    page.get_by_role("button", name="Run", exact=True).click()
    expect(page.get_by_text("Last run: subtask3 complete")).to_be_visible(timeout=60_000)
    r3 = studio.session.study.result("subtask3")
    assert r3.parent_pick == other.member
    assert float(r3.box.center[7]) == float(r2.X[other.member][7])
    expect(page.locator('table.clm-history tr[data-stage="subtask3"]')).to_have_attribute("data-status", "complete")


def test_a_session_downloads_and_loads_back(page: Any, studio: Any, tmp_path: Path) -> None:
    run_stage(page, studio, SUBTASK2, "subtask2", pop=8, gens=2)
    saved = studio.session.to_dict()
    expand(page, "Session and export")
    path = tmp_path / "session.json"
    download(page, "Download session").save_as(path)
    assert json.loads(path.read_text()) == saved
    # Change the state, then load the file back.
    field(page, "r4 [mm]").fill("129")
    wait_for(lambda: studio.session.view.values["r4"] == 129.0, "the edit to reach the server")
    with studio.session.lock:
        studio.session.study.keep_branch("test")
    # It replaced six branches and a run without a word: now it asks, says what would go, and offers a download.
    changed = studio.session.to_dict()
    page.locator('input[type="file"][accept="application/json"]').set_input_files(str(path))
    dialog = page.get_by_role("dialog")
    expect(dialog).to_contain_text("It replaces the current session: Stephenson-I six-bar, 1 stage result, 1 branch")
    expect(dialog).to_contain_text("download the current session first")  # this studio keeps no session file
    with page.expect_download() as got:
        dialog.get_by_role("button", name="Download the current session").click()
    assert json.loads(Path(got.value.path()).read_text()) == changed
    dialog.get_by_role("button", name="Cancel").click()
    expect(dialog).to_have_count(0)
    assert studio.session.to_dict() == changed  # Cancel loads nothing
    load_session(page, studio, path)
    wait_for(lambda: studio.session.to_dict() == saved, "the session to load back")
    expect_params(page, studio.session.view.design)
    expect(page.locator('table.clm-history tr[data-stage="subtask2"]')).to_have_attribute("data-status", "complete")


def test_malformed_uploads_are_refused_naming_the_problem_and_nothing_changes(page: Any, studio: Any,
                                                                              tmp_path: Path) -> None:
    run_stage(page, studio, SUBTASK2, "subtask2", pop=8, gens=2)
    before = studio.session.to_dict()
    expand(page, "Session and export")
    bad = tmp_path / "broken.json"
    broken = json.loads(json.dumps(before))
    broken["design"]["mechanism"] = "nope"
    bad.write_text(json.dumps(broken))
    page.locator('input[type="file"][accept="application/json"]').set_input_files(str(bad))
    expect(notification(page, "Session not loaded", "broken.json")).to_be_visible()
    expect(notification(page, "Session not loaded", "'nope'")).to_be_visible()
    assert studio.session.to_dict() == before
    expand(page, "Target")
    curve = tmp_path / "curve.csv"
    curve.write_text("x,y\n0,0\n1,two\n2,0\n0,1\n")
    page.locator('input[type="file"][accept=".csv,text/csv"]').set_input_files(str(curve))
    expect(notification(page, "Target curve not loaded", "'two' is not a number")).to_be_visible()
    assert studio.session.to_dict() == before


def test_a_new_page_gets_the_run_chart_and_pick_and_two_pages_stay_consistent(page: Any, open_page: Any,
                                                                              studio: Any) -> None:
    r = run_stage(page, studio, SUBTASK2, "subtask2", pop=16, gens=15)
    # A new client (a second tab, or a reload) arrives with the whole current state.
    b = open_page()
    expect(b.get_by_text("Last run: subtask2 complete")).to_be_visible()
    expect(pareto_points(b, "subtask2 · complete").first).to_be_attached()
    expect(b.get_by_label("Candidate", exact=True)).to_have_value(
        next(c.label for c in candidates(r) if c.member == r.picked))
    # A pick on one page shows on the other.
    other = next(c for c in candidates(r) if c.member != r.picked)
    choose(b, "Candidate", other.label)
    wait_for(lambda: np.array_equal(studio.session.view.design.params[0], r.X[other.member]),
             "the pick from the second page")
    expect(page.get_by_label("Candidate", exact=True)).to_have_value(other.label)
    expect_params(page, studio.session.view.design)
    expect_params(b, studio.session.view.design)


def test_exports_are_files_a_collaborator_can_open_offline(page: Any, studio: Any, browser: Any, tmp_path: Path,
                                                           blocked: list[str]) -> None:
    run_stage(page, studio, SUBTASK2, "subtask2", pop=8, gens=2)
    expand(page, "Session and export")

    def fetch(button: str) -> bytes:
        got = download(page, button)
        p = tmp_path / got.suggested_filename
        got.save_as(p)
        return p.read_bytes()

    design = design_from_dict(json.loads(fetch("Design (JSON)")))
    np.testing.assert_array_equal(design.params, studio.session.view.design.params)
    cols = parse_trajectories_csv(fetch("Trajectories (CSV)"))
    np.testing.assert_array_equal(cols["y_leg_mm"], studio.session.view.solution.leg[0, :, 1])
    assert b"subtask2" in fetch("Pareto chart (HTML)")
    # The chart's camera button saves a PNG, drawn by plotly.js in the browser.
    camera = pareto_plot(page, "subtask2 · complete").locator('.modebar-btn[data-title^="Download plot as a"]')
    camera.scroll_into_view_if_needed()
    with page.expect_download() as dl:
        camera.click()
    assert dl.value.suggested_filename == "pareto.png"
    assert Path(dl.value.path()).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The animated scene opens on its own, with every outside request blocked; viser's software-rendering notice
    # closes after the studio's delay, as on the studio's pages (it stayed, over the recording's top-left).
    studio.notice_seconds = 2.0
    try:
        scene = fetch("Animated scene (HTML)").decode()
    finally:
        studio.notice_seconds = 10.0
    ctx = browser.new_context(viewport={"width": 800, "height": 600})
    try:
        ctx.route("**/*", lambda r: (blocked.append(r.request.url), r.abort()) if not r.request.url.startswith(
            ("data:", "blob:", "about:")) else r.continue_())
        viewer = ctx.new_page()
        viewer.set_content(scene)
        viewer.wait_for_selector("canvas", state="visible")
        notice = viewer.locator(".mantine-Notification-root").filter(has_text="Software WebGL rendering detected")
        expect(notice).to_be_visible()
        expect(notice).to_have_count(0, timeout=15_000)
    finally:
        ctx.close()
    assert blocked == []
