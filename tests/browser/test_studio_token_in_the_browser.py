"""The studio's gate in a real browser: the printed URL with its token opens the studio (page, scripts and
websocket pass the gate), the bare address shows only the refusal, and another page's script cannot open the
studio's websocket."""

from __future__ import annotations

from typing import Any

from studio.gate import Gate

TOKEN = "browser-token-0123"
OPENS_JS = """(url) => new Promise((done) => {
  const ws = new WebSocket(url, ['viser-v' + '0']);
  ws.onopen = () => { ws.close(); done('open'); };
  ws.onerror = () => done('refused');
  setTimeout(() => done('timeout'), 10000);
})"""


def test_the_url_with_the_token_opens_the_studio_and_without_it_nothing(browser: Any, studio: Any,
                                                                          ready: Any) -> None:
    gate = Gate("127.0.0.1", 0, studio.server.get_port(), TOKEN)
    try:
        ctx = browser.new_context(viewport={"width": 900, "height": 700})
        ctx.set_default_timeout(30_000)
        page = ctx.new_page()
        page.goto(f"http://127.0.0.1:{gate.get_port()}/?token={TOKEN}")
        ready(page)  # the scene and the metrics arrived over the gated websocket
        assert "token" not in page.url  # the gate dropped it from the address bar
        page.reload()
        ready(page)  # the cookie alone admits a reload
        ctx.close()

        stranger = browser.new_context()
        other = stranger.new_page()
        response = other.goto(f"http://127.0.0.1:{gate.get_port()}/")
        assert response is not None and response.status == 403
        assert "needs its token" in other.content() and other.locator("canvas").count() == 0
        stranger.close()
    finally:
        gate.close()


def test_another_pages_script_cannot_open_the_studios_websocket(browser: Any, studio: Any) -> None:
    gate = Gate("127.0.0.1", 0, studio.server.get_port())
    try:
        ctx = browser.new_context()
        page = ctx.new_page()
        url = f"ws://127.0.0.1:{gate.get_port()}/"
        page.goto(f"http://127.0.0.1:{gate.get_port()}/")  # the studio's own page: its origin may
        assert page.evaluate(OPENS_JS, url) == "open"
        page.goto("data:text/html,<p>another site</p>")  # any other page (origin null) may not
        assert page.evaluate(OPENS_JS, url) == "refused"
        page.goto(f"http://localhost:{gate.get_port()}/")  # nor a page served under another name
        assert page.evaluate(OPENS_JS, url) == "refused"
        ctx.close()
    finally:
        gate.close()
