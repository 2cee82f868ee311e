"""Browser tests: Playwright drives Debian's headless chromium against a studio started in-process.

One studio and one page serve every browser test (a page load costs seconds under software
WebGL); the session is reset to the opening design, with no pipeline, before every test. Every non-loopback
request (HTTP or websocket) is blocked and recorded, so the tests also prove the studio works
offline. Skipped only when /usr/bin/chromium is missing (CI installs it).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
TIMEOUT_MS = 30_000
VIEWPORT = {"width": 1100, "height": 760}
LOOPBACK = re.compile(r"^(https?|wss?)://(127\.0\.0\.1|localhost|\[::1\])(:\d+)?(/|$)")


def is_local(url: str) -> bool:
    return bool(LOOPBACK.match(url)) or url.startswith(("data:", "blob:", "about:"))


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium); CI installs it")
    from playwright.sync_api import expect, sync_playwright

    expect.set_options(timeout=20_000)
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        yield b
        b.close()


@pytest.fixture(scope="session")
def studio(browser: Any) -> Iterator[Any]:
    """A studio on a free loopback port, on the default session (Stephenson-I X3, animating)."""
    from studio.app import Studio
    from studio.state import Session

    s = Studio(Session.default(), host="127.0.0.1", port=0)
    yield s
    s.close()


@pytest.fixture(scope="session")
def blocked() -> list[str]:
    """Non-loopback URLs the pages tried to reach (must stay empty)."""
    return []


def _new_context(browser: Any, blocked: list[str]) -> Any:
    def route(r: Any) -> None:
        if is_local(r.request.url):
            r.continue_()
        else:
            blocked.append(r.request.url)
            r.abort()

    def refuse_ws(ws: Any) -> None:
        blocked.append(ws.url)
        ws.close()

    ctx = browser.new_context(viewport=VIEWPORT)
    ctx.set_default_timeout(TIMEOUT_MS)
    ctx.route("**/*", route)
    ctx.route_web_socket(lambda url: not is_local(url), refuse_ws)
    return ctx


def open_studio(ctx: Any, port: int) -> Any:
    page = ctx.new_page()
    page.goto(f"http://127.0.0.1:{port}/")
    wait_ready(page)
    return page


def wait_ready(page: Any) -> None:
    """The scene canvas and the metrics table are there."""
    page.wait_for_selector("canvas", state="visible")
    page.wait_for_selector('table.clm-metrics tr[data-key="mse"] td[data-value]')


@pytest.fixture(scope="session")
def ready() -> Callable[[Any], None]:
    """``ready(page)`` waits until the studio page shows its scene and metrics."""
    return wait_ready


@pytest.fixture(scope="session")
def page(browser: Any, studio: Any, blocked: list[str]) -> Iterator[Any]:
    """The main page on the studio, shared by every browser test."""
    ctx = _new_context(browser, blocked)
    yield open_studio(ctx, studio.server.get_port())
    ctx.close()


@pytest.fixture
def open_page(browser: Any, studio: Any, blocked: list[str]) -> Iterator[Callable[[], Any]]:
    """Open another page on the studio (a second tab in its own browser context)."""
    contexts: list[Any] = []

    def _open() -> Any:
        ctx = _new_context(browser, blocked)
        contexts.append(ctx)
        return open_studio(ctx, studio.server.get_port())

    yield _open
    for ctx in contexts:
        ctx.close()


@pytest.fixture(autouse=True)
def fresh_session(request: pytest.FixtureRequest) -> None:
    """Put the studio back on the opening design, paused, with no pipeline, before each test that uses it.

    Paused because viser renders on demand: a still scene keeps software WebGL (and so the
    test) fast. The animation itself is tested explicitly.
    """
    if "studio" not in request.fixturenames:
        return
    from studio.state import DEFAULT_PRESET
    from studio.study import Study
    from studio.target import TargetSpec
    from studio.walking import WalkSpec

    studio = request.getfixturevalue("studio")
    studio.runner.stop()
    studio.runner.join(30)
    d, w = TargetSpec(), WalkSpec()
    studio.session.set_target(length=d.length, height=d.height, period=d.period)
    studio.session.set_walk(layout=w.layout, a=w.a, b=w.b, place=w.place)
    studio.session.load_preset(DEFAULT_PRESET)
    studio.session.set_playing(False)
    with studio.session.lock:
        studio.session.study = Study()
        studio.session.undone, studio.session.redone = [], []  # the reset above is not the user's to undo
    studio.refresh()
    studio.mechanism.show(studio.session.view)  # the Undo button follows (the view may not have changed)
