"""The pacer: a page's frame time is the median of its recent probe round trips; a page that has not
answered holds the next frame back, a stalled one no longer does."""

from __future__ import annotations

import pytest
import viser
from viser import _messages

from studio import pacer as pacer_module
from studio.pacer import Pacer


class FakeClient:
    def __init__(self, client_id: int) -> None:
        self.client_id = client_id


@pytest.fixture(scope="module")
def server():
    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


def answer(p: Pacer, client_id: int, sent_at: float, now: float, monkeypatch) -> None:
    """The page ``client_id`` answers a probe sent at ``sent_at``, at ``now`` (monotonic seconds)."""
    p._pending[client_id] = ("probe", sent_at)
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: now)
    p._on_answer(client_id, _messages.LocalStorageGetItemResponseMessage(value=None, error=None, request_uuid="probe"))


def test_frame_time_is_the_median_round_trip_of_the_slowest_page(server, monkeypatch):
    p = Pacer(server)
    monkeypatch.setattr(server, "get_clients", lambda: {1: FakeClient(1), 2: FakeClient(2)})
    assert p.frame_time() == 0.0  # no answer yet
    for k, trip in enumerate([0.010, 0.012, 0.500, 0.011]):  # one slow outlier among fast frames
        answer(p, 1, 100.0 + k, 100.0 + k + trip, monkeypatch)
    assert p.frame_time() == pytest.approx(0.0115)
    for k, trip in enumerate([0.09, 0.11, 0.10]):
        answer(p, 2, 200.0 + k, 200.0 + k + trip, monkeypatch)
    assert p.frame_time() == pytest.approx(0.10)  # the slowest page's
    assert p.answered == 7
    monkeypatch.setattr(server, "get_clients", lambda: {1: FakeClient(1)})  # page 2 left
    assert p.frame_time() == pytest.approx(0.0115)
    for k in range(pacer_module.ROUND_TRIPS):  # only the last ROUND_TRIPS round trips count
        answer(p, 1, 300.0 + k, 300.0 + k + 0.2, monkeypatch)
    assert p.frame_time() == pytest.approx(0.2)


def test_a_wrong_or_late_answer_does_not_count(server, monkeypatch):
    p = Pacer(server)
    monkeypatch.setattr(server, "get_clients", lambda: {1: FakeClient(1)})
    p._pending[1] = ("probe", 10.0)
    p._on_answer(1, _messages.LocalStorageGetItemResponseMessage(value=None, error=None, request_uuid="other"))
    assert p.answered == 0 and p.frame_time() == 0.0
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: 10.5)
    assert not p.ready()  # still waiting for page 1
    monkeypatch.setattr(pacer_module.time, "monotonic", lambda: 10.0 + pacer_module.STALL + 0.1)
    assert p.ready()  # stalled: it no longer holds the frames back
