"""A named design: the unit the preset registry (``core.kinematics.presets``) is made of."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.kinematics.design import Design
from core.kinematics.model import IDENTITY, Mechanism, OutputStage

# The paper's Stephenson presets map the design frame to the leg frame by this pantograph (spec §2).
PAPER_PANTOGRAPH = OutputStage(k=-1.0, ox=150.0, oy=0.0)


@dataclass(frozen=True)
class Preset:
    name: str
    mechanism: Mechanism
    values: tuple[float, ...]
    output: OutputStage = field(default=IDENTITY)
    source: str = ""
    case: int | None = None  # the RTCLM case (paper §4.2, 1-5) whose h6/h4 targets the design was made for

    def design(self) -> Design:
        return Design(self.mechanism, np.array([self.values]), self.output)
