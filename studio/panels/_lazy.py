"""A plotly chart that each page gets only once it has drawn.

viser sends plotly.js (4.8 MB) with a GUI's first plotly element, and a page compiles it (~1.5 s on
software rendering) before it draws anything else of the same batch. A server-wide chart would put
plotly.js into every page's first batch; so the chart is one client-scoped element per page, nested in
the server's folder, created when :meth:`LazyPlotly.attach` says the page has drawn. The page is ready
first; plotly.js and the chart follow. The figure and visibility live here and go to every page.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import Any

import plotly.graph_objects as go
import viser


def write(handle: Any, name: str, value: Any) -> bool:
    """Set a property of a page's own element; False if the page left (viser removed its elements then,
    possibly while the server still listed it among its clients)."""
    try:
        setattr(handle, name, value)
    except RuntimeError:  # "Cannot assign to ... on a removed ..."
        return False
    return True


class LazyPlotly:
    """A chart at ``order`` in ``folder``: one ``client.gui.add_plotly`` per attached page."""

    def __init__(self, server: viser.ViserServer, folder: viser.GuiFolderHandle, order: float, aspect: float,
                 config: Mapping[str, Any]) -> None:
        self._server = server
        self._folder, self._order, self._aspect, self._config = folder, order, aspect, dict(config)
        self._figure: go.Figure | None = None
        self._visible = False
        self._handles: dict[int, viser.GuiPlotlyHandle] = {}
        self._lock = threading.RLock()
        server.on_client_disconnect(self._forget)

    def attach(self, client: viser.ClientHandle) -> None:
        """Give this page the chart (its current figure and visibility), once."""
        with self._lock:
            if client.client_id in self._handles:
                return
            with self._folder:
                try:
                    handle = client.gui.add_plotly(
                        self._figure if self._figure is not None else go.Figure(), aspect=self._aspect,
                        config=self._config, order=self._order, visible=self._visible)
                except RuntimeError:  # the page left while its chart was made (as write(): viser removed it)
                    return
            self._handles[client.client_id] = handle

    def attached(self, client: viser.ClientHandle) -> bool:
        return client.client_id in self._handles

    def _forget(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._handles.pop(client.client_id, None)

    def _write(self, name: str, value: Any) -> None:
        """Set a property on every connected page's chart; forget the charts of pages that left (a page may
        leave before its disconnect callback ran)."""
        clients = self._server.get_clients()
        for cid, h in list(self._handles.items()):
            if cid not in clients or not write(h, name, value):
                self._handles.pop(cid, None)

    @property
    def figure(self) -> go.Figure | None:
        return self._figure

    @figure.setter
    def figure(self, fig: go.Figure) -> None:
        with self._lock:
            self._figure = fig
            self._write("figure", fig)

    @property
    def aspect(self) -> float:
        return self._aspect

    @aspect.setter
    def aspect(self, value: float) -> None:
        """Height over width; sent only when it changes (a 3-D chart needs more height than a 2-D one)."""
        with self._lock:
            if value != self._aspect:
                self._aspect = float(value)
                self._write("aspect", self._aspect)

    @property
    def visible(self) -> bool:
        return self._visible

    @visible.setter
    def visible(self, value: bool) -> None:
        with self._lock:
            self._visible = bool(value)
            self._write("visible", self._visible)
