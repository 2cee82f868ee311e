"""Number inputs with validated edits: apply at once when valid, revert when left invalid.

viser's number input reports every keystroke, so typing ``128`` first reports ``1``, which
may well be invalid. A valid value is applied immediately; an invalid one is rejected only
once the field has kept it for ``delay`` seconds: the field returns to the last valid value
and the client that typed it gets a notification with the reason.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

REJECT_DELAY = 0.8


def set_value(handle: Any, value: object) -> None:
    """Assign a GUI input's value (sent to every client; our callbacks see ``client is None``).

    A function because viser declares ``value``'s setter apart from its getter, which mypy reads
    as a read-only property.
    """
    handle.value = value


class ValidatedNumbers:
    """Binds number inputs to an apply function that raises ``ValueError`` on invalid input."""

    def __init__(self, studio: Studio, delay: float = REJECT_DELAY) -> None:
        self.studio = studio
        self.delay = delay
        self._lock = threading.Lock()
        self._pending: dict[str, threading.Timer] = {}

    def bind(
        self,
        key: str,
        handle: viser.GuiNumberHandle[Any],
        apply: Callable[[float], object],
        current: Callable[[], float],
        what: str,
    ) -> None:
        """Wire one input.

        Args:
            key: unique name of the field (one pending rejection per field).
            handle: the number input.
            apply: commits a value; raises ValueError with the reason if invalid.
            current: the last valid value (what the field returns to).
            what: how the notification names the field (``r4 (mm)``).
        """

        @handle.on_update
        def _(event: viser.GuiEvent[Any]) -> None:
            if event.client is None:  # our own assignment, not an edit
                return
            value = handle.value
            self._cancel(key)
            try:
                apply(value)
            except ValueError as exc:
                timer = threading.Timer(self.delay, self._reject, (key, handle, value, str(exc), current, what,
                                                                     event.client))
                timer.daemon = True
                with self._lock:
                    self._pending[key] = timer
                timer.start()
                return
            self.studio.refresh()

    def _cancel(self, key: str) -> None:
        with self._lock:
            timer = self._pending.pop(key, None)
        if timer is not None:
            timer.cancel()

    def _reject(
        self,
        key: str,
        handle: viser.GuiNumberHandle[Any],
        value: float,
        reason: str,
        current: Callable[[], float],
        what: str,
        client: viser.ClientHandle,
    ) -> None:
        with self._lock:
            # This runs in the timer's own thread; a newer edit would have replaced it.
            if self._pending.get(key) is not threading.current_thread():
                return
            del self._pending[key]
            if handle.value != value:  # the field was set to something else meanwhile
                return
        kept = current()
        set_value(handle, kept)
        self.studio.notify(client, f"{what} not applied", f"{reason}. Kept {kept:g}.")

    def cancel_all(self) -> None:
        with self._lock:
            timers = list(self._pending.values())
            self._pending.clear()
        for t in timers:
            t.cancel()
