"""The studio's number fields (``studio.panels._inputs``): what they parse, how they show values, and the edit path.

The fields are viser text inputs the server parses, so that "", "abc" or "1e9" reach the server and can be
refused (viser's own number input drops or mangles them in the browser). The browser side is in
tests/browser/test_studio_messages_in_the_browser.py; here a stand-in handle drives the same code.
"""

from __future__ import annotations

import inspect
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

from studio.panels._inputs import NumberField, NumberForm, format_number

POP = NumberForm(whole=True, lo=2, hi=2000)
LENGTH = NumberForm(lo=0.0, lo_open=True, unit="mm")


class Handle:
    """What NumberField uses of a viser text handle; ``type`` is a client's keystroke, ``value =`` the server's."""

    def __init__(self, value: str) -> None:
        self._value = value
        self.disabled = False
        self.update_timestamp = 0.0
        self.sent: list[str] = []
        self._callbacks: list[Callable[[Any], None]] = []

    @property
    def value(self) -> str:
        return self._value

    @value.setter
    def value(self, value: str) -> None:  # viser: skip unchanged, send, call back with client None
        if value == self._value:
            return
        self._value = value
        self.sent.append(value)
        self.update_timestamp = time.time()
        self._run(None)

    def on_update(self, cb: Callable[[Any], Any]) -> None:
        self._callbacks.append(cb)

    def _run(self, client: object, coroutines_only: bool = False) -> None:
        event = type("Event", (), {"client": client})()
        for cb in self._callbacks:
            if inspect.iscoroutinefunction(cb):  # one step: it never awaits (no event loop needed)
                with pytest.raises(StopIteration):
                    cb(event).send(None)
            elif not coroutines_only:
                cb(event)

    def arrive(self, text: str, client: object = "client") -> None:
        """A client's text reaches the server: viser sets it and awaits the coroutine callbacks; the others wait
        for a thread (``field.edit``)."""
        self._value = text
        self.update_timestamp = time.time()
        self._run(client, coroutines_only=True)

    def type(self, field: NumberField, text: str, client: object = "client") -> None:
        self.arrive(text, client)
        field.edit(client)  # type: ignore[arg-type]


class Studio:
    def __init__(self) -> None:
        self.refreshed = 0
        self.notes: list[tuple[object, str, str]] = []

    def refresh(self) -> None:
        self.refreshed += 1

    def notify(self, client: object, title: str, body: str) -> None:
        self.notes.append((client, title, body))


def make(form: NumberForm, value: float, check: Callable[[Any], None] | None = None,
         delay: float = 0.05) -> tuple[NumberField, Handle, Studio, list[Any]]:
    studio, handle, applied = Studio(), Handle(format_number(value, form.whole)), [value]

    def apply(v: Any) -> None:
        if check is not None:
            check(v)
        applied.append(v)

    field = NumberField(studio, handle, form=form, apply=apply, current=lambda: applied[-1],  # type: ignore[arg-type]
                        what="Population", delay=delay)
    return field, handle, studio, applied


@pytest.mark.parametrize(("value", "whole", "text"), [
    (40, True, "40"), (128.0, False, "128"), (128.33, False, "128.33"), (-4.21, False, "-4.21"),
    (1 / 3, False, "0.333333"), (123.4567891, False, "123.456789"), (1.5e-9, False, "1.5e-09"), (2.0, False, "2"),
])
def test_values_are_shown_as_a_person_writes_them(value: float, whole: bool, text: str) -> None:
    assert format_number(value, whole) == text


@pytest.mark.parametrize(("text", "value"), [("40", 40), (" 40 ", 40), ("4e1", 40), ("+40", 40), ("40.0", 40),
                                             ("2000", 2000), ("2", 2)])
def test_a_whole_number_in_range_parses(text: str, value: int) -> None:
    got = POP.parse(text)
    assert got == value and isinstance(got, int)


