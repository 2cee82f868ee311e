"""The pacer: only a page's answer to its own probe counts; a page that has not answered holds the next frame
back, a stalled one no longer does."""

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
