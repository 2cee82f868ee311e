"""What a panel may use of the studio: the session, the viser server and the studio's actions.

Panels depend on this protocol, not on ``studio.app`` (which builds them): no import circle, and a
panel can be driven by anything that offers these members (``studio.app.Studio`` does).
"""

from __future__ import annotations

from typing import Literal, Protocol

import viser

from studio.chains import ChainStage
from studio.runner import Runner
from studio.state import Session


class StudioContext(Protocol):
    session: Session
    server: viser.ViserServer
    runner: Runner

    def chain(self) -> tuple[ChainStage, ...]: ...

    def refresh(self, fit_camera: bool = False) -> None: ...

    def notify(self, client: viser.ClientHandle, title: str, body: str,
               color: Literal["red", "yellow", "green"] = "red") -> None: ...

    def start_run(self) -> bool: ...

    def pick(self, stage: str, member: int, client: viser.ClientHandle | None) -> None: ...

    def use_for_next(self, stage: str, client: viser.ClientHandle | None) -> None: ...

    def view_stage(self, stage: str, client: viser.ClientHandle | None) -> None: ...

    def restore_branch(self, j: int, client: viser.ClientHandle | None) -> None: ...

    def session_file(self) -> tuple[str, bytes]: ...

    def design_file(self) -> tuple[str, bytes]: ...

    def drawing_file(self, kind: str) -> tuple[str, bytes]: ...

    def trajectories_file(self) -> tuple[str, bytes]: ...

    def pareto_file(self) -> tuple[str, bytes]: ...

    def scene_file(self) -> tuple[str, bytes]: ...

    def load_session_bytes(self, name: str, content: bytes, client: viser.ClientHandle | None) -> bool: ...

    def autosave(self) -> None: ...
