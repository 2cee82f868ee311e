"""Candidate labels as plotly.js draws the studio's Pareto charts from one update to the next.

viser updates a chart with ``Plotly.react``, which never draws a point's label again once it has been drawn as
"": K1 stayed blank after a pick moved its label onto the pick's ring and back, and on live charts after a redraw
that had left it to the hover (QA, session 36). The figures here are the studio's own, drawn in a page with the
plotly.js the studio ships.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import plotly
import pytest

from studio.figures import NO_LABEL, make_pareto_figure

PLOTLY_JS = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
LABELS = "() => Array.from(document.querySelectorAll('#chart .textpoint text')).map(t => t.textContent)"


@pytest.fixture(scope="module")
def chart_page(browser: Any) -> Any:
    ctx = browser.new_context(viewport={"width": 600, "height": 500})
    page = ctx.new_page()
    page.set_content("<div id='chart'></div>")
    page.add_script_tag(content=PLOTLY_JS.read_text())
    yield page
    ctx.close()


def draw(page: Any, fig: Any, how: str = "react") -> list[str]:
    """Draw ``fig`` with Plotly.newPlot or Plotly.react (as viser does) and return the label texts drawn (a far
    label's padding off)."""
    spec = json.loads(fig.to_json())
    page.evaluate(f"(f) => Plotly.{how}('chart', f.data, f.layout)", spec)
    return [t.replace("\xa0", " ").strip() for t in page.evaluate(LABELS) if t.replace("\xa0", " ").strip()]


def front() -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    t = np.linspace(0.0, 1.0, 12)
    F = np.column_stack([t, (1.0 - t) ** 2])
    return F, np.zeros(len(F)), {"objectives": ("a", "b"), "front": tuple(range(12)), "knees": (6, 3, 9),
                                 "best": (0, 11)}


def test_a_label_moved_onto_the_pick_and_back_is_drawn_again(chart_page: Any) -> None:
    F, cv, kw = front()
    plain, picked = make_pareto_figure(F, cv, **kw), make_pareto_figure(F, cv, shown=6, **kw)
    assert NO_LABEL in list(next(t for t in picked.data if t.name == "knees").text)
    everything = sorted(draw(chart_page, plain, "newPlot"))
    assert {"K1", "K2", "K3", "best a", "best b"} <= set(everything)
    # K1 picked: its label is drawn on the ring, once; unpicked: beside its diamond again (it stayed blank).
    assert sorted(draw(chart_page, picked)) == everything
    assert sorted(draw(chart_page, plain)) == everything
    assert sorted(draw(chart_page, make_pareto_figure(F, cv, shown=9, **kw))) == everything


def test_plotly_react_still_forgets_a_label_drawn_empty(chart_page: Any) -> None:
    # Why NO_LABEL is not "": when plotly.js draws labels from "" again (a fixed release would fail this test, and
    # NO_LABEL could go back to "").
    F, cv, kw = front()
    fig = make_pareto_figure(F, cv, **kw)
    knees = next(t for t in fig.data if t.name == "knees")
    text = list(knees.text)
    knees.text = [""] + text[1:]
    draw(chart_page, fig, "newPlot")
    knees.text = text
    assert text[0] not in draw(chart_page, fig)
