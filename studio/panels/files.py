"""Session and export panel: download / load the session, export the design, its trajectories, the Pareto
chart and the animated scene.

Downloads go to the client that asked (``ClientHandle.send_file_download``). A malformed upload
gets a red notification naming the problem and changes nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import viser

if TYPE_CHECKING:
    from studio.context import StudioContext as Studio


class FilesPanel:
    """Buttons for every file the studio reads or writes."""

    def __init__(self, studio: Studio, order: float) -> None:
        self.studio = studio
        gui = studio.server.gui
        self.folder = gui.add_folder("Session and export", order=order, expand_by_default=False)
        with self.folder:
            self.download = gui.add_button("Download session", icon=viser.Icon.DOWNLOAD,
                                           hint="the whole session as JSON: design, target, pipeline, branches")
            self.load = gui.add_upload_button("Load session", icon=viser.Icon.UPLOAD, mime_type="application/json",
                                              hint="a session JSON saved by the studio (the current one is replaced)")
            self.design = gui.add_button("Design (JSON)", icon=viser.Icon.FILE_DOWNLOAD,
                                         hint="the current design; clm simulate --design reads it")
            self.dxf = gui.add_button("Drawing (DXF)", icon=viser.Icon.FILE_DOWNLOAD,
                                      hint="the design at the shown crank angle: one layer per link, pivot holes, "
                                      "dimensions in mm")
            self.svg = gui.add_button("Drawing (SVG)", icon=viser.Icon.FILE_DOWNLOAD,
                                      hint="the design at the shown crank angle and its foot path")
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
        self.dxf.on_click(self._send(lambda: self.studio.drawing_file("dxf")))
        self.svg.on_click(self._send(lambda: self.studio.drawing_file("svg")))
        self.csv.on_click(self._send(self.studio.trajectories_file))
        self.pareto.on_click(self._send(self.studio.pareto_file))
        self.pareto_png.on_click(self._send(self.studio.pareto_png_file, slow="kaleido draws the chart on the server"))
        self.scene.on_click(self._send(self.studio.scene_file))
        self.load.on_upload(self._on_load)

    def _send(self, make: Any, slow: str | None = None) -> Any:
        """A button's handler: ``make()`` -> (name, bytes) sent to the page. ``slow``: what takes the time, said in a
        notification while it does (the PNG took 6-9 s with nothing on screen, so a presenter clicked again); a click
        while it is drawn is ignored."""
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

        return handler

    def _on_load(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:
            return
        f = self.load.value
        self.studio.load_session_bytes(f.name, f.content, event.client)
