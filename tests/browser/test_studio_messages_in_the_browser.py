"""What the studio tells the designer, in the browser (issue 13, items 11 and 12).

Item 11: every invalid entry is refused with a notification and the field goes back to the last valid value
("abc" or an emptied field in a link length and in Generations; "1e9" in Population is not silently 19): the
studio's number fields are text inputs the server parses (``studio.panels._inputs``). Item 12: a malformed CSV
gets an error naming the file and the problem, and the target is kept; the Pareto chart rings a member "passed
on" only once it is; a loaded session shows its stage and start in the Stages panel; the Pick comparison colours
better and worse values; the candidate list names each design once and the front slider spans the front; the
exported Pareto chart names the mechanism, stage and target.

(The typed crank angle is tested in test_studio_inputs_in_the_browser.py; negative and non-assembling lengths in
test_studio_in_the_browser.py.)
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import (
    SUBTASK2,
    SUBTASK3,
    choose,
    download,
    expand,
    field,
    load_session,
    notification,
    pass_on,
    run_stage,
    wait_for,
)
from test_studio_views_in_the_browser import close_notices, open_target_panel

from studio.candidates import candidates, front_order
from studio.chains import MAX_POP
from studio.panels._inputs import format_number

PLOT_NAMES_JS = """(title) => {
  for (const p of document.querySelectorAll('.js-plotly-plot')) {
    const t = p.querySelector('.gtitle');
    if (t && t.textContent.includes(title) && p._fullData) return p._fullData.map(d => d.name);
  }
  return null;
}"""


# A table's [left, right] and its folder's (the nearest ancestor with a border), in page pixels.
FOLDER_BOX_JS = """t => { let e = t.parentElement;
  while (e && parseFloat(getComputedStyle(e).borderLeftWidth) === 0) e = e.parentElement;
  const a = t.getBoundingClientRect(), b = e.getBoundingClientRect();
  return [[a.left, a.right], [b.left, b.right]]; }"""


def shown_setting(studio: Any, stage: str, key: str) -> int:
    return int(getattr(studio.session.study.settings_for(
        next(s for s in studio.chain() if s.name == stage)), key))


def refused(page: Any, box: Any, typed: str, title: str, said: str, kept: str) -> None:
    """Type an entry, leave the field: a notification says it was not applied and why, the field shows ``kept``."""
    box.fill(typed)
    box.press("Tab")
    # Refusals come after the field kept the entry for 0.8 s; they name the entry, what the field takes and
    # the value kept.
    expect(notification(page, title, said)).to_be_visible(timeout=3_000)
    expect(notification(page, title, said)).to_contain_text(f"Kept {kept}.")
    expect(box).to_have_value(kept, timeout=2_000)
    close_notices(page)


@pytest.mark.parametrize(("typed", "said"), [("abc", "'abc' is not a number"), ("", "The field is empty")])
def test_a_link_length_that_is_not_a_number_is_refused_and_the_field_shows_the_last_value(
        page: Any, studio: Any, typed: str, said: str) -> None:
    box = field(page, "r4 [mm]")
    before = studio.session.view
    kept = format_number(before.values["r4"])
    expect(box).to_have_value(kept)
    refused(page, box, typed, "r4 [mm] not applied", said, kept)
    expect(notification(page, "r4 [mm] not applied", said)).to_have_count(0)
    assert studio.session.view is before


def test_generations_that_are_not_a_number_are_refused_and_the_field_shows_the_last_value(
        page: Any, studio: Any) -> None:
    box = field(page, "Generations")
    stage = studio.session.study.next_stage or studio.chain()[0].name
    kept = str(shown_setting(studio, stage, "n_gen"))
    expect(box).to_have_value(kept)
    for typed, said in (("abc", "'abc' is not a number"), ("", "The field is empty"), ("2.5", "not a whole number"),
                        ("nan", "'nan' is not a number"), ("1,5", "use a point for decimals")):
        refused(page, box, typed, "Generations not applied", said, kept)
        assert str(shown_setting(studio, stage, "n_gen")) == kept


def test_a_population_of_1e9_is_refused_not_silently_read_as_19(page: Any, studio: Any) -> None:
    box = field(page, "Population")
    stage = studio.session.study.next_stage or studio.chain()[0].name
    kept = str(shown_setting(studio, stage, "pop_size"))
    expect(box).to_have_value(kept)
    refused(page, box, "1e9", "Population not applied", f"'1e9' is above {MAX_POP}", kept)
    assert str(shown_setting(studio, stage, "pop_size")) == kept
    # Typed key by key, a valid entry is applied as it is typed (no notification), and "1e2" is 100.
    box.fill("")
    box.press_sequentially("1e2", delay=100)
    wait_for(lambda: shown_setting(studio, stage, "pop_size") == 100, "the population typed key by key")
    expect(box).to_have_value("1e2")
    box.press("Tab")
    page.wait_for_timeout(1_500)  # longer than a refusal takes: "1" and "1e" passed through on the way
    expect(page.locator(".mantine-Notification-root").filter(has_text="Population not applied")).to_have_count(0)


def test_a_value_set_by_the_server_shows_in_the_field_without_an_edit(page: Any, studio: Any) -> None:
    box = field(page, "r4 [mm]")
    studio.session.set_param("r4", 129.25)
    studio.refresh()
    expect(box).to_have_value("129.25")
    studio.session.set_param("r4", 129.609144)  # a run's pick: shown to 0.01 mm, as a preset's values are
    studio.refresh()
    expect(box).to_have_value("129.61")
    studio.session.set_param("r4", 130.0)
    studio.refresh()
    expect(box).to_have_value("130")  # whole values without ".0"
    page.wait_for_timeout(1_000)
    expect(page.locator(".mantine-Notification-root").filter(has_text="not applied")).to_have_count(0)


def test_a_malformed_csv_is_refused_naming_the_file_and_the_target_is_unchanged(
        page: Any, studio: Any, tmp_path: Path) -> None:
    """The studio's notification says the file arrived but is not a curve, and the target stays as it was.

    viser's upload button shows its own "File uploaded successfully." in the page once the transfer is
    complete, whatever the server then does with the file, and the server cannot suppress it (it is the
    client's notification, not the studio's). So the studio's refusal agrees with it: the file was uploaded,
    and it is not a target curve.
    """
    open_target_panel(page)
    before = studio.session.view.target
    status = page.get_by_text(f"Target: {before.label()}")
    expect(status).to_be_visible()
    curve = tmp_path / "bad.csv"
    curve.write_text("x,y\n0,0\n1,two\n2,0\n")
    page.locator('input[type="file"][accept=".csv,text/csv"]').set_input_files(str(curve))
    said = notification(page, "Target curve not loaded", "bad.csv was uploaded but is not a target curve")
    expect(said).to_be_visible()
    expect(said).to_contain_text("'two' is not a number")
    expect(said).to_contain_text(f"The target is unchanged: {before.label()}.")
    assert studio.session.view.target == before
    expect(status).to_be_visible()  # the Target panel still shows the previous target
    close_notices(page)


def test_a_foot_path_uploaded_in_the_leg_frame_becomes_the_design_frame_target(
        page: Any, studio: Any, tmp_path: Path) -> None:
    """A designer's foot path (stance below, swing above, as the bench view draws it) is not the paper's
    design-frame curve: chosen as a leg-frame file, it is mapped by the design's output stage, and the page
    says so. Back to the cycloid and the design frame afterwards (the page is shared between tests)."""
    open_target_panel(page)
    out = studio.session.view.design.output
    t = np.arange(40) / 40
    foot = np.stack([150 + 150 * np.cos(2 * np.pi * t), np.maximum(0.0, 80 * np.sin(2 * np.pi * t))], -1)
    path = tmp_path / "foot.csv"
    path.write_text("x,y\n" + "".join(f"{x:.6f},{y:.6f}\n" for x, y in foot))
    choose(page, "CSV frame", "leg frame (bench view)")
    wait_for(lambda: studio.target.frame.value == "leg frame (bench view)", "the frame to reach the server")
    page.locator('input[type="file"][accept=".csv,text/csv"]').set_input_files(str(path))
    said = notification(page, "Target curve read in the leg frame", "foot.csv: mapped to the design frame")
    expect(said).to_be_visible()
    expect(said).to_contain_text("k = -1 about (150, 0) mm")
    wait_for(lambda: studio.session.view.target.is_curve, "the curve to become the target")
    curve = studio.session.view.target.curve
    np.testing.assert_allclose(out.apply(np.array(curve.points)), foot, atol=1e-5)
    assert max(y for _, y in curve.points) <= 1e-9  # in the design frame the swing hangs below, as the cycloid's
    expect(page.get_by_text(re.compile(r"Target: curve foot\.csv .*in the design frame"))).to_be_visible()
    expect(field(page, "L [mm]")).to_be_hidden()  # the cycloid's size beside a curve read as the curve's
    page.get_by_role("button", name="Back to the compound cycloid").click()
    wait_for(lambda: not studio.session.view.target.is_curve, "the cycloid back")
    expect(field(page, "L [mm]")).to_be_visible()
    choose(page, "CSV frame", "design frame (mechanism view)")
    close_notices(page)


def test_after_a_run_the_pick_panel_chart_export_and_a_loaded_session_tell_the_truth(
        page: Any, studio: Any, tmp_path: Path) -> None:
    # Before any run there is no front to slide over: no slider (it used to span 1-2, disabled).
    expect(page.locator("label", has_text="Along the front")).to_have_count(0)
    r = run_stage(page, studio, SUBTASK2, "subtask2", pop=12, gens=3)
    title = "subtask2 · complete"
    # No "passed on" ring before anything is passed on: not on the automatic pick when another one is looked at.
    wait_for(lambda: page.evaluate(PLOT_NAMES_JS, title) is not None, "the Pareto chart")
    first = r.picked
    other = next(c for c in candidates(r) if c.member != first)
    choose(page, "Candidate", other.label)
    wait_for(lambda: studio.session.study.shown_member("subtask2") == other.member, "the other candidate shown")
    expect(page.get_by_label("Candidate", exact=True)).to_have_value(other.label)
    assert "passed on" not in page.evaluate(PLOT_NAMES_JS, title)

    # The candidate list names each member, and each design, once.
    page.get_by_label("Candidate", exact=True).click()
    page.get_by_role("option").first.wait_for(state="visible")  # the list opens after the click returns
    options = page.get_by_role("option").all_text_contents()
    page.keyboard.press("Escape")
    members = [int(m.group(1)) for o in options if (m := re.search(r"· #(\d+) ·", o))]
    assert members and len(members) == len(set(members))
    designs = {r.X[i].tobytes() for i in members}
    assert len(designs) == len(members)
    # The front slider spans the front (and is not shown for a one-member front).
    n_front = len(front_order(r))
    slider = page.locator("label", has_text="Along the front")
    if n_front >= 2:
        root = slider.get_attribute("for")
        expect(page.locator(f'[id="{root}"] [role="slider"]')).to_have_attribute("aria-valuemax", str(n_front))
    else:
        expect(slider).to_have_count(0)

    # The comparison colours the candidate's values better (green) or worse (red) than the start's; nothing bold.
    cells = page.locator("table.clm-compare td[data-candidate]")
    expect(cells.first).to_be_attached()
    styles = cells.evaluate_all("cs => cs.map(c => [getComputedStyle(c).color, getComputedStyle(c).fontWeight])")
    assert any(c in ("rgb(21, 128, 61)", "rgb(185, 28, 28)") for c, _ in styles), styles
    assert all(int(w) < 600 for _, w in styles), styles
    # The comparison and the metrics tables keep a margin inside their folders' borders (their text touched them).
    for table in ("table.clm-compare", "table.clm-metrics"):
        t, f = page.locator(table).first.evaluate(FOLDER_BOX_JS)
        assert t[0] >= f[0] + 6 and t[1] <= f[1] - 6, (table, t, f)

    # The exported chart says what it shows: mechanism, stage and target.
    if not page.get_by_role("button", name="Pareto chart (HTML)", exact=True).is_visible():
        expand(page, "Session and export")
    html = Path(download(page, "Pareto chart (HTML)").path()).read_text()
    target = studio.session.view.target.option()
    assert "Stephenson-I six-bar" in html and "subtask2" in html
    assert f"target {target}" in html or f"target {target.split(':', 1)[-1]}" in html or "target cycloid" in html

    # Once passed on, the member keeps a "passed on" ring when another one is picked to look at.
    pass_on(page, studio, "subtask2")
    expect(page.get_by_label("Stage", exact=True)).to_have_value(SUBTASK3)
    choose(page, "Candidate", next(c.label for c in candidates(r) if c.member == first))
    wait_for(lambda: "passed on" in (page.evaluate(PLOT_NAMES_JS, title) or []), "the passed-on ring")

    # A saved session loads back into the same Stages panel: subtask 3, from the previous stage's pick.
    saved = tmp_path / "session.json"
    download(page, "Download session").save_as(saved)
    assert json.loads(saved.read_text())["study"]["next_stage"] == "subtask3"
    studio.session.load_preset("stephenson1/X0")  # elsewhere meanwhile: another stage and start in the panel
    with studio.session.lock:
        from studio.study import Study

        studio.session.study = Study()
    studio.refresh()
    expect(page.get_by_label("Stage", exact=True)).not_to_have_value(SUBTASK3)
    load_session(page, studio, saved)
    expect(page.get_by_label("Stage", exact=True)).to_have_value(SUBTASK3)
    expect(page.get_by_label("Start from", exact=True)).to_have_value("the previous stage's pick")
    assert np.array_equal(studio.session.study.result("subtask2").X, r.X)
