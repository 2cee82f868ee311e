"""A plotly chart created when it is first needed.

viser sends plotly.js (4.8 MB) to every page with the first plotly element; a page compiles it before
it draws what follows (~1.5 s on software rendering). Charts the opening page does not show are
therefore created on first use, and :meth:`LazyPlotly.ensure` lets the studio create one (hidden) once
a page has drawn, so plotly.js arrives after the page is ready and before the first run needs it.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import Any

import plotly.graph_objects as go
import viser


class LazyPlotly:
    """``gui.add_plotly(...)`` at ``order`` in ``folder``, deferred until a figure is set or :meth:`ensure`."""

    def __init__(self, gui: viser.GuiApi, folder: viser.GuiFolderHandle, order: float, aspect: float,
                 config: Mapping[str, Any]) -> None:
        self._gui, self._folder, self._order, self._aspect, self._config = gui, folder, order, aspect, config
        self._handle: viser.GuiPlotlyHandle | None = None
        self._visible = False
        self._lock = threading.Lock()

    @property
    def created(self) -> bool:
        return self._handle is not None

    def ensure(self) -> viser.GuiPlotlyHandle:
        """The chart, created hidden and empty if it was not yet."""
        with self._lock:
            if self._handle is None:
                with self._folder:
                    self._handle = self._gui.add_plotly(go.Figure(), aspect=self._aspect, config=dict(self._config),
                                                        order=self._order, visible=self._visible)
            return self._handle

    @property
    def figure(self) -> go.Figure | None:
        return None if self._handle is None else self._handle.figure

    @figure.setter
    def figure(self, fig: go.Figure) -> None:
        self.ensure().figure = fig

    @property
    def visible(self) -> bool:
        return self._visible

    @visible.setter
    def visible(self, value: bool) -> None:
        self._visible = bool(value)
        if self._handle is not None:
            self._handle.visible = self._visible
        elif self._visible:
            self.ensure()
