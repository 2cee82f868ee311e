"""The paper's constrained MOEAs in the studio (issue 11, items 4 and 5), in the browser: a designer picks one in
the Stages panel's Algorithm dropdown, runs a stage with it, and reads its trace (feasible ratios, task
probabilities, epsilon) in the small chart under the Pareto chart."""

from __future__ import annotations

from typing import Any

import pytest
from playwright.sync_api import expect
from test_studio_stages_in_the_browser import SUBTASK2, pareto_plot, run_stage

from benchmarks.studio import choose
from core.optimize.algorithms import ALGORITHMS
from studio.panels.stages import LABELS


def trace_chart(page: Any, name: str) -> Any:
    return page.locator(".js-plotly-plot", has=page.locator(".gtitle", has_text=f"{name} trace"))


@pytest.mark.parametrize(("name", "lines", "log_epsilon"), [
    ("moead_cmt", ["feasible (main)", "feasible (archive)", "P(task 1)"], False),
    ("imtcmo", ["feasible (main)", "feasible (auxiliary)"], True),
])
def test_a_stage_runs_with_a_cmoea_chosen_in_the_panel_and_its_trace_is_drawn(page: Any, studio: Any, name: str,
                                                                              lines: list[str],
                                                                              log_epsilon: bool) -> None:
    choose(page, "Stage", SUBTASK2)
    choose(page, "Algorithm", LABELS[name])  # by its published name, as the designer reads it
    r = run_stage(page, studio, SUBTASK2, "subtask2", pop=12, gens=4)
    assert r.status == "complete" and r.generation == 4
    assert r.settings["algorithm"]["name"] == name
    assert len(r.trace) == 4 and all(row["n_eval"] > 0 for row in r.trace)  # one row a generation
    expect(pareto_plot(page, "subtask2 · complete")).to_be_attached()
    chart = trace_chart(page, ALGORITHMS[name].title)
    expect(chart).to_be_visible()
    for line in lines:
        expect(chart.locator(".legendtext", has_text=line).first).to_be_attached()
    eps = chart.locator(".legendtext", has_text="epsilon")
    if log_epsilon:
        expect(eps).to_be_attached()
        expect(chart.locator(".y2title")).to_have_text("epsilon")
    else:
        expect(eps).to_have_count(0)
