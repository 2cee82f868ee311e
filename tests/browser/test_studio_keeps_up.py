"""The page keeps up with the server during a run, on software WebGL, and Stop acts at once (issue 13, item 4).

The lag is recorded as ``benchmarks/studio.py`` does it: how long ago the server reached the generation after
the one the page shows. Before pushes were paced by the page, this run trailed by 4-13 s; the bound here is
loose (a loaded CI machine draws slower), the pacing property is exact. Stop ends the run within STOP_BOUND
of the press.
"""

from __future__ import annotations

import time

from playwright.sync_api import expect
from test_studio_stages_in_the_browser import SUBTASK2, choose, settle, wait_for

from benchmarks.studio import PRESS_CLOCK, ServerClock, page_generation_at

STOP_BOUND = 1.0  # s from the press to the cancelled run
LAG_BOUND = 2.0  # s; measured ~0.1 s median, ~0.4 s worst on this machine (benchmarks/studio.py)


def test_the_page_trails_a_run_by_well_under_a_second_and_stop_acts_at_once(page, studio):
    studio.session.set_playing(True)  # the animation plays, as it does for a designer
    studio.refresh()
    choose(page, "Stage", SUBTASK2)
    settle(page, studio, "subtask2", 60, 2000)
    page.evaluate(PRESS_CLOCK)
    pushed0, answered0 = studio.scene.frames_pushed, studio.pacer.answered
    clock = ServerClock(studio, time.time)  # the page's press time is in the same clock
    page.get_by_role("button", name="Run", exact=True).click()
    lags: list[float] = []
    held_from: int | None = None
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if held_from is None and studio.session.study.status.running:
                held_from = studio.scene.frames_pushed
            shown, at = page_generation_at(page)  # and when the page showed it (its clock is time.time's)
            if shown is not None and shown > 0:
                nxt = clock.reached.get(shown + 1)
                lags.append(at - nxt if nxt is not None and nxt < at else 0.0)
            if shown is not None and shown >= 300:
                break
            time.sleep(0.05)
        assert lags, "the page never showed the run's progress"
        assert held_from is not None and studio.scene.frames_pushed <= held_from + 1  # no frames while it ran
        expect(page.get_by_text("(held while the stage runs)")).to_be_visible()
        page.get_by_role("button", name="Stop", exact=True).click()
        expect(page.get_by_text("Last run: subtask2 stopped at generation")).to_be_visible(timeout=30_000)
        # The run over, the animation goes on from where it held, and the readout says it plays.
        held = studio.session.playback.angle
        after = studio.scene.frames_pushed
        wait_for(lambda: studio.scene.frames_pushed > after + 2, "the animation to go on")
        expect(page.get_by_text("(playing)")).to_be_visible()
        assert studio.session.playback.angle != held
    finally:
        studio.runner.stop()
        studio.runner.join(30)
        clock.close()
        studio.session.set_playing(False)
    print(f"lag over {len(lags)} samples: median {sorted(lags)[len(lags) // 2]:.2f} s, max {max(lags):.2f} s")
    assert max(lags) < LAG_BOUND
    # Paced: a frame goes out only once every page has answered the probe after the previous push.
    pushed = studio.scene.frames_pushed - pushed0
    assert pushed <= studio.pacer.answered - answered0 + len(studio.server.get_clients()) + 1
    # Stop acted within a second of the press as the page's event records it (the benchmark measures ~0.04 s):
    # not seconds of queued generations later.
    pressed = page.evaluate("() => window.__downAt") / 1000.0
    at_press = max(g for g, t in clock.reached.items() if t <= pressed)
    within = max(g for g, t in clock.reached.items() if t <= pressed + STOP_BOUND)
    final = studio.session.study.result("subtask2").generation
    assert at_press <= final <= within + 1, (at_press, final, within)