@pytest.mark.parametrize(("text", "reason"), [
    ("", "The field is empty"), ("   ", "The field is empty"), ("abc", "'abc' is not a number"),
    ("nan", "'nan' is not a number"), ("inf", "'inf' is not a number"), ("-inf", "'-inf' is not a number"),
    ("1,5", "use a point for decimals"), ("1_000", "is not a number"), ("0x10", "is not a number"),
    ("40.5", "'40.5' is not a whole number"), ("1e9", "'1e9' is above 2000"), ("1", "'1' is below 2"),
    ("1e400", "'1e400' is too large"), ("-", "'-' is not a number"), ("1e", "'1e' is not a number"),
])
def test_anything_else_is_refused_naming_the_entry(text: str, reason: str) -> None:
    with pytest.raises(ValueError, match=reason.replace("(", r"\(")):
        POP.parse(text)


def test_forms_describe_what_they_take() -> None:
    assert POP.describe() == "a whole number from 2 to 2000"
    assert LENGTH.describe() == "a number > 0 (mm)"
    assert NumberForm(lo=0.0, unit="mm").describe() == "a number >= 0 (mm)"
    assert NumberForm().describe() == "a number"
    assert NumberForm(text="an angle in rad").describe() == "an angle in rad"
    with pytest.raises(ValueError, match="'0' is not above 0"):
        LENGTH.parse("0")


def test_a_valid_entry_is_applied_at_once_and_left_as_typed() -> None:
    field, handle, studio, applied = make(LENGTH, 12.0)
    handle.type(field, "12.")  # the same value: applied, and the field keeps the point being typed
    handle.type(field, "12.5")
    assert applied[-1] == 12.5 and studio.refreshed == 2 and studio.notes == []
    field.show(12.5)  # the refresh that follows does not rewrite what is typed
    assert handle.value == "12.5" and handle.sent == []


def test_an_invalid_entry_is_refused_after_the_delay_and_the_field_shows_the_last_value() -> None:
    field, handle, studio, applied = make(POP, 40)
    handle.type(field, "1e9", client="me")
    assert handle.value == "1e9" and studio.notes == []  # not yet: it may be on its way to a valid entry
    time.sleep(0.2)
    assert handle.value == "40" and applied == [40]
    ((client, title, body),) = studio.notes
    assert client == "me" and title == "Population not applied"
    assert body == "'1e9' is above 2000. It takes a whole number from 2 to 2000. Kept 40."


def test_an_entry_on_its_way_to_a_valid_one_is_not_refused() -> None:
    field, handle, studio, applied = make(POP, 40, delay=0.2)
    for text in ("", "1", "12", "128"):
        handle.type(field, text)
    time.sleep(0.4)
    assert applied == [40, 12, 128] and studio.notes == [] and handle.value == "128"


def test_the_model_refuses_too_and_says_why() -> None:
    def positive_and_small(v: float) -> None:
        if v > 100:
            raise ValueError(f"r4 = {v:g} mm does not assemble")

    field, handle, studio, applied = make(LENGTH, 50.0, positive_and_small)
    handle.type(field, "500")
    time.sleep(0.2)
    assert handle.value == "50" and applied == [50.0]
    assert studio.notes[0][2] == "r4 = 500 mm does not assemble. It takes a number > 0 (mm). Kept 50."


def test_the_server_shows_its_values_without_the_edit_path_but_not_over_a_pending_entry() -> None:
    field, handle, studio, applied = make(LENGTH, 50.0)
    field.show(60.25)  # a preset, a pick, another page
    assert handle.value == "60.25" and handle.sent == ["60.25"] and applied == [50.0] and studio.refreshed == 0
    field.show(60.25)
    assert handle.sent == ["60.25"]  # nothing to send
    applied.append(60.25)
    handle.type(field, "abc")
    field.show(70.0)  # while "abc" waits for its refusal, the server's value is not forced over it ...
    assert handle.value == "abc"
    applied.append(70.0)
    time.sleep(0.2)  # ... the refusal puts the then valid value back
    assert handle.value == "70" and "Kept 70." in studio.notes[-1][2]


def test_a_parameter_is_shown_to_its_decimals_and_typed_digits_are_kept() -> None:
    # A rehearsal saw a preset's "128.33" become "100.609144" after a run's pick: lengths show 0.01 mm.
    from studio.panels.mechanism import param_form
    from studio.state import Session

    mech = Session.default().view.design.mechanism
    r4, b = (next(p for p in mech.params if p.name == n) for n in ("r4", "b"))
    field, handle, studio, applied = make(param_form(r4), 128.33)
    field.show(100.609144)
    assert handle.value == "100.61" and applied == [128.33]  # shown rounded; the value held is not touched
    field.show(100.609144)
    assert handle.sent == ["100.61"]
    handle.type(field, "100.6091")  # the designer's own digits stay as typed
    assert applied[-1] == 100.6091
    field.show(100.6091)
    assert handle.value == "100.6091"
    angle, _, _, _ = make(param_form(b), 0.52)
    angle.show(0.523456789)
    assert angle.handle.value == "0.5235"  # 0.0001 rad


