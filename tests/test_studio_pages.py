"""What the server keeps per page. The pacer: only a page's answer to its own probe counts; a page that has
not answered holds the next frame back, a stalled one no longer does. A chart per page: a page that left while
the server still listed it (its elements already removed by viser) is forgotten, not an error in the animator;
the pages still there get every figure."""

from __future__ import annotations

import plotly.graph_objects as go
import pytest
import viser
from viser import _messages

from studio import pacer as pacer_module
from studio.pacer import Pacer
from studio.panels._lazy import LazyPlotly


class FakeClient:
    def __init__(self, client_id: int) -> None:
        self.client_id = client_id


class Handle:
    """A page's chart element; ``removed`` ones refuse writes as viser's removed handles do."""

    def __init__(self, removed: bool = False) -> None:
        object.__setattr__(self, "removed", removed)
        object.__setattr__(self, "written", {})

    def __setattr__(self, name: str, value: object) -> None:
        if self.removed:
            raise RuntimeError(f"Cannot assign to {name!r} on a removed GuiPlotlyHandle.")
        self.written[name] = value


@pytest.fixture(scope="module")
def server():
    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


def test_a_wrong_or_late_answer_does_not_count(server, monkeypatch):
    p = Pacer(server)
    monkeypatch.setattr(server, "get_clients", lambda: {1: FakeClient(1)})
    p._pending[1] = ("probe", 10.0)
    p._on_answer(1, _messages.LocalStorageGetItemResponseMessage(value=None, error=None, request_uuid="other"))
    assert p.answered == 0
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: 10.5)
    assert not p.ready()  # still waiting for page 1
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: 10.0 + pacer_module.STALL + 0.1)
    assert p.ready()  # stalled: it no longer holds the frames back
    p._pending[1] = ("probe", 20.0)
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: 20.1)
    assert not p.ready()
    p._on_answer(1, _messages.LocalStorageGetItemResponseMessage(value=None, error=None, request_uuid="probe"))
    assert p.answered == 1 and p.ready()  # answered: the next frame may go


def test_a_page_that_left_is_forgotten_and_the_others_still_get_the_figure(server, monkeypatch):
    chart = LazyPlotly(server, server.gui.add_folder("charts"), 1.0, 0.7, {})
    here, gone, closed = Handle(), Handle(removed=True), Handle()
    chart._handles.update({1: here, 2: gone, 3: closed})
    monkeypatch.setattr(server, "get_clients", lambda: {1: object(), 2: object()})  # 3 disconnected
    fig = go.Figure(go.Scatter(x=[1, 2], y=[3, 4]))
    chart.figure = fig  # no RuntimeError from page 2
    chart.visible = True
    assert here.written == {"figure": fig, "visible": True}
    assert closed.written == {}
    assert set(chart._handles) == {1}
    assert chart.figure is fig and chart.visible
