"""Record the README's pictures of a whole X0 -> X3 session: assets/studio.png and assets/session.gif.

    .venv/bin/python scripts/record_session.py            # about two minutes on a 2-core machine

A studio starts on the paper's Stephenson-I design; headless chromium (Debian's) opens it at 1600 x 1000.
Predesign, subtask 1, 2 and 3 run in turn (small populations, so the recording stays short), each stage's
knee candidate is passed on, and the page is photographed along the way. The GIF is those photographs,
half size, one second each.
"""

from __future__ import annotations

import sys
import time
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from PIL import Image  # noqa: E402 - Pillow comes with viser's imageio
from playwright.sync_api import sync_playwright  # noqa: E402

from studio.app import Studio  # noqa: E402
from studio.chains import RunSettings, find  # noqa: E402
from studio.state import Session  # noqa: E402

STAGES = (("predesign", 60, 20), ("subtask1", 60, 20), ("subtask2", 60, 25), ("subtask3", 60, 25))


def run(studio: Studio, name: str, pop: int, gens: int) -> None:
    stage = find(studio.chain(), name)
    with studio.session.lock:
        studio.session.study.next_stage = name
        studio.session.study.settings[name] = RunSettings(stage.name, "nsga2", pop, gens, 2)
    studio._last_start = -10.0
    studio.start_run()
    studio.runner.join(600)
    studio.refresh()


def main() -> int:
    studio = Studio(Session.default(), host="127.0.0.1", port=0)
    frames: list[Image.Image] = []
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=["--headless", "--no-sandbox"])
            page = browser.new_context(viewport={"width": 1600, "height": 1000}).new_page()
            page.goto(f"http://127.0.0.1:{studio.server.get_port()}/")
            page.wait_for_selector('table.clm-metrics tr[data-key="mse"] td[data-value]', timeout=120_000)
            time.sleep(1.0)
            for close in page.locator(".mantine-Notification-closeButton").all():  # viser's software-WebGL notice
                close.click()

            def shot(wait: float = 1.5) -> None:
                time.sleep(wait)
                frames.append(Image.open(BytesIO(page.screenshot())).convert("RGB"))

            shot(3.0)
            for k, (name, pop, gens) in enumerate(STAGES):
                run(studio, name, pop, gens)
                shot()
                if name == "subtask2":
                    page.screenshot(path=str(ROOT / "assets" / "studio.png"), clip={"x": 0, "y": 0, "width": 1600,
                                                                                    "height": 900})
                if k + 1 < len(STAGES):
                    studio.use_for_next(name, None)
                    shot(1.0)
            browser.close()
    finally:
        studio.close()
    small = [f.resize((800, 500)).quantize(colors=128) for f in frames]
    small[0].save(ROOT / "assets" / "session.gif", save_all=True, append_images=small[1:], duration=1200, loop=0,
                  optimize=True)
    print(f"wrote assets/studio.png and assets/session.gif ({len(frames)} frames)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
