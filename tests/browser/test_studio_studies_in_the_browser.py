"""The Studies panel in the browser (issue 12, item 6): find the studies under a folder, see a box plot, load a
run's picked design into the editor."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import choose, expand, wait_for

from core.formats.study import load_study
from core.study.runner import run_study
from studio.studies import finished_runs, picked_design, study_rows
from tests.study_files import tiny_study

TINY = tiny_study("nsga2")


def test_a_collaborator_finds_a_study_sees_its_boxes_and_loads_a_design(page: Any, studio: Any, tmp_path: Path):
    (tmp_path / "tiny.toml").write_text(TINY)
    run_study(load_study(tmp_path / "tiny.toml"), str(tmp_path / "tiny"), workers=1, stream=None)
    expand(page, "Studies")
    folder = page.locator('input[value="runs"]')
    folder.fill(str(tmp_path))
    wait_for(lambda: studio.studies.path.value == str(tmp_path), "the folder to reach the server")
    page.get_by_role("button", name="Find studies").click()
    expect(page.get_by_text("tiny: 2 runs done, 0 failed")).to_be_visible()
    expect(page.locator(".js-plotly-plot", has=page.locator(".gtitle", has_text="subtask2: MSE (mm)"))).to_be_visible()
    runs = finished_runs(study_rows(tmp_path / "tiny")[1])
    choose(page, "Run", runs[1].label)
    wait_for(lambda: studio.studies.run.value == runs[1].label, "the run to be chosen")
    page.get_by_role("button", name="Load its design").click()
    want = picked_design(tmp_path / "tiny", runs[1])
    wait_for(lambda: np.array_equal(studio.session.view.design.params, want.params), "the design in the editor")
    expect(page.get_by_text("Design loaded")).to_be_visible()  # the editor changed: the page says whose design
    expect(page.get_by_role("button", name="Undo study design")).to_be_visible()  # it read "Undo design"
