"""Numeric entry fields the server parses: apply at once when valid, refuse when left invalid.

The studio's numbers are viser *text* inputs, not viser number inputs: viser's number input
(Mantine's) drops an empty or unparsable entry in the browser and strips letters as they are
typed ("1e9" arrives as 19), so the server would never see what the designer typed and could not
refuse it. A text input reports every keystroke verbatim; ``NumberField`` parses it.

Typing ``128`` first reports ``1`` and ``12``, which may well be invalid. A valid entry (a finite
number in the field's form and range that the apply function accepts) is applied immediately;
an invalid one ("", "abc", "nan", "1,5", out of range, refused by the model) is rejected only
once the field has kept it for ``delay`` seconds: the field returns to the last valid value and
the client that typed it gets a notification naming the field, the entry, the reason and what
the field takes.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import viser

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio

REJECT_DELAY = 0.8
# An edit whose callback never ran (its client left in between) stops holding the field after this.
STALE_EDIT = 2.0
# A text that has arrived but whose edit waits for one of viser's callback threads holds the field this long at most.
PENDING_EDIT = 30.0
# Plain decimal notation only: no "nan", "inf", "0x10", "1_000" or "1,5" (Python's float() takes some of those).
NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def set_value(handle: Any, value: object) -> None:
    """Assign a GUI input's value (sent to every client; our callbacks see ``client is None``).

    A function because viser declares ``value``'s setter apart from its getter, which mypy reads
    as a read-only property.
    """
    handle.value = value


def format_number(value: float, whole: bool = False, decimals: int = 6) -> str:
    """How a field shows a value: integers without ``.0``, others with up to ``decimals`` decimals (``128.33``)."""
    v = float(value)
    if whole or (v.is_integer() and abs(v) < 1e15):
        return str(int(v))
    text = f"{v:.{decimals}f}".rstrip("0").rstrip(".")
    if text in ("0", "-0"):  # too small for its decimals: keep its significant digits
        text = f"{v:.6g}"
    return text


@dataclass(frozen=True)
class NumberForm:
    """What a field takes: a (whole) number, optionally bounded; ``text`` overrides the description.

    Args:
        whole: only whole numbers (``40``, ``4e1``; not ``40.5``).
        lo, hi: inclusive bounds (None: unbounded); ``lo_open`` makes ``lo`` exclusive (``> 0``).
        unit: shown after the description (``mm``).
        text: the description when the model checks more than the form (a parameter's bounds).
        decimals: at most this many decimals shown; the value held keeps all of them.
    """

    whole: bool = False
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    unit: str = ""
    text: str | None = None
    decimals: int = 6

    def describe(self) -> str:
        """``a whole number from 2 to 2000``, ``a number > 0 (mm)``, ..."""
        if self.text is not None:
            return self.text
        unit = f" ({self.unit})" if self.unit else ""
        kind = "a whole number" if self.whole else "a number"
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None and not self.lo_open:
            return f"{kind} from {format_number(lo)} to {format_number(hi)}{unit}"
        parts = []
        if lo is not None:
            parts.append(f"{'>' if self.lo_open else '>='} {format_number(lo)}")
        if hi is not None:
            parts.append(f"<= {format_number(hi)}")
        return f"{kind}{' ' if parts else ''}{' and '.join(parts)}{unit}"

    def parse(self, text: str) -> float | int:
        """The number ``text`` spells, or ValueError saying why not (naming the entry)."""
        s = text.strip()
        if not s:
            raise ValueError("The field is empty")
        if not NUMBER.fullmatch(s):
            if NUMBER.fullmatch(s.replace(",", ".", 1)):
                raise ValueError(f"{text!r} is not a number (use a point for decimals)")
            raise ValueError(f"{text!r} is not a number")
        v = float(s)
        if not math.isfinite(v):
            raise ValueError(f"{text!r} is too large")
        if self.whole and not v.is_integer():
            raise ValueError(f"{text!r} is not a whole number")
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            raise ValueError(f"{text!r} is {'not above' if self.lo_open else 'below'} {format_number(self.lo)}")
        if self.hi is not None and v > self.hi:
            raise ValueError(f"{text!r} is above {format_number(self.hi)}")
        return int(v) if self.whole else v


class NumberField:
    """One numeric entry: a viser text input, what it takes, how to apply it, and its last valid value.

    Client edits go through :meth:`edit` (in viser's callback threads); the server's own changes
    through :meth:`show`, which never triggers the edit path.
    """

    def __init__(
        self,
        studio: Studio,
        handle: viser.GuiTextHandle,
        *,
        form: NumberForm,
        apply: Callable[[Any], object],
        current: Callable[[], float],
        what: str,
        delay: float = REJECT_DELAY,
        size_note: Callable[[float], str | None] | None = None,
    ) -> None:
        """
        Args:
            handle: the text input.
            form: what the field takes (parsed before ``apply``).
            apply: commits a parsed value; raises ValueError with the reason if the model refuses it.
            current: the last valid value (what the field returns to).
            what: how the notification names the field (``r4 [mm]``).
            size_note: a word on an applied value that is valid but of an odd size (a 5 m obstacle for a 300 mm
                leg), said in a yellow "check its size" notification, or None.
        """
        self.studio = studio
        self.handle = handle
        self.form = form
        self.apply = apply
        self.current = current
        self.what = what
        self.size_note = size_note
        self.delay = delay
        self._state = threading.Lock()  # the fields below
        self._edits = threading.Lock()  # one edit at a time, on the newest text
        self._timer: threading.Timer | None = None
        self._settled = handle.value  # the text last handled (an edit, or a value shown by the server)
        self._arrived: tuple[str, float] | None = None  # a client's newest text not yet handled, and when it came
        handle.on_update(self._on_arrival)  # first: viser awaits coroutines in order, then queues the others
        handle.on_update(self._on_update)

    @property
    def disabled(self) -> bool:
        return bool(self.handle.disabled)

    @disabled.setter
    def disabled(self, disabled: bool) -> None:
        self.handle.disabled = disabled

    def format(self, value: float) -> str:
        return format_number(value, self.form.whole, self.form.decimals)

    # The server's side ---------------------------------------------------------------------

    def show(self, value: float) -> None:
        """Show a value the server holds (sent to every client; not an edit).

        What the designer is typing is left alone: a pending rejection will restore the then
        valid value, an edit on its way or being applied ends in a refresh or a rejection, and a
        text that already spells the value (``12.`` for 12) stays as typed.
        """
        with self._state:
            if self._timer is not None or self._edits.locked():
                return
            if self._arrived is not None and time.time() - self._arrived[1] < PENDING_EDIT:
                return
            text = self.handle.value
            if text != self._settled and time.time() - self.handle.update_timestamp < STALE_EDIT:
                return
            shown = self.format(value)
            if text == shown:  # already shown (rounded to the form's decimals: not sent again each refresh)
                self._settled = text
                return
            try:
                if self.form.parse(text) == value:
                    self._settled = text
                    return
            except ValueError:
                pass
            self._settled = shown
            set_value(self.handle, self._settled)

    def cancel(self) -> None:
        """Drop a pending rejection (the field or the server is going away)."""
        with self._state:
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()

    # The client's side ---------------------------------------------------------------------

    async def _on_arrival(self, event: viser.GuiEvent[Any]) -> None:
        # In viser's event loop, as the text arrives. The edit itself waits for a callback thread, which a busy
        # server may take seconds to give it; until then no value the server shows may replace the text (it did
        # once, and the edit then found the server's value in the field and was lost).
        if event.client is not None:
            self.arrived(str(self.handle.value))

    def arrived(self, text: str) -> None:
        """Note a client's text that its edit will handle."""
        with self._state:
            self._arrived = (text, time.time())

    def _on_update(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:  # our own assignment, not an edit
            return
        self.edit(event.client)

    def edit(self, client: viser.ClientHandle) -> None:
        """Handle the field's newest text, typed by ``client``: apply it, or refuse it after ``delay``."""
        with self._edits:
            with self._state:
                text = self.handle.value if self._arrived is None else self._arrived[0]
                self._arrived = None
                if text == self._settled:  # handled already (a later callback saw the same text)
                    return
                self._settled = text
                timer, self._timer = self._timer, None
            if timer is not None:
                timer.cancel()
            try:
                value = self.form.parse(text)
                self.apply(value)
            except ValueError as exc:
                self._schedule(text, str(exc), client)
                return
        self.studio.refresh()
        said = None if self.size_note is None else self.size_note(value)
        if said:
            self.studio.notify(client, f"{self.what}: check its size", said, color="yellow")

    def _schedule(self, text: str, reason: str, client: viser.ClientHandle) -> None:
        timer = threading.Timer(self.delay, self._reject, (text, reason, client))
        timer.daemon = True
        with self._state:
            if self._settled != text:  # a newer edit came in meanwhile
                return
            self._timer = timer
        timer.start()

    def _reject(self, text: str, reason: str, client: viser.ClientHandle) -> None:
        kept = self.current()
        with self._state:
            # This runs in the timer's own thread; a newer edit would have replaced it.
            if self._timer is not threading.current_thread():
                return
            self._timer = None
            if self.handle.value != text:  # a newer edit is on its way
                return
            self._settled = self.format(kept)
            set_value(self.handle, self._settled)
        self.studio.notify(client, f"{self.what} not applied",
                           f"{reason}. It takes {self.form.describe()}. Kept {self.format(kept)}.")


class NumberFields:
    """Makes and keeps a panel's number fields (one pending rejection per field)."""

    def __init__(self, studio: Studio, delay: float = REJECT_DELAY) -> None:
        self.studio = studio
        self.delay = delay
        self.fields: dict[str, NumberField] = {}

    def add(
        self,
        key: str,
        label: str,
        value: float,
        *,
        form: NumberForm,
        apply: Callable[[Any], object],
        current: Callable[[], float],
        what: str | None = None,
        hint: str | None = None,
        disabled: bool = False,
        size_note: Callable[[float], str | None] | None = None,
    ) -> NumberField:
        """A text input labelled ``label`` in the current GUI container, showing ``value``.

        Args:
            key: unique name of the field in this panel.
            what: how notifications name it (default: the label).
            hint: shown on hover; what the field takes is added to it.
            size_note: see :class:`NumberField`.
        """
        takes = f"takes {form.describe()}"
        h = self.studio.server.gui.add_text(label, format_number(value, form.whole), disabled=disabled,
                                            hint=f"{hint} ({takes})" if hint else takes)
        field = NumberField(self.studio, h, form=form, apply=apply, current=current, what=what or label,
                            delay=self.delay, size_note=size_note)
        self.fields[key] = field
        return field

    def cancel_all(self) -> None:
        for f in self.fields.values():
            f.cancel()

    def clear(self) -> None:
        """Forget the fields (their inputs were removed), dropping pending rejections."""
        self.cancel_all()
        self.fields.clear()
