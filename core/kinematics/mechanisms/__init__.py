"""Topologies: every mechanism the product knows, by registry name."""

from __future__ import annotations

from core.kinematics.mechanisms.fourbar import FOURBAR
from core.kinematics.mechanisms.rtclm import RTCLM_AUXILIARY, RTCLM_PRIMARY
from core.kinematics.mechanisms.stephenson import STEPHENSON1, STEPHENSON3
from core.kinematics.mechanisms.walkers import JANSEN, KLANN
from core.kinematics.mechanisms.watt import WATT1
from core.kinematics.model import Attach, Crank, Dyad, Ground, Mechanism, OutputStage

MECHANISMS: dict[str, Mechanism] = {
    m.name: m for m in (FOURBAR, WATT1, STEPHENSON1, STEPHENSON3, RTCLM_PRIMARY, RTCLM_AUXILIARY, JANSEN, KLANN)
}


def get(name: str) -> Mechanism:
    """The mechanism of that name; ValueError naming the known ones otherwise."""
    if name not in MECHANISMS:
        raise ValueError(f"unknown mechanism {name!r}; known: {', '.join(sorted(MECHANISMS))}")
    return MECHANISMS[name]


__all__ = ["MECHANISMS", "Attach", "Crank", "Dyad", "Ground", "Mechanism", "OutputStage", "get"]
