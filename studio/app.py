"""The running studio: one viser server, one shared session, its scene, panels, animator and stage runner.

Everything the browser needs is served locally (viser ships its client, plotly.js comes from the plotly
package), so the studio works offline. ``studio.serve`` is the ``clm-studio`` command that starts it.
"""

from __future__ import annotations

import collections
import json
import sys
import threading
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
import viser
from viser import _messages

from core.formats.drawing import Plates
from core.formats.files import slug
from core.optimize.lineage import next_feasible, unmet_by, where_mask
from studio.address import url_for
from studio.candidates import candidates
from studio.chains import ChainStage, chain_for, find, sized_where, stage_spec, takes_target
from studio.charts import png, stop_png_browser
from studio.exports import design_json, drawing_export, drawing_warnings, figure_html, notice_closed, trajectories_csv
from studio.frames import DEFAULT_ASPECT, FPS, INSET_EXPORT_TITLE, INSET_NOTE, INSET_TITLE, SceneFrames, inset_caption
from studio.geometry import SCENE_SCALE, frame_index, inset_positions
from studio.inset import Animator, CandidateInset, InsetMarker
from studio.pacer import Pacer
from studio.panels.bench import BenchPanel
from studio.panels.files import FilesPanel
from studio.panels.history import HistoryPanel
from studio.panels.mechanism import MechanismPanel
from studio.panels.metrics import MetricsPanel
from studio.panels.pareto import ParetoPanel, pareto_figure
from studio.panels.pick import PickPanel
from studio.panels.playback import PlaybackPanel
from studio.panels.stages import StagesPanel
from studio.panels.studies import StudiesPanel
from studio.panels.target import TargetPanel
from studio.panels.walking import WalkingPanel
from studio.runner import LIVE_PERIOD, Runner
from studio.scene import MechanismScene
from studio.session_file import read_session_bytes, rescue_session, save_session
from studio.state import DesignView, Session, same_leg
from studio.study import result_labels
from studio.study_view import StudyView, constraint_text, study_view

BRAND = (31, 119, 180)
# While a stage runs, the study panels (Pareto chart, progress) are redrawn at most this often.
STUDY_PUSH_PERIOD = 0.15
# While a stage runs, the session file is written at most this often (s; the first generation at once, the end
# always): a restart loses at most the last seconds of a run. Written after every generation (30-45 ms for a
# session with a few dozen branches, against a few ms a generation) a run took about 15 times as long.
SAVE_PERIOD = 2.0
SAVE_REMIND = 60.0  # s: a failing autosave is said again after this long while it keeps failing
# A Run click this soon after a run of the same stage and settings started is the second click of a double
# click (even if that run already finished): it starts nothing.
DOUBLE_CLICK = 1.0
# A page gets its plotly charts this long after it first reports its camera (it has drawn), or after it connected
# if it reports none (s): with them viser sends it plotly.js, compiled once the page is up (studio/panels/_lazy.py).
PLOTLY_AFTER, PLOTLY_LATEST = 0.5, 3.0
# The scene holds still while a page loads, until it first reports its camera (it has drawn) or this many
# seconds after it connected: frames pushed during a load made the new page and the open ones compete for the
# two cores (a second tab ready in 1.55-1.8 s against 1.4-1.5 s with the animation paused).
LOAD_HOLD_MAX = 3.0
# A page's request for the studio's address (seen by clm-studio's gate) starts the hold that long before its
# websocket connects: fetching and starting viser's client takes ~0.5-1 s, which the frames pushed to the open
# pages competed with. It ends when a page connects (its own hold goes on), or after this many seconds.
REQUEST_HOLD_MAX = 2.0
# A page whose canvas aspect changed by more than this (a resized window), its camera not moved by the designer,
# is framed again: a demo moved to a projector's resolution cut the mechanism and slid the inset under the panel.
RESIZE = 0.02
FIT_LATEST = 4.0  # s after connecting: a page not framed yet is framed with the aspect it last reported
# viser's notice on a page drawing with software WebGL (its client's BrowserWarning.tsx), closed this many seconds
# after the page has drawn (Studio.notice_seconds): it never closes by itself and covers the scene's top-left.
VIEWER_NOTICE, NOTICE_SECONDS = "webgl-software-rendering", 10.0


def later(delay: float, fn: Any, *args: Any) -> None:
    """Call ``fn(*args)`` in ``delay`` seconds on a daemon thread: a pending call never holds up the process's
    exit (Ctrl-C while a page's charts were still due left ``clm-studio`` waiting on one)."""
    t = threading.Timer(delay, fn, args)
    t.daemon = True
    t.start()


