"""What the server keeps per page. The pacer: only a page's answer to its own probe counts; a page that has
not answered holds the next frame back, a stalled one no longer does. A chart per page: a page that left while
the server still listed it (its elements already removed by viser) is forgotten, not an error in the animator;
the pages still there get every figure."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import plotly.graph_objects as go
import pytest
import viser
from viser import _messages

from studio import pacer as pacer_module
from studio.pacer import Pacer
from studio.panels._lazy import LazyPlotly
from studio.state import Session


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


class Connection:
    def __init__(self) -> None:
        self.sent: list[str] = []

    def queue_message(self, message: object) -> None:
        self.sent.append(message.request_uuid)  # type: ignore[attr-defined]


class ProbedClient(FakeClient):
    def __init__(self, client_id: int) -> None:
        super().__init__(client_id)
        self._websock_connection = Connection()

    def flush(self) -> None:
        pass


def test_a_page_is_probed_once_until_it_answers_or_stalls_and_then_again(server, monkeypatch):
    p, page = Pacer(server), ProbedClient(1)
    monkeypatch.setattr(server, "get_clients", lambda: {1: page})
    clock = {"t": 10.0}
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: clock["t"])
    p.probe()
    clock["t"] = 10.5
    p.probe()  # its probe is outstanding: no second one
    assert len(page._websock_connection.sent) == 1
    clock["t"] = 10.0 + pacer_module.STALL + 0.1
    p.probe()  # stalled: asked again, with a new id
    sent = page._websock_connection.sent
    assert len(sent) == 2 and sent[0] != sent[1] and p._pending[1][0] == sent[1]


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


def test_a_page_that_leaves_while_its_chart_is_made_gets_none_and_no_error(server):
    # CI, session 35: a page closed as its charts were attached raised "Cannot assign to 'aspect' on a removed
    # GuiPlotlyHandle" in the attaching thread
    class Leaving(FakeClient):
        class gui:  # noqa: N801 - the client's gui API, as viser names it
            @staticmethod
            def add_plotly(*args, **kwargs):
                return Handle(removed=True).__setattr__("aspect", 1.0)

    chart = LazyPlotly(server, server.gui.add_folder("charts"), 1.0, 0.7, {})
    chart.attach(Leaving(5))
    assert not chart.attached(Leaving(5))


def test_the_animation_holds_while_a_page_loads(monkeypatch):
    # A page that has connected but not yet drawn (no camera report) gets no scene frames and the crank stands
    # still for everyone; it goes on once the page has drawn, or LOAD_HOLD_MAX s after it connected.
    from studio import app as app_module
    from studio.app import Studio
    from studio.state import Session

    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    studio.animator.stop()  # ticks below are the test's own
    try:
        now = [100.0]
        monkeypatch.setattr(app_module.time, "monotonic", lambda: now[0])
        monkeypatch.setattr(studio.server, "get_clients", lambda: {7: FakeClient(7)})
        drawn: list[int] = []
        monkeypatch.setattr(studio.scene, "draw", lambda k: drawn.append(k) or False)
        studio._loading[7] = now[0]
        angle = studio.session.snapshot()[1].angle
        studio._tick(0.1)
        assert studio.session.snapshot()[1].angle == angle and drawn == []
        now[0] += app_module.LOAD_HOLD_MAX + 0.1  # a page that never reports its camera holds no longer
        studio._tick(0.1)
        assert studio.session.snapshot()[1].angle != angle and len(drawn) == 1
        studio._loading[7] = now[0]  # loading again (a reload), then it has drawn
        angle = studio.session.snapshot()[1].angle
        studio._tick(0.1)
        assert studio.session.snapshot()[1].angle == angle
        studio._loading.pop(7)
        studio._tick(0.1)
        assert studio.session.snapshot()[1].angle != angle and len(drawn) == 2
    finally:
        studio.close()


def test_the_animation_holds_from_a_page_request_until_that_page_connects(monkeypatch):
    # clm-studio's gate reports a page's request a second or so before its websocket connects: the hold starts
    # there, hands over to the page's own hold when it connects (each connect answers the oldest request), and
    # ends REQUEST_HOLD_MAX s after a request whose page never connects.
    from studio import app as app_module
    from studio.app import Studio
    from studio.state import Session

    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    studio.animator.stop()
    try:
        now = [100.0]
        monkeypatch.setattr(app_module.time, "monotonic", lambda: now[0])
        monkeypatch.setattr(studio.server, "get_clients", lambda: {7: FakeClient(7), 8: FakeClient(8)})
        monkeypatch.setattr(studio.scene, "draw", lambda k: False)

        def moves() -> bool:
            angle = studio.session.snapshot()[1].angle
            studio._tick(0.1)
            return studio.session.snapshot()[1].angle != angle

        def connects(cid: int) -> None:  # viser's connect callback, for a page without a browser
            studio._on_connect(PageClient(cid))

        assert moves()
        studio.page_requested()
        assert not moves()
        now[0] += app_module.REQUEST_HOLD_MAX - 0.1
        assert not moves()
        now[0] += 0.2  # that page never connected: the hold ends
        assert moves()
        studio.page_requested()
        studio.page_requested()  # two pages on their way
        now[0] += 0.5
        connects(7)  # the first connects: its own hold, and the second request's, go on ...
        studio._loading.pop(7)  # ... the first has drawn
        assert not moves()  # the second page has not connected yet
        connects(8)
        studio._loading.pop(8)  # the second has drawn: nothing holds
        assert moves()
    finally:
        studio.close()


class PageClient(FakeClient):
    """Enough of a viser ClientHandle for Studio._on_connect: a camera that takes a callback."""

    class Camera:
        def on_update(self, cb: object) -> None:
            pass

    def __init__(self, client_id: int) -> None:
        super().__init__(client_id)
        self.camera = self.Camera()


@pytest.mark.parametrize("preset", [None, "jansen", "rtclm/case1", "watt1/paper"])
def test_every_line_and_point_cloud_carries_a_colour_per_vertex(preset):
    # One colour per vertex everywhere (studio.frames.paint): a page then compiles one line shader and one point
    # shader. The colours must match the points in number, on every design and frame.
    import viser as v

    from studio.app import Studio
    from studio.state import Session

    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    studio.animator.stop()
    try:
        if preset is not None:
            studio.session.load_preset(preset)
            studio.refresh(fit_camera=True)
        nodes = [n for n in vars(studio.scene).values() if isinstance(n, (v.LineSegmentsHandle, v.PointCloudHandle))]
        nodes += [studio.inset.border, studio.inset.front]
        assert len(nodes) == 20
        n = studio.scene.frames.n_samples
        for k in (0, n // 3, n - 1):
            studio.scene.draw(k)
            for node in nodes:
                points, colors = np.asarray(node.points), np.asarray(node.colors)
                assert colors.dtype == np.uint8 and colors.shape == points.shape[:-1] + (3,), node.name
    finally:
        studio.close()


def test_a_canvas_resized_before_the_page_applied_its_framing_is_framed_again() -> None:
    # After a reload a tall design's top was cut off: the page's report of its final canvas size still showed the
    # initial camera (our framing not applied yet), which read as the designer's own move, so it was never refitted.
    from studio.app import Studio

    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    try:
        initial = np.asarray(studio.server.initial_camera.position, dtype=np.float64)
        framed = initial + np.array([0.0, 0.05, 0.2])
        studio._framed[5] = (1.6, framed)

        def report(position: np.ndarray, aspect: float) -> bool:
            return studio._resized(5, SimpleNamespace(position=position, aspect=aspect))

        assert report(initial, 0.8)  # the early report: framed again for the canvas it gives
        assert report(framed, 0.8)  # at our framing, the window resized
        assert not report(framed, 1.6) and not report(initial, 1.6)  # nothing changed shape
        assert not report(framed + np.array([0.3, 0.0, 0.0]), 0.8)  # the designer moved the camera: left alone
    finally:
        studio.close()
