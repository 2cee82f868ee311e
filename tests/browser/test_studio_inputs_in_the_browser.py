"""Inputs (issue 13, item 11): a crank angle typed while the animation plays pauses it and sticks; the slider
stays still while playing, so the animation never writes into a box someone is typing in."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from test_studio_stages_in_the_browser import wait_for


def test_a_typed_crank_angle_pauses_playback_and_sticks(page: Any, studio: Any) -> None:
    studio.session.set_playing(True)
    studio.refresh()
    wait_for(lambda: studio.session.playback.playing, "playback")
    row = page.locator("label", has_text="Crank angle [deg]").locator(
        "xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]")
    box = row.locator(".mantine-NumberInput-root input")  # the slider's number box
    # While playing, the slider stays still (a readout runs instead): nothing is pushed into the box being typed in.
    wait_for(lambda: box.input_value() == f"{studio.playback.angle.value:g}", "the page to show the server's angle")
    before = box.input_value()
    time.sleep(1.0)
    assert box.input_value() == before and studio.session.playback.playing
    box.fill("90")
    box.press("Enter")
    wait_for(lambda: not studio.session.playback.playing, "the typed angle to pause playback")
    time.sleep(1.0)  # the animation would have moved it on by now
    assert math.degrees(studio.session.playback.angle) == pytest.approx(90.0)
    assert box.input_value() == "90"
