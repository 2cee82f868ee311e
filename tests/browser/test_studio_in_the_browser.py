"""The studio in a real (headless) browser: load, animate, edit, refuse, stay consistent across tabs."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import choose, field

from core.kinematics import presets
from studio.panels._inputs import format_number
from tests.ctrl_c import sigint_as_in_a_terminal

ROOT = Path(__file__).resolve().parents[2]
X3 = presets.get("stephenson1/X3")

# Everything a page shows of the design, in one round trip: input values by label text, and
# metric values by row key. (One evaluation instead of dozens of locator queries matters when
# the browser renders WebGL in software.)
SHOWN_JS = """() => {
  const got = {};
  for (const l of document.querySelectorAll('label[for]')) {  // the input in each label's row
    const el = l.closest('.mantine-Flex-root')?.querySelector('input:not([type="hidden"])');
    if (el) got[l.textContent] = el.value;
  }
  for (const td of document.querySelectorAll('table.clm-metrics tr[data-key] td[data-value]'))
    got['metric ' + td.parentElement.dataset.key] = td.dataset.value;
  return got;
}"""
MATCHES_JS = f"(exp) => {{ const got = ({SHOWN_JS})(); return Object.entries(exp).every(([k, v]) => got[k] === v); }}"


def shown(page: Any) -> dict[str, str]:
    return page.evaluate(SHOWN_JS)


def expected_of(view: Any) -> dict[str, str]:
    """What a page must show for a session view: every parameter input and every metric."""
    exp = {f"{p.name} [{p.unit}]": format_number(view.values[p.name]) for p in view.design.mechanism.params}
    exp.update({f"metric {r.key}": r.text() for r in view.rows})
    return exp


def expect_design_of(page: Any, view: Any, timeout: float = 20_000) -> None:
    """Wait until the page shows the view's design and metrics; on timeout, fail with the difference."""
    exp = expected_of(view)
    try:
        page.wait_for_function(MATCHES_JS, arg=exp, timeout=timeout, polling=100)
    except PlaywrightError:
        got = shown(page)
        diff = {k: (got.get(k), v) for k, v in exp.items() if got.get(k) != v}
        raise AssertionError(f"page differs from the session (shown, expected): {diff}") from None


def param_input(page: Any, name: str, unit: str = "mm") -> Any:
    """The entry field of a design parameter, found by its label (``r4 [mm]``)."""
    return field(page, f"{name} [{unit}]")


def angle_readout(page: Any) -> str:
    """The Playback panel's live angle ("θ = 78° (playing)")."""
    return page.get_by_text(re.compile(r"^θ = \d+° \((playing|paused)\)$")).first.inner_text()


def wait_until_changes(read: Any, what: str, timeout: float = 15.0) -> None:
    first = read()
    deadline = time.monotonic() + timeout
    while read() == first:
        assert time.monotonic() < deadline, f"{what} did not change within {timeout:g} s"
        time.sleep(0.2)


def notification(page: Any, title: str, reason: str) -> Any:
    return page.locator(".mantine-Notification-root").filter(has_text=title).filter(has_text=reason).first


def test_page_loads_offline_and_plays_the_x3_design(page: Any, studio: Any, blocked: list[str]) -> None:
    view = studio.session.view
    assert view.preset == "stephenson1/X3"
    expect_design_of(page, view)
    page.get_by_role("button", name="Play", exact=True).click()
    expect(page.get_by_role("button", name="Pause", exact=True)).to_be_visible()
    assert studio.session.playback.playing
    # The GUI follows the animation (the angle readout runs; the slider stays still under the user's hand) ...
    wait_until_changes(lambda: angle_readout(page), "the angle readout")
    # ... and the canvas renders the moving mechanism: two captures a moment apart differ.
    canvas = page.locator("canvas").first
    wait_until_changes(lambda: canvas.screenshot(), "the scene")
    assert blocked == []


def test_editing_a_parameter_re_solves_and_updates_the_metrics(page: Any, studio: Any) -> None:
    before = studio.session.view
    expect_design_of(page, before)
    param_input(page, "r4").fill("130")
    old_mse = next(r for r in before.rows if r.key == "mse").text()
    expect(page.locator('tr[data-key="mse"] td[data-value]')).not_to_have_attribute("data-value", old_mse)
    after = studio.session.view
    assert after.values["r4"] == 130.0 and after.edited == ("r4",)
    expect_design_of(page, after)
    expect(page.get_by_text("Edited: r4")).to_be_visible()