def unsaved_text(reason: str) -> str:
    """What a page is told while its session cannot be saved."""
    return (f"{reason}. The work goes on in memory and is written at the next change once saving works again; if the "
            "file still cannot take it when the studio stops, it goes to the user's cache.")


class StudioServer(viser.ViserServer):
    """viser's server, never published: viser answers any client's share request by opening a public tunnel
    to the studio through an outside relay (share.viser.studio); the studio refuses it."""

    def request_share_url(self, verbose: bool = True) -> str | None:
        return None


class Studio:
    """The running studio: one viser server, one shared :class:`Session`, scene, panels, animator, runner.

    Every client sees the same server-level scene and GUI, so two tabs show the same state and
    a reload receives the current state. Callbacks mutate the session, then call
    :meth:`refresh`, which redraws what changed from the latest snapshot under a render lock
    (so concurrent edits can never leave an older design on screen). Stages run in the
    :class:`~studio.runner.Runner`'s worker thread, which records the live result every ``LIVE_PERIOD`` s,
    saves the session (every ``SAVE_PERIOD`` s) and refreshes (throttled).

    Args:
        session: the state to serve.
        host, port: where to listen (port 0: any free port).
        session_path: if given, the session is written there after every change, and during a run every
            ``SAVE_PERIOD`` s and at its end.
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
        self.notice_seconds = NOTICE_SECONDS
        self._render_lock = threading.RLock()
        self._save_lock = threading.Lock()
        self._shown: DesignView | None = None
        self._optimized_by: tuple[str, ...] | None = None
        self._study_key: object = None
        self._inset_key: object = None
        self._inset_drawn: object = None
        self._inset_box: np.ndarray | None = None  # where the inset's square was placed (mm)
        self._last_push = 0.0
        self._study_dirty = False
        self._fitted: np.ndarray | None = None  # the views' bounds the camera last framed (mm)
        self._last_start = -DOUBLE_CLICK
        self._last_request: object = None  # (stage, settings, from the pick) of the last run started
        self._loading: dict[int, float] = {}  # pages that have not drawn yet: client id -> connected at
        self._framed: dict[int, tuple[float, np.ndarray]] = {}  # client id -> the aspect and position it was framed at
        self._save_error: str | None = None  # the last autosave's failure, said to every page
        self._save_said = 0.0  # when it was last said
        self._requested: collections.deque[float] = collections.deque()  # pages asked for, not yet connected
        self._request_lock = threading.Lock()  # the gate's thread adds, viser's and the animator's take
        self.server = StudioServer(host=host, port=port, label="CLM Studio", verbose=False)
        self.server.gui.configure_theme(show_share_button=False, control_width="large", brand_color=BRAND,
                                        show_logo=False)
        self.server.gui.main_panel.dock_right()
        self.pacer = Pacer(self.server)
        self.scene = MechanismScene(self.server)
        self.inset = CandidateInset(self.server, self._on_inset_pick)
        # A run records its live result every LIVE_PERIOD s, which is what the pages can show; with a session
        # file, one every SAVE_PERIOD s reaches the disk.
        self.runner = Runner(session.lock, lambda: self.session.study, self._on_generation, self._on_finish,
                             LIVE_PERIOD)
        self._run_saved = -SAVE_PERIOD  # when a running stage was last saved (monotonic s)
        self.playback = PlaybackPanel(self, order=0)
        self.stages = StagesPanel(self, order=1)
        self.pareto = ParetoPanel(self, order=2)
        self.pick_panel = PickPanel(self, order=3)
        self.metrics = MetricsPanel(self, order=4)
        self.mechanism = MechanismPanel(self, order=5)
        self.target = TargetPanel(self, order=6)
        self.walking = WalkingPanel(self, order=7)
        self.history = HistoryPanel(self, order=8)
        self.bench = BenchPanel(self, order=9)
        self.files = FilesPanel(self, order=10)
        self.studies = StudiesPanel(self, order=11)
        self.refresh(fit_camera=True)
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(self._forget_client)
        self.animator = Animator(self._tick, fps)
        self.animator.start()

    @property
    def url(self) -> str:
        return url_for(self.server.get_host(), self.server.get_port())

    def chain(self) -> tuple[ChainStage, ...]:
        """The stages offered for the editor's mechanism."""
        return chain_for(self.session.view.design.mechanism)

    # State -> screen ----------------------------------------------------------------------

    def study_view(self) -> StudyView:
        with self.session.lock:
            view = self.session.view
            return study_view(self.session.study, view.design, self.chain(), view.target)

    def refresh(self, fit_camera: bool = False) -> None:
        """Show the latest session state; refit every camera if asked (a new design to frame)."""
        with self._render_lock:
            view, pb, _ = self.session.snapshot()
            optimized_by = self.target_stages()
            changed = view is not self._shown or optimized_by != self._optimized_by
            previous = self._shown
            if changed:
                shown = bool(optimized_by)
                self.scene.show(view, frame_index(pb.angle, view.n_samples), shown)
                self.mechanism.show(view)
                self.metrics.show(view)
                self.target.show(view, optimized_by)
                self.walking.show(view)
                self.bench.show(view, shown)
                self._shown, self._optimized_by = view, optimized_by
            self.playback.show(pb, self.held())
            self.files.show(self.session.plates)  # a loaded session's pin holes (the field kept the old ones)
            sv = self.study_view()
            study_changed = sv.key != self._study_key
            if changed and not fit_camera:
                # Another topology, however it came (a pick, a study's design): framed as the Topology dropdown
                # frames it (rehearsal 7: a pick that changed the RTCLM's mode left the scene in a corner).
                fit_camera = self._outgrown() or (previous is not None and
                                                  previous.design.mechanism.name != view.design.mechanism.name)
            if fit_camera:
                self._inset_box = None  # the camera moves: the inset goes where the new layout puts it
            if changed or study_changed:
                self._show_study(sv)
                self.metrics.show_stage(sv, view)
                self._last_push = time.monotonic()
            if fit_camera:
                self._show_inset(sv)  # nothing to do if the study was just shown
                frames = self.scene.frames
                self._fitted = None if frames is None else frames.composition.bounds.copy()
                self.scene.fit_camera()
                for client in self.server.get_clients().values():
                    self._fit_client(client)
        # While a stage runs, its live result changes the study at every push (~6 a second with a page open): the
        # runner saves it every SAVE_PERIOD s and at its end. Saving here too took 3 of a run's 4.6 s at 2.6 MB.
        if (changed or study_changed) and not self.session.study.status.running:
            self.autosave()

    def target_stages(self) -> tuple[str, ...]:
        """The stages of the editor's mechanism whose problem (as set in the Stages panel) optimizes the Target
        panel's target; the target is drawn only if there is one (the RTCLM stages optimize h6 and h4)."""
        with self.session.lock:
            study = self.session.study
            return tuple(st.name for st in self.chain() if takes_target(study.settings_for(st).problem))

    def _outgrown(self) -> bool:
        """True when the views' extent changed enough that the camera should frame them again: they no longer
        fit in what was framed, or they shrank to less than half of it (a Jansen pick 4x larger, a preset), or to
        less than 0.7 of its height or width (a design without a walking view lost the views' lower row and sat in
        the top half of an empty page, QA session 38: X3's views keep 0.48 of their height then, Jansen's 0.57,
        Watt-I's 0.56)."""
        frames = self.scene.frames
        if frames is None:
            return False
        b, old = frames.composition.bounds, self._fitted
        if old is None:
            return True
        span = max(old[2] - old[0], old[3] - old[1], 1e-9)
        outside = bool((b[:2] < old[:2] - 0.02 * span).any() or (b[2:] > old[2:] + 0.02 * span).any())
        shrunk = max(b[2] - b[0], b[3] - b[1]) < 0.5 * span
        lower = (b[3] - b[1]) < 0.7 * (old[3] - old[1]) or (b[2] - b[0]) < 0.7 * (old[2] - old[0])
        return bool(outside or shrunk or lower)

    def _show_study(self, sv: StudyView) -> None:
        self.mechanism.hold(sv.status.running)
        self.mechanism.show_steps()  # a pass-on, or its Undo, moves the history without a new design
        self.stages.show(sv)
        self.pareto.show(sv)
        self.pick_panel.show(sv)
        self.history.show(sv)
        self._show_inset(sv)
        self._study_key = sv.key

    def _steady_inset(self, frames: SceneFrames) -> np.ndarray:
        """The inset's square (mm). A pick lays the views out again, which moved the square, and the sphere under
        the pointer, by 1-2 % of its side: while the camera stays, the square stays where it was if the new one is
        within 3 % of its side and the leg view keeps a text height of room to it (the layout leaves two)."""
        new, old = frames.composition.inset, self._inset_box
        if old is not None:
            side = old[2] - old[0]
            near = bool(np.abs(new - old).max() <= 0.03 * side)
            if near and new[0] - old[0] <= frames.text_height / SCENE_SCALE:
                return old
        self._inset_box = new.copy()
        return new

    def _show_inset(self, sv: StudyView) -> None:
        frames = self.scene.frames
        if frames is None:
            return
        box = self._steady_inset(frames)
        r = sv.result(sv.viewing)
        key = (tuple(np.round(box, 6)), frames.text_height, sv.shown)
        if r is self._inset_drawn and key == self._inset_key:  # by identity: a freed result's id can be reused
            return
        running = sv.status.running and sv.status.stage == sv.viewing
        if running:
            self._inset_key = None  # held still while the stage runs: the end of the run redraws it
            return
        self._inset_key, self._inset_drawn = key, r
        if r is None or r.pop == 0:
            self.inset.place(box, INSET_NOTE, frames.text_height)
            self.inset.show((), np.zeros((0, 2)), None)
            return
        spec = sv.specs.get(sv.viewing or "")
        labels = dict(spec.problem.labels) if spec is not None else {}
        if len(r.objectives) == 1:
            xy = np.stack([r.F[:, 0], r.cv], axis=1)
            axes = inset_caption(labels.get(r.objectives[0], r.objectives[0]), "violation")
        else:
            xy = r.F[:, :2]
            axes = inset_caption(*(labels.get(o, o) for o in r.objectives[:2]))
        front = np.array(sorted(set(r.front)), dtype=np.intp)
        marks = [c for c in candidates(r) if c.kind in ("knee", "best", "fallback")]
        members = np.array([c.member for c in marks] + front.tolist(), dtype=np.intp)
        pos = inset_positions(xy[members], box) if len(members) else np.zeros((0, 2))
        markers = tuple(InsetMarker(c.member, c.tag, c.kind, (float(pos[j, 0]), float(pos[j, 1])))
                        for j, c in enumerate(marks))
        if sv.shown is not None and sv.shown in front and all(c.member != sv.shown for c in marks):
            # A front member picked with the slider or the dropdown: red like a picked knee (it was a grey dot).
            j = len(marks) + int(np.flatnonzero(front == sv.shown)[0])
            markers += (InsetMarker(sv.shown, f"#{sv.shown}", "shown", (float(pos[j, 0]), float(pos[j, 1]))),)
        self.inset.place(box, axes, frames.text_height)
        self.inset.show(markers, pos[len(marks):], sv.shown)

    def _fit_client(self, client: viser.ClientHandle) -> None:
        try:
            aspect = client.camera.aspect
        except (AssertionError, ZeroDivisionError):  # no camera report from this client yet
            aspect = DEFAULT_ASPECT
        pos = self.scene.fit_camera(client, aspect)
        if pos is not None:
            self._framed[client.client_id] = (aspect, np.asarray(pos, dtype=np.float64))

    def _forget_client(self, client: viser.ClientHandle) -> None:
        self._framed.pop(client.client_id, None)

    def _resized(self, client_id: int, cam: viser.CameraHandle) -> bool:
        """True when a page's canvas changed shape (a resized window) while its camera is still where the studio
        framed it: the views are framed again. A camera the designer moved stays where it is."""
        framed = self._framed.get(client_id)
        if framed is None:
            return False
        aspect, pos = framed
        here = np.asarray(cam.position, dtype=np.float64)
        moved = not np.allclose(here, pos, rtol=0.0, atol=1e-3 * max(1e-9, float(np.linalg.norm(pos))))
        # A report sent before the page applied its framing still shows the initial camera: not the designer's move.
        # (Taken for one, the canvas's final size went unframed: a tall design's top was cut after a reload.)
        early = np.allclose(here, self.server.initial_camera.position, atol=1e-4)
        return (not moved or early) and abs(cam.aspect / aspect - 1.0) > RESIZE

    def _on_connect(self, client: viser.ClientHandle) -> None:
        """Refit the views to this client's canvas once it shows the initial camera.

        The initial camera is framed for a typical aspect ratio; a client's first camera report
        at that pose (not yet moved by the user) gives its real aspect. Later, a resized window is framed
        again while the designer has not moved the camera.
        """
        fitted = threading.Event()
        self._loading[client.client_id] = time.monotonic()
        failing = self._save_error
        if failing is not None:  # saves are failing: a page opened since is told too (QA, session 37)
            self.notify(client, "Session not saved", unsaved_text(failing), color="yellow")
        with self._request_lock:
            if self._requested:  # the oldest page requested has connected (its own hold follows)
                self._requested.popleft()

        def framed() -> None:
            fitted.set()
            self._loading.pop(client.client_id, None)
            self._fit_client(client)
            later(self.notice_seconds, self._hide_viewer_notice, client)

        def on_camera(cam: viser.CameraHandle) -> None:
            if fitted.is_set():
                if self._resized(client.client_id, cam):
                    self._fit_client(client)
                return
            if np.allclose(cam.position, self.server.initial_camera.position, atol=1e-4):
                framed()
                # The page has drawn: now its charts (and with them plotly.js) can follow without holding it up.
                later(PLOTLY_AFTER, self._attach_charts, client)

        def unfitted() -> None:  # a page whose reports never showed the initial camera is framed all the same
            if not fitted.is_set() and client.client_id in self.server.get_clients():
                framed()

        client.camera.on_update(on_camera)
        later(PLOTLY_LATEST, self._attach_charts, client)  # a page that reports no camera
        later(FIT_LATEST, unfitted)

    def _hide_viewer_notice(self, client: viser.ClientHandle) -> None:
        """Close viser's "Software WebGL rendering detected" notice on this page: it never closes by itself and
        covers the scene's top-left corner (the joint labels and the design's name), while the studio already
        paces its frames to such a page (studio/pacer.py). Shown for ``notice_seconds`` after the page has drawn;
        a page on a GPU never gets it."""
        if client.client_id in self.server.get_clients():
            client._websock_connection.queue_message(_messages.RemoveNotificationMessage(uuid=VIEWER_NOTICE))
            client.flush()

    def _attach_charts(self, client: viser.ClientHandle) -> None:
        """Give a page that has drawn its plotly charts (studio/panels/_lazy.py); once per page."""
        if client.client_id not in self.server.get_clients():
            return
        for chart in (*self.pareto.charts(), self.studies.plot):
            chart.attach(client)

    def _tick(self, dt: float) -> None:
        held = self.held()  # playback time stands still too: the animation goes on from there after the run
        still = held or self._page_loading()  # (a page loading holds it quietly: ~1.5 s)
        pb = self.session.snapshot()[1] if still else self.session.advance(dt)
        view = self._shown
        self.scene.name_joints(not pb.playing)  # a no-op but on Play / Pause
        if view is None or not self.server.get_clients():  # nobody watching: keep time, skip the pushes
            return
        if self._study_dirty and time.monotonic() - self._last_push >= STUDY_PUSH_PERIOD:
            # GUI only: a page applies it on arrival, without drawing its scene (so no probe, which would)
            self._study_dirty = False
            self.refresh()
            view = self._shown or view
        if still:  # the readout says so while a stage runs (refresh), and the scene stays as it is
            return
        self.playback.tick(pb)
        if self.pacer.ready() and self.scene.draw(frame_index(pb.angle, view.n_samples)):
            self.pacer.probe()  # a page still drawing the last frame skips this one; time goes on

    def page_requested(self) -> None:
        """A browser asked for the studio's page (clm-studio's gate calls this): hold the scene from now on, not
        only once its websocket connects (see REQUEST_HOLD_MAX). Any thread."""
        with self._request_lock:
            self._requested.append(time.monotonic())

    def _page_loading(self) -> bool:
        """True while a page is on its way: requested less than REQUEST_HOLD_MAX s ago and not connected yet (each
        connect answers the oldest request), or connected less than LOAD_HOLD_MAX s ago and not drawn yet (closed
        pages and late ones are forgotten)."""
        now, clients = time.monotonic(), self.server.get_clients()
        with self._request_lock:
            while self._requested and now - self._requested[0] > REQUEST_HOLD_MAX:
                self._requested.popleft()  # a page that never connected holds no longer
            if self._requested:
                return True
        for cid, since in list(self._loading.items()):
            if cid not in clients or now - since > LOAD_HOLD_MAX:
                self._loading.pop(cid, None)
        return bool(self._loading)

    def held(self) -> bool:
        """True while a stage runs: the scene (the linkage, and the candidate spheres) holds still until it ends;
        the Stages status, the Pareto chart and the trace go on. viser's client draws for 0.25 s after every
        scene change, and in software WebGL each of those frames keeps the page's main thread ~0.1 s (the WebGL
        frame and its read-back), so frames during a run kept such a page busy and its progress behind
        (docs/studio.md)."""
        return self.session.study.status.running

    def notify(
        self, client: viser.ClientHandle, title: str, body: str, color: Literal["red", "yellow", "green"] = "red"
    ) -> viser.NotificationHandle:
        """Tell one client something about its own action (red: refused; yellow: a warning); its handle."""
        return client.add_notification(title, body, color=color, auto_close_seconds=8.0, with_close_button=True)

    # Stages, picks, history -----------------------------------------------------------------

    def start_run(self) -> bool:
        """Run the stage selected in the Stages panel (ValueError naming the problem if it cannot start).

        Returns:
            False if the click was the second of a double click (nothing started).
        """
        session = self.session
        with session.lock:
            chain = self.chain()
            sv = self.study_view()
            if sv.next_stage is None:
                raise ValueError(f"no stage is available for {session.view.design.mechanism.title}")
            stage = find(chain, sv.next_stage)
            settings = session.study.settings_for(stage)
            view, from_pick = session.view, session.study.from_pick
            # The second click of a double click asks for the same run again; a click for another stage or
            # other settings, however soon, is a new request.
            request = (stage.name, settings, from_pick)
            if request == self._last_request and time.monotonic() - self._last_start < DOUBLE_CLICK:
                return False
            self._run_saved = -SAVE_PERIOD  # the run's first recorded generation is saved at once
            self.runner.start(lambda study: study.plan(stage, settings, view.design, view.target, from_pick, chain))
            self._last_start, self._last_request = time.monotonic(), request
        self.refresh()
        return True

    def _on_generation(self, _progress: object) -> None:
        now = time.monotonic()
        if now - self._run_saved >= SAVE_PERIOD:
            self._run_saved = now
            self.autosave()
        self._study_dirty = True  # the animator pushes it, at the pace the pages keep up with

    def _on_finish(self) -> None:
        """A run ended: animate the finished stage's pick, redraw everything, save."""
        session = self.session
        design, least = None, False
        with session.lock:
            st = session.study.status
            r = session.study.result(st.stage)
            if r is not None and r.pop > 0 and st.ok:
                i = session.study.shown_member(st.stage)
                if i is not None:
                    session.study.shown[st.stage or ""] = i
                    design = r.pick(i)
                    least = not r.feasible.any()
        if design is not None:
            what = "least violating member" if least else "pick"  # rehearsal 4: a failed stage replaced the design
            try:
                session.set_design(design, cause=f"{st.stage}'s {what}")  # it read "Undo 15 parameters"
            except ValueError:
                pass  # a member outside the parameters' hard limits stays listed but is not loaded
        self.refresh()
        self.autosave()

    def pick(self, stage: str, member: int, client: viser.ClientHandle | None) -> None:
        """Show member ``member`` of ``stage``: it becomes the editor's design (animated at once)."""
        session = self.session
        try:
            with session.lock:
                if session.study.status.running:
                    raise ValueError("a stage is running; pick when it has finished")
                r = session.study.result(stage)
                if r is None:
                    raise ValueError(f"stage {stage!r} has no result to pick from")
                if not 0 <= member < r.pop:
                    raise ValueError(f"member {member} out of range (population {r.pop})")
                v = session.view
                # The same leg in either RTCLM mode: a member is shown in the mode on screen (set_design).
                if (session.study.viewing == stage and session.study.shown_member(stage) == member
                        and same_leg(v.design.mechanism, r.mechanism)
                        and np.array_equal(v.design.params[0], r.X[member])):
                    return  # already shown (a page echoing the dropdown): no Undo step, and Redo is not cleared
                session.set_design(r.pick(member))  # first: its Undo step keeps the member shown before
                session.study.show(stage, member)
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Not picked", str(exc))
            self.refresh()
            return
        self.refresh()

    def _on_inset_pick(self, member: int, client: viser.ClientHandle) -> None:
        with self.session.lock:
            stage = self.study_view().viewing
        if stage is not None:
            self.pick(stage, member, client)

    def use_for_next(self, stage: str, client: viser.ClientHandle | None) -> None:
        """Pass the shown member of ``stage`` on to the next stage (shown with its search box)."""
        session = self.session
        try:
            with session.lock:
                member = session.study.shown_member(stage)
                if member is None:
                    raise ValueError(f"{stage} has nothing to pass on")
                session.pass_on(stage, member, self.chain())
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Not passed on", str(exc))
        self.refresh()

    def _next_of(self, stage: str) -> tuple[Any, int, int, str, Any] | None:
        """``stage``'s result, index and shown member, the next stage's name and the problem it would run now (its
        settings, the editor's target); None if there is none or it cannot be built. Under the session lock."""
        session = self.session
        study = session.study
        k, r, i = study.index(stage), study.result(stage), study.shown_member(stage)
        names = study.stage_names()
        if k is None or r is None or i is None or k + 1 >= len(names):
            return None
        nxt = next((c for c in self.chain() if c.name == names[k + 1]), None)
        if nxt is None:
            return None
        try:
            spec = stage_spec(nxt, study.settings_for(nxt), session.view.target)
        except ValueError:
            return None
        return r, k, i, nxt.name, spec.problem

    def next_unmet(self, stage: str) -> tuple[str, list[str], bool]:
        """The stage after ``stage``, what its shown member misses of that stage's constraints, as that stage
        would run now (its settings, the editor's target), and whether another feasible member of ``stage`` meets
        them (the pick could have: worth asking before it is passed on; else the next stage is there to find
        them, as rtclm2 finds the auxiliary mode rtclm1 never modelled); ("", [], False) if none or it cannot be
        built."""
        with self.session.lock:
            got = self._next_of(stage)
            if got is None:
                return "", [], False
            r, _, i, name, problem = got
            missed = unmet_by(r, i, problem.constraints, problem.labels)
            return name, missed, bool(missed) and bool(next_feasible(r, problem).any())

    def pick_limits(self, stage: str) -> list[str]:
        """The limits ``stage``'s automatic pick keeps to first (its chain's ``pick_where``, sized for the leg), in
        words (``f5 = I (mm/s) ≤ 1``), when they explain why its shown member misses the next stage's constraints:
        the member is within them, and no feasible member within them meets the next stage's (as it would run now);
        [] otherwise (no limits, a member the designer chose outside them, or one within them that could have)."""
        with self.session.lock:
            st = next((c for c in self.chain() if c.name == stage), None)
            got = self._next_of(stage)
            pipe = self.session.study.pipeline
            if st is None or not st.pick_where or got is None or pipe is None:
                return []
            r, k, i, _, problem = got
            where = tuple(c for c in sized_where(st.pick_where, pipe.stages[k].problem.scale) if c.metric in r.metrics)
            within = where_mask(r, where) & r.feasible
            if not where or not within[i] or (within & next_feasible(r, problem)).any():
                return []
            labels = result_labels(r)
            return [constraint_text(c, labels) for c in where]

    def view_stage(self, stage: str, client: viser.ClientHandle | None) -> None:
        """Show a stage of the lineage again (its front, candidates, and its shown member animated)."""
        session = self.session
        try:
            with session.lock:
                r = session.study.result(stage)
                if r is None:
                    raise ValueError(f"{stage} has no result")
                i = session.study.shown_member(stage)
                if i is not None:  # first: if the design may not change now, the stage in view does not either
                    session.set_design(r.pick(i), cause=f"showing {stage}")
                session.study.viewing = stage
                session.study.touch()
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Stage not shown", str(exc))
        self.refresh()

    def restore_branch(self, j: int, client: viser.ClientHandle | None) -> None:
        try:
            self.session.restore_branch(j)
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Branch not restored", str(exc))
            self.refresh()
            return
        # A branch is another design, often of another topology, framed as a topology switch frames it: a
        # Stephenson-I branch restored from Watt-I was drawn a quarter smaller until the page was reloaded (the
        # camera refits on its own only past half or double the framed size).
        self.refresh(fit_camera=True)

    def delete_branch(self, label: str, client: viser.ClientHandle | None) -> None:
        try:
            with self.session.lock:
                if self.session.study.status.running:
                    raise ValueError("a stage is running; delete branches when it has finished")
                self.session.study.delete_branch(label)
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Branch not deleted", str(exc))
        self.refresh()

    # Files -------------------------------------------------------------------------------

    def session_file(self) -> tuple[str, bytes]:
        data = json.dumps(self.session.to_dict(), separators=(",", ":")) + "\n"
        return f"clm-session-{time.strftime('%Y%m%d-%H%M%S')}.json", data.encode()

    def design_file(self) -> tuple[str, bytes]:
        view = self.session.view
        return f"{slug(view.preset or view.design.mechanism.name)}-design.json", design_json(view)

    def drawing_file(self, kind: str, plates: Plates | None = None) -> tuple[str, bytes]:
        """A drawing of the design at the pose on screen; the animation pauses there first, so that the next drawing
        (the DXF after the SVG) is of the same pose (QA, session 37: 96 and 25 degrees, a click apart)."""
        with self.session.lock:  # the design and the pose of one moment (another page may change them next)
            pb = self.session.set_playing(False) if self.session.playback.playing else None
            view, angle = self.session.view, self.session.playback.angle
        if pb is not None:
            self.playback.show(pb, self.held())
            self.autosave()
        return drawing_export(view, angle, kind, plates or Plates())

    def drawing_notes(self, plates: Plates | None = None) -> list[str]:
        """The shown design's parts: holes that overlap or leave a thin web (said after a drawing is sent)."""
        return drawing_warnings(self.session.view, self.session.playback.angle, plates or Plates())

    def trajectories_file(self) -> tuple[str, bytes]:
        view = self.session.view
        return f"{slug(view.preset or view.design.mechanism.name)}-trajectories.csv", trajectories_csv(view)

    def pareto_file(self) -> tuple[str, bytes]:
        sv = self.study_view()
        fig = pareto_figure(sv)
        if fig is None:
            raise ValueError("no stage result to chart yet; run a stage first")
        return f"pareto-{slug(sv.viewing or 'stage')}.html", figure_html(fig, f"CLM Studio: {sv.viewing}")

    def pareto_png_file(self) -> tuple[str, bytes]:
        """The chart in view (and its projection) as PNG, drawn on the server; ValueError if there is none or
        no browser can draw it."""
        sv = self.study_view()
        fig = pareto_figure(sv, self.pareto.axes())
        if fig is None:
            raise ValueError("no stage result to chart yet; run a stage first")
        return f"pareto-{slug(sv.viewing or 'stage')}.png", png(fig, keep=True)

    def scene_file(self) -> tuple[str, bytes]:
        view = self.session.view
        # Nothing can be picked in a recording: its inset is titled without "(click to pick)" while it is made.
        title = self.inset.title
        title.text = INSET_EXPORT_TITLE
        try:
            html = notice_closed(self.scene.record_html(view.target.period), self.notice_seconds)
        finally:
            title.text = INSET_TITLE
        return f"{slug(view.preset or view.design.mechanism.name)}-scene.html", html.encode()

    def load_session_bytes(self, name: str, content: bytes, client: viser.ClientHandle | None) -> bool:
        """Replace the session by an uploaded one; a malformed file is refused, naming the problem."""
        try:
            other = read_session_bytes(content)
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Session not loaded", f"{name or 'upload'}: {exc}. The current session is kept.")
            return False
        return self.replace_session(other, name, client)

    def replace_session(self, other: Session, name: str, client: viser.ClientHandle | None) -> bool:
        """Make a loaded session the current one; the current one is first saved beside the session file
        (``<name>.before-load.json``), if the studio keeps one. False (and said) if it cannot be replaced now."""
        kept = None
        if self.session_path is not None and self.session.holds_work():
            kept = self.session_path.with_name(self.session_path.stem + ".before-load.json")
            try:
                save_session(self.session, kept)
            except (ValueError, OSError) as exc:
                if client is not None:
                    self.notify(client, "Session not loaded", f"the current session could not be kept as {kept} "
                                f"({exc}); download it first. Nothing was changed.")
                return False
        try:
            self.session.restore(other)
        except ValueError as exc:
            if client is not None:
                self.notify(client, "Session not loaded", f"{name or 'upload'}: {exc}. The current session is kept.")
            return False
        self.refresh(fit_camera=True)
        if client is not None:  # viser's own "File uploaded successfully." said nothing of the session
            was = f" The previous session was saved as {kept}." if kept is not None else ""
            self.notify(client, "Session loaded", f"{name or 'upload'}: {self.session.summary()}.{was}",
                        color="green")
        return True

    def autosave(self) -> None:
        """Write the session file, if any (atomically: a crash never leaves half a file)."""
        if self.session_path is None:
            return
        with self._save_lock:
            try:
                save_session(self.session, self.session_path)
            except (ValueError, OSError) as exc:  # too large, disk full: said to every page, the work goes on
                message = str(exc) if isinstance(exc, ValueError) else f"cannot write {self.session_path} ({exc})"
                now = time.monotonic()
                # Said again when it changes and at most once a minute while it lasts (a whole run went unsaved
                # without a new word; QA, session 37); a page opened meanwhile is told as it connects.
                if message != self._save_error or now - self._save_said > SAVE_REMIND:
                    self._save_error, self._save_said = message, now
                    print(f"clm-studio: session not saved: {message}", file=sys.stderr)
                    for client in self.server.get_clients().values():
                        self.notify(client, "Session not saved", unsaved_text(message), color="yellow")
                return
            if self._save_error is not None:  # saving works again: said, or the warning stood for ever
                self._save_error = None
                print(f"clm-studio: session saved again to {self.session_path}", file=sys.stderr)
                for client in self.server.get_clients().values():
                    self.notify(client, "Session saved again", f"{self.session_path} holds the session again.",
                                color="green")

    def final_save(self) -> str | None:
        """The last save as the studio stops: None when the session file holds the session; else what happened to
        the work since the last save (kept in the user's cache if the file cannot take it). QA, session 37: after a
        disk filled up, Ctrl-C printed "CLM Studio stopped." and the edits and a run since were gone."""
        if self.session_path is None:
            return None
        self.autosave()
        if self._save_error is None:
            return None
        try:
            kept = rescue_session(self.session, self.session_path)
        except OSError as exc:
            return (f"the session could not be saved ({self._save_error}), nor kept in the cache ({exc}): the changes "
                    f"since {self.session_path}'s last save are lost")
        return (f"the session could not be saved ({self._save_error}); its latest state is in {kept} (load it with "
                f"clm-studio --session {kept}, or Load session in the page)")

    def close(self) -> None:
        """Stop a run, the animation, pending input checks and the server."""
        self.runner.stop()
        self.runner.join(10.0)
        self.animator.stop()
        self.mechanism.close()
        self.target.close()
        self.walking.close()
        self.stages.close()
        stop_png_browser()
        self.server.stop()

