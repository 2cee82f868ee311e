"""``clm-studio``: serve the design studio on localhost.

    clm-studio [--host 127.0.0.1] [--port 8080] [--session FILE]

Opens on the paper's Stephenson-I X3 design, animating, against the compound-cycloid target
(or on the session in FILE, which is then saved back after every change). Everything the
browser needs is served locally (viser ships its client, plotly.js comes from the plotly
package), so the studio works offline. Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
from pathlib import Path
from typing import Literal

import numpy as np
import viser

from studio.geometry import frame_index
from studio.panels.bench import BenchPanel
from studio.panels.mechanism import MechanismPanel
from studio.panels.metrics import MetricsPanel
from studio.panels.playback import PlaybackPanel
from studio.panels.target import TargetPanel
from studio.scene import DEFAULT_ASPECT, FPS, Animator, MechanismScene
from studio.state import DesignView, Session

BRAND = (31, 119, 180)


class Studio:
    """The running studio: one viser server, one shared :class:`Session`, scene, panels, animator.

    Every client sees the same server-level scene and GUI, so two tabs show the same state and
    a reload receives the current state. Callbacks mutate the session, then call
    :meth:`refresh`, which redraws what changed from the latest snapshot under a render lock
    (so concurrent edits can never leave an older design on screen).

    Args:
        session: the state to serve.
        host, port: where to listen (port 0: any free port).
        session_path: if given, the session is written there after every change.
        fps: animation frame rate pushed to the clients.
    """

    def __init__(
        self,
        session: Session,
        host: str = "127.0.0.1",
        port: int = 8080,
        session_path: Path | None = None,
        fps: float = FPS,
    ) -> None:
        self.session = session
        self.session_path = session_path
        self._render_lock = threading.Lock()
        self._save_lock = threading.Lock()
        self._shown: DesignView | None = None
        self.server = viser.ViserServer(host=host, port=port, label="CLM Studio", verbose=False)
        self.server.gui.configure_theme(show_share_button=False, control_width="large", brand_color=BRAND,
                                        show_logo=False)
        self.server.gui.main_panel.dock_right()
        self.scene = MechanismScene(self.server)
        self.playback = PlaybackPanel(self, order=0)
        self.metrics = MetricsPanel(self, order=1)
        self.mechanism = MechanismPanel(self, order=2)
        self.target = TargetPanel(self, order=3)
        self.bench = BenchPanel(self, order=4)
        self.refresh(fit_camera=True)
        self.server.on_client_connect(self._on_connect)
        self.animator = Animator(self._tick, fps)
        self.animator.start()

    @property
    def url(self) -> str:
        host = self.server.get_host()
        shown = "localhost" if host in ("127.0.0.1", "localhost") else host
        return f"http://{shown}:{self.server.get_port()}"

    # State -> screen ----------------------------------------------------------------------

    def refresh(self, fit_camera: bool = False) -> None:
        """Show the latest session state; refit every camera if asked (a new design to frame)."""
        with self._render_lock:
            view, pb, _ = self.session.snapshot()
            if view is not self._shown:
                self.scene.show(view, frame_index(pb.angle, view.n_samples))
                self.mechanism.show(view)
                self.metrics.show(view)
                self.target.show(view)
                self.bench.show(view)
                self._shown = view
                self.autosave()
            self.playback.show(pb)
            if fit_camera:
                self.scene.fit_camera()
                for client in self.server.get_clients().values():
                    self._fit_client(client)

    def _fit_client(self, client: viser.ClientHandle) -> None:
        try:
            aspect = client.camera.aspect
        except (AssertionError, ZeroDivisionError):  # no camera report from this client yet
            aspect = DEFAULT_ASPECT
        self.scene.fit_camera(client, aspect)

    def _on_connect(self, client: viser.ClientHandle) -> None:
        """Refit the views to this client's canvas once it shows the initial camera.

        The initial camera is framed for a typical aspect ratio; a client's first camera report
        at that pose (not yet moved by the user) gives its real aspect. One refit per client.
        """
        fitted = threading.Event()

        def on_camera(cam: viser.CameraHandle) -> None:
            if fitted.is_set():
                return
            if np.allclose(cam.position, self.server.initial_camera.position, atol=1e-4):
                fitted.set()
                self._fit_client(client)

        client.camera.on_update(on_camera)

    def _tick(self, dt: float) -> None:
        pb = self.session.advance(dt)
        view = self._shown
        if view is None or not self.server.get_clients():  # nobody watching: keep time, skip the pushes
            return
        self.scene.draw(frame_index(pb.angle, view.n_samples))
        self.playback.tick(pb)

    def notify(
        self, client: viser.ClientHandle, title: str, body: str, color: Literal["red", "yellow"] = "red"
    ) -> None:
        """Tell one client something about its own action (red: refused; yellow: a warning)."""
        client.add_notification(title, body, color=color, auto_close_seconds=8.0, with_close_button=True)

    def autosave(self) -> None:
        """Write the session file, if any (atomically: a crash never leaves half a file)."""
        if self.session_path is None:
            return
        with self._save_lock:
            save_session(self.session, self.session_path)

    def close(self) -> None:
        """Stop the animation, pending input checks and the server."""
        self.animator.stop()
        self.mechanism.close()
        self.target.close()
        self.server.stop()


def save_session(session: Session, path: Path) -> None:
    """Write a session as JSON via a temporary file and an atomic rename."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(session.to_dict(), indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def load_session(path: Path) -> Session:
    """A session from a JSON file; ValueError naming the problem."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    try:
        return Session.from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="clm-studio", description="Design studio for closed-chain legged mechanisms.")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; the next free one if taken)")
    p.add_argument("--session", type=Path, metavar="FILE",
                   help="session JSON to open if it exists, and to save to after every change")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the studio until Ctrl-C; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        if args.session is not None and args.session.exists():
            session = load_session(args.session)
        else:
            session = Session.default()
        if args.session is not None:
            save_session(session, args.session)  # fail now, not on the first autosave
        studio = Studio(session, args.host, args.port, session_path=args.session)
    except (OSError, ValueError) as exc:
        print(f"clm-studio: error: {exc}", file=sys.stderr)
        return 2
    print(f"CLM Studio: {studio.url}  (Ctrl-C to stop)", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        studio.close()
    print("CLM Studio stopped.", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
