"""Session and export panel: download / load the session, export the design, its trajectories, the Pareto
chart and the animated scene.

Downloads go to the client that asked (``ClientHandle.send_file_download``). A malformed upload
gets a red notification naming the problem and changes nothing.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import viser

from core.formats.drawing import Plates
from studio.panels._inputs import NumberFields, NumberForm
from studio.session_file import read_session_bytes

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class FilesPanel:
    """Buttons for every file the studio reads or writes."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        self._parts_note: dict[int, viser.NotificationHandle] = {}  # each page's open warning about a drawing's parts
        self._parts_lock = threading.Lock()
        studio.server.on_client_disconnect(self._forget)
        gui = studio.server.gui
        self.folder = gui.add_folder("Session and export", order=order, expand_by_default=False)
        with self.folder:
            self.download = gui.add_button("Download session", icon=viser.Icon.DOWNLOAD,
                                           hint="the whole session as JSON: design, target, pipeline, branches")
            self.load = gui.add_upload_button("Load session or design", icon=viser.Icon.UPLOAD,
                                              mime_type="application/json",
                                              hint="a session JSON saved by the studio replaces the current session "
                                                   "(asks first when that holds work); a design JSON (clm presets "
                                                   "show, Design (JSON)) becomes the editor's design (Undo takes it "
                                                   "back)")
            self.design = gui.add_button("Design (JSON)", icon=viser.Icon.FILE_DOWNLOAD,
                                         hint="the current design; clm simulate --design reads it")
            self._numbers = NumberFields(studio)
            self.hole = self._numbers.add(
                "hole", "Pin hole Ø [mm]", self.studio.session.plates.hole,
                form=NumberForm(lo=0.0, lo_open=True, hi=100.0, unit="mm", decimals=2), apply=self._set_hole,
                current=lambda: self.studio.session.plates.hole,
                hint="the drawings' pivot holes (your pins'), saved with the session; the parts sheet's plates are "
                     "three holes wide (clm export --hole, --width)")
            self.dxf = gui.add_button("Drawing (DXF)", icon=viser.Icon.FILE_DOWNLOAD,
                                      hint="the design at the shown crank angle (the animation pauses there): one "
                                      "layer per link, pivot holes, dimensions in mm, and each link as a plate laid "
                                      "flat to cut")
            self.svg = gui.add_button("Drawing (SVG)", icon=viser.Icon.FILE_DOWNLOAD,
                                      hint="the design at the shown crank angle (the animation pauses there) and its "
                                      "foot path")
            self.csv = gui.add_button("Trajectories (CSV)", icon=viser.Icon.FILE_DOWNLOAD,
                                      hint="design-frame path, bench trajectory, stance, target per crank sample")
            self.pareto = gui.add_button("Pareto chart (HTML)", icon=viser.Icon.FILE_DOWNLOAD,
                                         hint="the chart as a self-contained page (PNG: camera icon on the chart)")
            self.pareto_png = gui.add_button("Pareto chart (PNG)", icon=viser.Icon.FILE_DOWNLOAD,
                                             hint="the chart drawn on the server (kaleido), 1000 x 800")
            self.scene = gui.add_button("Animated scene (HTML)", icon=viser.Icon.FILE_DOWNLOAD,
                                        hint="one crank revolution of the scene, self-contained (works offline)")
        self.download.on_click(self._send(self.studio.session_file))
        self.design.on_click(self._send(self.studio.design_file))
        self.dxf.on_click(self._send(lambda: self.studio.drawing_file("dxf", self.studio.session.plates),
                                     notes=lambda: self.studio.drawing_notes(self.studio.session.plates)))
        self.svg.on_click(self._send(lambda: self.studio.drawing_file("svg", self.studio.session.plates),
                                     notes=lambda: self.studio.drawing_notes(self.studio.session.plates)))
        self.csv.on_click(self._send(self.studio.trajectories_file))
        self.pareto.on_click(self._send(self.studio.pareto_file))
        self.pareto_png.on_click(self._send(self.studio.pareto_png_file, slow="kaleido draws the chart on the server"))
        self.scene.on_click(self._send(self.studio.scene_file))
        self.load.on_upload(self._on_load)

    def _set_hole(self, value: float) -> None:
        """The drawings' hole diameter (mm); ValueError (the field says why, the old value stays) if unusable. Kept
        with the session, and saved with it at once (a restart lost it: the review of session 30)."""
        self.studio.session.set_plates(Plates(float(value)))
        self.studio.autosave()

    def show(self, plates: Plates) -> None:
        """Show the session's pin holes (a loaded session's, a restored one's)."""
        self.hole.show(plates.hole)

    def _forget(self, client: viser.ClientHandle) -> None:
        with self._parts_lock:
            self._parts_note.pop(client.client_id, None)

    def _send(self, make: Any, slow: str | None = None, notes: Any = None) -> Any:
        """A button's handler: ``make()`` -> (name, bytes) sent to the page. ``slow``: what takes the time, said in a
        notification while it does (the PNG took 6-9 s with nothing on screen, so a presenter clicked again); a click
        while it is drawn is ignored. ``notes()``: warnings about the file sent, shown after it (a drawing's parts)."""
        busy: set[int] = set()

        def handler(event: viser.GuiEvent[Any]) -> None:
            client = event.client
            if client is None or client.client_id in busy:
                return
            note = None
            if slow is not None:
                busy.add(client.client_id)
                note = client.add_notification("Preparing the file", f"{slow}; a few seconds", loading=True,
                                               with_close_button=False)
            try:
                name, content = make()
            except ValueError as exc:
                self.studio.notify(client, "Nothing to export", str(exc))
                return
            finally:
                busy.discard(client.client_id)
                if note is not None:
                    note.remove()
            client.send_file_download(name, content, save_immediately=True)
            said = notes() if notes is not None else []
            if said:
                # One warning on the page at a time: the DXF's and then the SVG's stacked the same text twice
                # over the mechanism view (QA session 38).
                with self._parts_lock:  # two exports handled at once in viser's pool stacked theirs again
                    old = self._parts_note.pop(client.client_id, None)
                    if old is not None:
                        old.remove()
                    self._parts_note[client.client_id] = self.studio.notify(
                        client, "Check the parts before cutting", "; ".join(said), color="yellow")

        return handler

    def _on_load(self, event: viser.GuiEvent[Any]) -> None:
        """Load an uploaded session; one that would replace work asks first (it replaced six branches and a run
        without a word, and the autosave followed at once)."""
        client = event.client
        if client is None:
            return
        f = self.load.value
        name = f.name or "upload"
        if self._load_design(client, name, f.content):
            return
        try:
            other = read_session_bytes(f.content)
        except ValueError as exc:
            self.studio.notify(client, "Session not loaded", f"{name}: {exc}. The current session is kept.")
            return
        if not self.studio.session.holds_work():
            self.studio.replace_session(other, name, client)
            return
        kept = self.studio.session_path
        where = (f"It is first saved as {kept.with_name(kept.stem + '.before-load.json')}." if kept is not None
                 else "The studio keeps no session file: download the current session first to keep it.")
        ask_to_replace(client, f"Load {name}?",
                       f"It replaces the current session: **{self.studio.session.summary()}**.\n\n{where}\n\n"
                       f"{name} holds: {other.summary()}.",
                       on_load=lambda: self.studio.replace_session(other, name, client),
                       on_download=lambda: client.send_file_download(*self.studio.session_file(),
                                                                     save_immediately=True))


    def _load_design(self, client: viser.ClientHandle, name: str, content: bytes) -> bool:
        """A design file (``mechanism`` and ``params``, as ``clm presets show`` and Design (JSON) write it) becomes
        the editor's design; False for anything else (a session, or what the session reader refuses and names).
        Rehearsal 3: the README's loop (presets show > my.json, edit, simulate --design) dead-ended at the studio."""
        from core.formats.design import design_from_dict, unit_note
        from core.formats.session import MAX_SESSION_BYTES, parse_json
        from studio.state import assembly_reason

        if len(content) > MAX_SESSION_BYTES:
            return False
        try:
            data = parse_json(content)
        except ValueError:
            return False
        # "mechanism" without "format" is a design, whatever else is wrong with it: the design reader names a
        # misspelt "params" (lab rehearsal: it was refused as "not a studio session (format None ...)").
        if not (isinstance(data, dict) and "mechanism" in data and "format" not in data):
            return False
        try:
            design = design_from_dict(data)
            self.studio.session.set_design(design, by_hand=True, cause=f"design {name}", refit=True)
        except ValueError as exc:
            self.studio.notify(client, "Design not loaded", f"{name}: {exc}. The editor's design is kept.")
            return True
        self.studio.refresh()
        # Yellow with what is wrong: its units (lab rehearsal: a design in m or degrees loaded green, a 0.3 mm leg on
        # screen), then its assembly (QA, session 37: one that assembles nowhere loaded green, its views broken);
        # a file in degrees that no longer assembles says both, the units first (the likelier cause).
        view = self.studio.session.view
        units, reason = unit_note(design, view.solution.point[0]), assembly_reason(view)
        if units or reason:
            title = ("check its units" if units else "it does not assemble" if "does not assemble" in (reason or "")
                     else "check it")
            said = "; ".join(t for t in (units, reason) if t)
            self.studio.notify(client, f"Design loaded: {title}", f"{name}: {said}. It is the editor's design now; "
                               "Undo takes it back", color="yellow")
            return True
        self.studio.notify(client, "Design loaded", f"{name} is the editor's design now "
                           f"({design.mechanism.title}); Undo takes it back", color="green")
        return True


def ask_to_replace(client: viser.ClientHandle, title: str, text: str, on_load: Callable[[], object],
                   on_download: Callable[[], object]) -> None:
    """A modal on ``client``'s page: download the current session (the modal stays), load the new one, or cancel."""
    modal = client.gui.add_modal(title)
    with modal:
        client.gui.add_markdown(text)
        download = client.gui.add_button("Download the current session", icon=viser.Icon.DOWNLOAD)
        load = client.gui.add_button("Load it", color="red")
        cancel = client.gui.add_button("Cancel")

    def on_load_click(_: Any) -> None:
        modal.close()
        on_load()

    def on_download_click(_: Any) -> None:
        on_download()

    download.on_click(on_download_click)
    load.on_click(on_load_click)
    cancel.on_click(lambda _: modal.close())