def test_the_newest_text_wins_when_edits_overlap() -> None:
    # viser runs callbacks in a thread pool: two keystrokes may be handled at once. Each handles the newest text.
    slow = threading.Event()

    def check(v: float) -> None:
        if v == 12:
            slow.wait(1.0)

    field, handle, studio, applied = make(LENGTH, 1.0, check)
    first = threading.Thread(target=handle.type, args=(field, "12"))
    first.start()
    time.sleep(0.05)
    second = threading.Thread(target=handle.type, args=(field, "12.5"))  # waits for the first edit to finish
    second.start()
    time.sleep(0.05)
    slow.set()
    first.join()
    second.join()
    assert applied[-1] == 12.5 and handle.value == "12.5" and studio.notes == []


def test_a_refusal_due_while_a_newer_text_is_on_its_way_leaves_that_text_alone() -> None:
    field, handle, studio, applied = make(POP, 40)
    handle.type(field, "1e9")
    handle.arrive("12")  # typed on: its edit callback has not run yet
    time.sleep(0.2)
    assert handle.value == "12" and studio.notes == [] and applied == [40]


def test_cancel_drops_a_pending_refusal() -> None:
    field, handle, studio, _ = make(POP, 40)
    handle.type(field, "abc")
    field.cancel()
    time.sleep(0.2)
    assert studio.notes == [] and handle.value == "abc"


def test_a_text_waiting_for_a_callback_thread_is_not_replaced_by_the_servers_value_however_long_it_waits() -> None:
    # A busy server (a first run compiling its kernels) gave an edit's callback a thread seconds after the text
    # came: a refresh meanwhile put the server's value in the field, and the edit found nothing to do.
    field, handle, studio, applied = make(POP, 40)
    handle.arrive("16")
    handle.update_timestamp -= 10.0  # long past STALE_EDIT
    field.show(40)
    assert handle.value == "16" and handle.sent == []
    field.edit("client")  # type: ignore[arg-type]
    assert applied == [40, 16] and studio.refreshed == 1
    field.show(16)
    assert handle.value == "16" and handle.sent == []


def test_texts_that_arrive_while_an_edit_waits_are_applied_once_the_newest() -> None:
    field, handle, studio, applied = make(POP, 40)
    handle.arrive("1")
    handle.arrive("16")
    field.show(40)
    assert handle.value == "16"
    field.edit("client")  # type: ignore[arg-type]
    field.edit("client")  # type: ignore[arg-type]  # the second keystroke's callback: handled already
    assert applied == [40, 16] and studio.refreshed == 1 and studio.notes == []


def test_the_target_and_obstacle_fields_state_the_limits_the_model_keeps() -> None:
    # QA (session 37): L = 1e9 read "must be at most 1e+06 mm, got 1000000000.0. It takes a number > 0 (mm)", and
    # T = 1e-9 "must be between 1e-06 and 1e+06 s ... It takes a number > 0 (s)": the form's own words now name the
    # whole rule, and refuse first.
    from studio.panels.target import field_form
    from studio.panels.walking import SIDE

    length, period = field_form("length", "mm"), field_form("period", "s")
    assert length.describe() == "a number > 0 and <= 1000000 (mm)"
    assert period.describe() == "a number from 0.000001 to 1000000 (s)"
    with pytest.raises(ValueError, match=r"^'1e9' is above 1000000$"):
        length.parse("1e9")
    with pytest.raises(ValueError, match=r"^'1e-9' is below 0.000001$"):
        period.parse("1e-9")
    with pytest.raises(ValueError, match=r"^'2e6' is above 1000000$"):
        SIDE.parse("2e6")
    # What the forms let through, the model takes: their bounds are the model's.
    from studio.target import TargetSpec

    TargetSpec(length=length.parse("1e6"), height=length.parse("1e6"), period=period.parse("1e-6")).target()
    TargetSpec(period=period.parse("1e6")).target()