def test_an_invalid_entry_is_refused_with_a_notification_and_the_design_kept(page: Any, studio: Any) -> None:
    before = studio.session.view
    expect_design_of(page, before)
    r4 = param_input(page, "r4")
    for typed, reason in (("-5", "must be > 0"), ("500", "does not assemble")):
        r4.fill(typed)
        expect(notification(page, "r4 [mm] not applied", reason)).to_be_visible()
        expect(r4).to_have_value(format_number(X3.values[7]))
        assert studio.session.view is before
    expect_design_of(page, before)


def test_two_pages_stay_consistent_and_a_reload_gets_the_current_state(
    page: Any, open_page: Any, studio: Any, ready: Any
) -> None:
    a, b = page, open_page()
    expect_design_of(a, studio.session.view)
    param_input(a, "r1").fill("57")
    expect(param_input(b, "r1")).to_have_value("57")
    view = studio.session.view
    assert view.values["r1"] == 57.0
    expect_design_of(a, view)
    expect_design_of(b, view)
    b.reload()
    ready(b)
    expect_design_of(b, view)


def test_the_viewers_software_rendering_notice_goes_after_a_while(open_page: Any, studio: Any) -> None:
    # viser's "Software WebGL rendering detected" never closed by itself and covered the scene's top-left (the
    # design's name, the joint labels) on every machine without a GPU, as this headless chromium is
    studio.notice_seconds = 2.0
    try:
        b = open_page()
        notice = b.locator(".mantine-Notification-root").filter(has_text="Software WebGL rendering detected")
        expect(notice).to_be_visible()
        expect(notice).to_have_count(0, timeout=15_000)
    finally:
        studio.notice_seconds = 10.0


def test_choosing_another_preset_loads_it(page: Any, studio: Any) -> None:
    expect_design_of(page, studio.session.view)
    choose(page, "Preset", "X0")
    expect(param_input(page, "r4")).to_have_value(format_number(presets.get("stephenson1/X0").values[7]))
    view = studio.session.view
    assert view.preset == "stephenson1/X0"
    expect_design_of(page, view)


def test_clm_studio_serves_on_loopback_opens_animating_and_stops_on_ctrl_c(browser: Any, ready: Any) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "studio", "--port", "0"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=sigint_as_in_a_terminal)
    try:
        assert proc.stdout is not None
        line = ""
        deadline = time.monotonic() + 60
        while "CLM Studio:" not in line:
            assert time.monotonic() < deadline and proc.poll() is None, "no URL printed"
            line = proc.stdout.readline()
        url = re.search(r"http://localhost:(\d+)", line)
        assert url, line
        ctx = browser.new_context(viewport={"width": 900, "height": 700})
        ctx.set_default_timeout(30_000)
        page = ctx.new_page()
        page.goto(f"http://127.0.0.1:{url.group(1)}/")
        ready(page)
        expect(page.get_by_role("button", name="Pause", exact=True)).to_be_visible()
        wait_until_changes(lambda: angle_readout(page), "the angle readout")
        ctx.close()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
        assert "CLM Studio stopped." in proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_undo_and_redo_take_back_an_edit_and_a_topology_switch(page: Any, studio: Any) -> None:
    x3 = studio.session.view
    undo = page.get_by_role("button", name=re.compile(r"^Undo"))
    redo = page.get_by_role("button", name=re.compile(r"^Redo"))
    undo.scroll_into_view_if_needed()
    expect(undo).to_be_disabled()
    expect(redo).to_be_disabled()
    param_input(page, "r4").fill("130")
    expect(undo).to_be_enabled()
    expect(undo).to_have_text("Undo r4")  # what it takes back, on the button: viser shows no button hint
    choose(page, "Topology", "Theo Jansen leg")
    expect(param_input(page, "a")).to_be_visible()
    undo.click()  # back to the Stephenson-I with r4 = 130
    expect(param_input(page, "r4")).to_have_value("130")
    expect(page.get_by_label("Topology", exact=True)).to_have_value("Stephenson-I six-bar")
    undo.click()  # back to X3 as it opened
    expect(param_input(page, "r4")).to_have_value(format_number(x3.values["r4"]))
    expect(undo).to_be_disabled()
    expect_design_of(page, studio.session.view)
    assert studio.session.view is x3
    redo.click()
    expect(param_input(page, "r4")).to_have_value("130")
    expect(page.get_by_text("Edited: r4")).to_be_visible()
    expect(redo).to_be_enabled()  # the topology switch can still be made again
    param_input(page, "r4").fill("131")  # a new edit: what was undone is gone
    expect(redo).to_be_disabled()
