"""The target the studio compares against: the compound cycloid of spec §3 (L, H, T) or a closed curve
uploaded as CSV.

The curves themselves come from ``core.analysis.targets``; this is the Target panel's small, validated,
JSON-ready set of settings. The optimization problems take their target as an option string
(``cycloid:L=..,H=..,T=..`` or a CSV path, ``core.analysis.targets.parse_target``): an uploaded curve is
written once to a content-addressed CSV file (:func:`curve_file`) that reproduces it exactly.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import io
import math
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.analysis.targets import (
    MAX_COORD,
    Target,
    compound_cycloid,
    curve_from_rows,
    cycloid_target,
    path_note,
    resample,
    scale_note,
)
from core.kinematics.model import OutputStage
from core.optimize.rtclm import H4_CASES, H6_TARGET

F64 = NDArray[np.float64]

# Where uploaded curves are written for the optimization problems (content-addressed, shared).
# In the user's own cache folder, not the shared temporary one: a session resolves stage curves only here.
CURVE_DIR = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "clm-studio" / "targets"
MAX_CURVE_BYTES = 2_000_000
MAX_CURVE_POINTS = 100_000  # a curve read from a session (an upload is bounded by its bytes)
STORED_CURVE = re.compile(r"target-[0-9a-f]{20}\.csv")  # a curve's file in the store: named by its content




@dataclass(frozen=True)
class Curve:
    """A closed target curve from a CSV upload (design frame).

    Attributes:
        name: file name it came from.
        points: ``(m, 2)`` distinct points (mm), without a repeated closing point.
        times: ``(m,)`` times from 0 (s), or None (then compared at the best cyclic shift).
        period: one cycle (s); 2 s for a curve without times.
    """

    name: str
    points: tuple[tuple[float, float], ...]
    times: tuple[float, ...] | None
    period: float

    def scale_note(self) -> str:
        """A word on the curve's size if it is far from a leg's (a file written in m or um is read as mm: 300 m
        across drew nothing at all, 0.3 mm a dot), else "" (``core.analysis.targets.scale_note``)."""
        return scale_note(self.points, self.period if self.times is not None else None)

    def path_note(self, output: OutputStage) -> str:
        """A word on the curve if, mapped to the leg frame by ``output``, it would make a leg walk wrongly (drawn
        clockwise, or with its flat part at the top), else "" (``core.analysis.targets.path_note``)."""
        return path_note(output.apply(np.asarray(self.points, dtype=np.float64)))

    @staticmethod
    def from_target(t: Target) -> Curve:
        pts = tuple((float(x), float(y)) for x, y in np.asarray(t.points))
        times = None if t.times is None else tuple(float(v) for v in np.asarray(t.times))
        return Curve(t.name, pts, times, float(t.period))

    @staticmethod
    def from_csv(content: bytes, name: str, leg: OutputStage | None = None) -> Curve:
        """Parse an uploaded CSV (``x,y`` or ``x,y,t`` rows, optional header); ValueError naming the problem.

        With ``leg``, the file is a foot path in the leg frame (as the bench view draws it: stance at the
        bottom, swing above) and is mapped to the design frame by the inverse of that output stage."""
        if len(content) > MAX_CURVE_BYTES:
            raise ValueError(f"{name}: {len(content)} bytes is too large for a target curve "
                             f"(at most {MAX_CURVE_BYTES // 1000} kB)")
        try:
            text = content.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise ValueError(f"{name}: not a text file (expected CSV rows 'x,y' or 'x,y,t')") from None
        curve = Curve.from_target(curve_from_rows(list(csv.reader(io.StringIO(text))), name))
        if leg is None:
            return curve
        pts = leg.invert(np.array(curve.points, dtype=np.float64))
        return replace(curve, points=tuple((float(x), float(y)) for x, y in pts))

    def target(self) -> Target:
        pts = np.array(self.points, dtype=np.float64)
        times = None if self.times is None else np.array(self.times, dtype=np.float64)
        return Target(self.name, pts, times, self.period)

    def csv_text(self) -> str:
        """CSV that ``core.analysis.targets`` reads back to exactly this curve (closed by repeating the first row)."""
        rows = [(*p, *(() if self.times is None else (self.times[i],))) for i, p in enumerate(self.points)]
        first = (*self.points[0], *(() if self.times is None else (self.times[0] + self.period,)))
        head = "x,y" if self.times is None else "x,y,t"
        return head + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in [*rows, first])

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "points": [list(p) for p in self.points],
                "times": None if self.times is None else list(self.times), "period": self.period}

    @staticmethod
    def from_dict(data: object) -> Curve:
        """A curve saved by :meth:`to_dict`, validated like an upload."""
        if not isinstance(data, dict) or "points" not in data:
            raise ValueError(f"target curve must be an object with points, got {data!r:.80}")
        name = str(data.get("name", "curve"))
        pts, times = data["points"], data.get("times")
        if not isinstance(pts, list) or (times is not None and (not isinstance(times, list) or len(times) != len(pts))):
            raise ValueError("target curve: points must be a list of [x, y] and times null or one per point")
        if len(pts) > MAX_CURVE_POINTS:
            raise ValueError(f"target curve {name}: {len(pts)} points is too many (at most {MAX_CURVE_POINTS})")
        period = data.get("period", 2.0)
        rows = [[str(v) for v in (*p, *(() if times is None else (times[i],)))] for i, p in enumerate(pts)]
        if pts:
            rows.append([str(v) for v in (*pts[0], *(() if times is None else (times[0] + period,)))])
        return Curve.from_target(curve_from_rows(rows, name))


@dataclass(frozen=True)
class TargetSpec:
    """The target: the compound cycloid with step length L (mm), height H (mm), period T (s), or
    an uploaded ``curve`` (then ``period`` is the curve's); and the RTCLM's heights, ``h6`` of the primary
    mode and ``h4`` of the auxiliary mode (mm, paper §4.2; its stages' ``h6_target`` and ``h4_target``)."""

    length: float = 300.0
    height: float = 100.0
    period: float = 2.0
    curve: Curve | None = None
    origin: str = ""  # where it came from, for the Target panel ("the paper's", "scaled to the jansen path")
    h6: float = H6_TARGET
    h4: float = H4_CASES[1]

    def __post_init__(self) -> None:
        for name, unit in (("length", "mm"), ("height", "mm"), ("period", "s"), ("h6", "mm"), ("h4", "mm")):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0.0:
                raise ValueError(f"target {name} must be a positive number ({unit}), got {v!r}")
            # The analysis' domain, as a config's target and a CSV curve (review of session 31: 1e300 mm was taken).
            low = 1.0 / MAX_COORD if name == "period" else 0.0
            if not low <= v <= MAX_COORD:
                raise ValueError(f"target {name} must be {'between 1e-06 and' if low else 'at most'} {MAX_COORD:g} "
                                 f"{unit}, got {v!r}")

    @property
    def is_curve(self) -> bool:
        return self.curve is not None

    @property
    def has_time(self) -> bool:
        """False for a curve given without times (compared at the best cyclic shift)."""
        return self.curve is None or self.curve.times is not None

    def label(self) -> str:
        why = f" ({self.origin})" if self.origin and self.origin != "uploaded" else ""
        if self.curve is not None:
            return f"curve {self.curve.name} ({len(self.curve.points)} points, T = {self.period:g} s){why}"
        return f"compound cycloid L = {self.length:g} mm, H = {self.height:g} mm, T = {self.period:g} s{why}"

    def points(self, n_samples: int) -> F64:
        """``(n_samples, 2)`` target in the design frame (mm), uniform in time (or arc length) over one cycle."""
        if self.curve is not None:
            c = self.curve
            return resample(np.array(c.points), n_samples, None if c.times is None else np.array(c.times), c.period)
        return compound_cycloid(n_samples, float(self.length), float(self.height))[0]

    def target(self) -> Target:
        """The ``core.analysis.targets.Target`` for ``core.analysis.evaluate``."""
        if self.curve is not None:
            return self.curve.target()
        return cycloid_target(float(self.length), float(self.height), float(self.period))

    def option(self) -> str:
        """The target as the optimization problems' ``target`` option (``core.analysis.targets.parse_target``)."""
        if self.curve is not None:
            return str(curve_file(self.curve))
        return f"cycloid:L={float(self.length)!r},H={float(self.height)!r},T={float(self.period)!r}"

    def heights(self) -> str:
        """The RTCLM's targets in words."""
        return f"h6 = {self.h6:g} mm (primary mode), h4 = {self.h4:g} mm (auxiliary mode)"

    def changed_from(self, ran: TargetSpec, rtclm: bool) -> str:
        """What ``ran`` (a run's target) was, in words, if it differs from this one where a mechanism's stages look:
        the heights for an RTCLM, the curve for the others; "" if it does not."""
        if rtclm:
            return "" if (ran.h6, ran.h4) == (self.h6, self.h4) else ran.heights()
        return "" if replace(ran, h6=self.h6, h4=self.h4) == self else ran.label()

    def with_curve(self, curve: Curve | None) -> TargetSpec:
        period = curve.period if curve is not None else self.period
        return replace(self, period=period, curve=curve, origin="uploaded" if curve is not None else "")

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"L": float(self.length), "H": float(self.height), "T": float(self.period)}
        if self.curve is not None:
            out["curve"] = self.curve.to_dict()
        if self.origin:
            out["origin"] = self.origin
        if (self.h6, self.h4) != (H6_TARGET, H4_CASES[1]):  # only where they differ: a six-bar's file is unchanged
            out["h6"], out["h4"] = float(self.h6), float(self.h4)
        return out

    @staticmethod
    def from_dict(data: object, parsed: dict[int, Curve] | None = None) -> TargetSpec:
        """A target saved by :meth:`to_dict`; ValueError naming the problem. ``parsed``: curves already read
        from curve objects of this load, by the object's id (targets sharing one curve parse it once)."""
        if not isinstance(data, dict):
            raise ValueError(f"target must be an object {{L, H, T}}, got {data!r}")
        unknown = [k for k in data if k not in ("L", "H", "T", "curve", "origin", "h6", "h4")]
        if unknown:
            raise ValueError(f"unknown target key {unknown[0]!r}; expected L, H, T (and curve, origin, h6, h4)")
        origin = data.get("origin", "")
        if not isinstance(origin, str) or len(origin) > 200:
            raise ValueError("target origin must be a short text")
        d = TargetSpec()
        spec = TargetSpec(data.get("L", d.length), data.get("H", d.height), data.get("T", d.period), None, origin,
                          data.get("h6", d.h6), data.get("h4", d.h4))
        raw = data.get("curve")
        if raw is not None:
            curve = parsed.get(id(raw)) if parsed is not None else None
            if curve is None:
                curve = Curve.from_dict(raw)
                if parsed is not None:
                    parsed[id(raw)] = curve
            spec = replace(spec.with_curve(curve), origin=origin or "uploaded")
        return spec


def stored_curve(name: str) -> dict[str, Any] | None:
    """The curve the store holds under ``name`` (``target-<hash>.csv``), as :meth:`Curve.to_dict`; None if it
    holds none (or the name is not a store name)."""
    if not STORED_CURVE.fullmatch(name):
        return None
    return _read_stored(CURVE_DIR / name)


@functools.lru_cache(maxsize=64)
def _read_stored(path: Path) -> dict[str, Any] | None:  # a name fixes the content: cached for good
    try:
        return Curve.from_csv(path.read_bytes(), path.name).to_dict()
    except (OSError, ValueError):
        return None


def curve_path(curve: Curve, directory: Path | None = None) -> Path:
    """Where ``curve_file`` keeps the curve (named by its content); nothing is written."""
    text = curve.csv_text()
    folder = CURVE_DIR if directory is None else directory
    return folder / f"target-{hashlib.sha256(text.encode()).hexdigest()[:20]}.csv"


def curve_file(curve: Curve, directory: Path | None = None) -> Path:
    """The curve as a CSV file named by its content (written if missing); its path."""
    text = curve.csv_text()
    folder = CURVE_DIR if directory is None else directory
    path = curve_path(curve, directory)
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    return path
