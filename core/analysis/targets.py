"""Target curves in the design frame: the paper's compound cycloid (spec §3) and user curves from CSV.

A target is a closed curve sampled at ``n_samples`` points that are uniform in time (index i
against crank sample i) or, for a curve given without times, uniform in arc length.
"""

from __future__ import annotations

import csv
import io
import math
import os
import stat
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.kinematics.checks import MAX_ABS

F64 = NDArray[np.float64]

MAX_COORD = MAX_ABS  # mm: a target curve's coordinates, as a design file's values (one limit)
MIN_POINTS = 4
CLOSE_TOL = 3.0  # a curve is closed when its last-to-first gap is at most this many median steps


@dataclass(frozen=True)
class Target:
    """A closed target curve.

    Attributes:
        name: label for tables.
        points: ``(m, 2)`` the curve as given (mm), without a repeated closing point.
        times: ``(m,)`` times from 0 (s), or None when the curve has no time law.
        period: duration of one cycle (s); for a curve without times, the nominal 2 s.
        formula: exact sampler ``n -> (n, 2)`` of an analytic target (used by ``sample``), or None.
    """

    name: str
    points: F64
    times: F64 | None
    period: float
    formula: Callable[[int], F64] | None = field(default=None, compare=False)
    _samples: dict[int, F64] = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def has_time(self) -> bool:
        return self.times is not None

    def sample(self, n_samples: int) -> F64:
        """``(n_samples, 2)`` uniform in time from t = 0, or uniform in arc length from the first point.

        Read-only and kept per ``n_samples``: an optimizer evaluating one design at a time asks for the same
        samples several times per design.
        """
        n = int(n_samples)
        got = self._samples.get(n)
        if got is None:
            got = self.formula(n) if self.formula is not None else resample(self.points, n, self.times, self.period)
            got = np.array(got, dtype=np.float64)
            got.flags.writeable = False
            if len(self._samples) < 16:
                self._samples[n] = got
        return got


def compound_cycloid(n_samples: int, L: float = 300.0, H: float = 100.0) -> tuple[F64, F64]:
    """The compound-cycloid target (paper Eq. 19, spec §3) at N time-uniform samples.

    First half-period: the arch ``x = L (s - sin(2 pi s) / (2 pi))``, ``y = -H (1 - cos(2 pi s)) / 2``
    with s the normalised half-period time; second half-period: the straight return from (L, 0)
    to (0, 0) at constant speed. Sample i is at ``t = i T / N`` for any period T.

    Returns:
        ``(n_samples, 2)`` points (mm) and ``(n_samples, 2)`` derivatives d/dtheta (mm/rad),
        theta being the crank angle ``2 pi t / T`` (one-sided, forward, at the two junctions).
    """
    s2 = 2.0 * np.arange(n_samples) / n_samples  # half-periods elapsed
    arch = s2 < 1.0
    s = np.where(arch, s2, s2 - 1.0)
    w = 2.0 * np.pi * s
    x = np.where(arch, L * (s - np.sin(w) / (2.0 * np.pi)), L * (1.0 - s))
    y = np.where(arch, -H * (0.5 - 0.5 * np.cos(w)), 0.0)
    ds = 1.0 / np.pi  # ds/dtheta
    dx = np.where(arch, L * (1.0 - np.cos(w)) * ds, -L * ds)
    dy = np.where(arch, -H * np.pi * np.sin(w) * ds, 0.0)
    return np.stack([x, y], -1), np.stack([dx, dy], -1)


def cycloid_target(L: float = 300.0, H: float = 100.0, period: float = 2.0, n_dense: int = 3600) -> Target:
    """The compound cycloid as a Target: sampled exactly by its formula, with a dense copy as points."""
    pts, _ = compound_cycloid(n_dense, L, H)
    t = (np.arange(n_dense) * (period / n_dense)).astype(np.float64)

    def formula(n: int) -> F64:
        return compound_cycloid(n, L, H)[0]

    return Target(f"compound cycloid L={L:g} H={H:g} T={period:g}", pts, t, float(period), formula)


def _periodic_interp(u: F64, s: F64, values: F64, total: float) -> F64:
    """Values of a closed polyline with knots at s in [0, total) at parameters u (linear)."""
    s_ext = np.concatenate([s, [total]])
    v_ext = np.concatenate([values, values[:1]], 0)
    return np.stack([np.interp(u, s_ext, v_ext[:, k]) for k in range(values.shape[1])], -1)


def resample(points: F64, n_samples: int, times: F64 | None = None, period: float | None = None) -> F64:
    """Resample a closed curve to n points, uniform in time (when times are given) or in arc length.

    Args:
        points: ``(m, 2)`` closed curve without a repeated closing point (mm).
        n_samples: number of output samples.
        times: ``(m,)`` increasing times starting anywhere, or None.
        period: cycle duration (s), required with times.

    Returns:
        ``(n_samples, 2)`` starting at the first point.
    """
    pts = np.asarray(points, dtype=np.float64)
    if times is not None:
        t = (np.asarray(times, dtype=np.float64) - times[0]).astype(np.float64)
        total = float(period) if period is not None else float(t[-1] + np.median(np.diff(t)))
        return _periodic_interp((np.arange(n_samples) * (total / n_samples)).astype(np.float64), t, pts, total)
    seg = np.linalg.norm(np.roll(pts, -1, 0) - pts, axis=1)
    s: F64 = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    total = float(seg.sum())
    return _periodic_interp((np.arange(n_samples) * (total / n_samples)).astype(np.float64), s, pts, total)


def curve_from_rows(rows: list[list[str]], name: str = "curve") -> Target:
    """Validate CSV rows (``x,y`` or ``x,y,t``; an optional header, a first row without a number) into a
    closed Target.

    Raises:
        ValueError: one clear sentence for too few points, non-numeric or non-finite values, a
            wrong number of columns, times not increasing, or an open curve.
    """
    body = [r for r in rows if r and any(c.strip() for c in r)]
    if body and not any(_numeric(c) for c in body[0]):
        body = body[1:]  # a header: no cell of it is a number ("abc,1.5" is a bad data row, not a header)
    if not body:
        raise ValueError(f"{name}: no data rows (expected lines 'x,y' or 'x,y,t')")
    semi = next((i for i, r in enumerate(body) if len(r) > 1 and any(";" in c for c in r)), None)
    if semi is not None:  # '1,9;1,4': a spreadsheet's ';' columns with decimal commas, read as '9;1' (lab rehearsal)
        raise ValueError(f"{name}: data row {semi + 1} {','.join(body[semi]).strip()!r} has ';' between columns and "
                         "',' as the decimal point: save the CSV with ',' between columns and '.' as the decimal "
                         "point")
    ncol = len(body[0])
    if ncol not in (2, 3):
        hint = ""
        if ncol == 1 and any(sep in body[0][0] for sep in (";", "\t", " ")):  # 'x;y': a European spreadsheet
            hint = " (the columns must be separated by commas)"
        raise ValueError(f"{name}: expected 2 columns (x,y) or 3 (x,y,t), got {ncol}{hint}")
    data = np.empty((len(body), ncol))
    for i, r in enumerate(body):
        if len(r) != ncol:
            raise ValueError(f"{name}: data row {i + 1} has {len(r)} columns, expected {ncol}")
        for k, c in enumerate(r):
            try:
                data[i, k] = float(c)
            except ValueError:
                raise ValueError(f"{name}: data row {i + 1}: {c.strip()!r} is not a number") from None
    bad = ~np.isfinite(data).all(1)
    if bad.any():
        raise ValueError(f"{name}: data row {int(np.argmax(bad)) + 1} has a NaN or infinite value")
    # The design files' domain (core.formats.design): past it the geometry is floating-point noise, and 1e300 mm
    # overflowed into numpy warnings (rehearsal 8).
    huge = (np.abs(data[:, :2]) > MAX_COORD).any(1)
    if huge.any():
        raise ValueError(f"{name}: data row {int(np.argmax(huge)) + 1} has a coordinate beyond +-{MAX_COORD:g} mm")
    pts = data[:, :2]
    times = data[:, 2] if ncol == 3 else None
    if times is not None and np.any(np.diff(times) <= 0.0):
        raise ValueError(f"{name}: times (third column) must be strictly increasing")
    closed_by_repeat = len(pts) > 1 and np.allclose(pts[-1], pts[0], rtol=0.0, atol=1e-9 * (1.0 + np.abs(pts).max()))
    if closed_by_repeat:
        period = float(times[-1] - times[0]) if times is not None else 2.0
        pts, times = pts[:-1], (times[:-1] if times is not None else None)
    n = len(np.unique(pts, axis=0))
    if n < MIN_POINTS:
        # Distinct points, as it says: four rows of 0,0 read "got 3" (the closing repeat was taken off, not the
        # copies), and 0,0 / 1,0 / 0,0 / 1,0 was a target (QA and review, session 37).
        raise ValueError(f"{name}: a closed curve needs at least {MIN_POINTS} distinct points, got {n} in "
                         f"{len(data)} row{'s' * (len(data) != 1)}")
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    med = float(np.median(steps))
    if med <= 0.0:
        raise ValueError(f"{name}: the points do not move (median step 0)")
    if not closed_by_repeat:
        gap = float(np.linalg.norm(pts[-1] - pts[0]))
        if gap > CLOSE_TOL * med:
            raise ValueError(
                f"{name}: open curve: the last point is {gap:.3g} mm from the first (median step {med:.3g} mm); "
                "close it by repeating the first point or sampling the whole cycle"
            )
        period = float(times[-1] - times[0] + np.median(np.diff(times))) if times is not None else 2.0
    if times is not None and not 1.0 / MAX_COORD <= period <= MAX_COORD:  # evaluate()'s range of crank periods
        raise ValueError(f"{name}: its times span {period:g} s, where a crank period must be 1e-06 to 1e+06 s "
                         "(the third column is read in s)")
    if times is not None:
        times = times - times[0]
    return Target(name, pts, times, period)


def _numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


MAX_CURVE_FILE_BYTES = 10 * 2**20


def read_user_file(path: str | Path, max_bytes: int = MAX_CURVE_FILE_BYTES, what: str = "curve") -> str:
    """The text of a file a user named: a regular file (no FIFO, device or directory) of at most ``max_bytes``,
    checked before reading a byte; ValueError naming the file otherwise."""
    p = Path(path)
    try:
        if not stat.S_ISREG(os.stat(p).st_mode):
            raise ValueError(f"cannot read {what} {str(p)!r}: not a regular file")
        # No blocking on a FIFO swapped in since the stat; on Windows (no O_NONBLOCK) bytes as they are (O_BINARY)
        flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
        fd = os.open(p, flags)
        try:
            st = os.fstat(fd)  # the file opened, not the one stat'ed (it may have been swapped)
            if not stat.S_ISREG(st.st_mode):
                raise ValueError(f"cannot read {what} {str(p)!r}: not a regular file")
            if st.st_size > max_bytes:
                raise ValueError(f"cannot read {what} {str(p)!r}: {st.st_size / 2**20:.1f} MB is more than the "
                                 f"{max_bytes / 2**20:.0f} MB such a file may have")  # 'a design file file' (QA)
            with os.fdopen(os.dup(fd), "rb") as f:
                data = f.read(max_bytes + 1)
        finally:
            os.close(fd)
    except OSError as e:
        raise ValueError(f"cannot read {what} {str(p)!r}: {e.strerror}") from None
    if len(data) > max_bytes:
        raise ValueError(f"cannot read {what} {str(p)!r}: more than {max_bytes / 2**20:.0f} MB")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"cannot read {what} {str(p)!r}: not UTF-8 text") from None


SPAN_MM = (5.0, 5000.0)  # a target curve's width or height outside this is probably not in mm
PERIOD_S = (0.05, 60.0)  # a target's cycle (s) outside this is probably not in s


def scale_note(points: Any, period: float | None = None) -> str:
    """A word on a curve's size if it is far from a leg's (a file written in m or um is read as mm: 0.18 m became a
    0.18 mm target, optimized to a confident nonsense), and on its period (``period``: a curve with times) if it is
    far from a crank's (times in ms made T = 2000 s and I a thousandth of itself; rehearsal 8), else ""."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    span = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    notes = []
    if not SPAN_MM[0] <= span <= SPAN_MM[1]:
        size = f"{span:,.0f}" if 1.0 <= span < 1e9 else f"{span:.2g}"
        notes.append(f"it spans {size} mm, where a foot path spans tens to hundreds of mm: its numbers are read in "
                     "mm (values in m or µm need scaling)")
    if period is not None and not PERIOD_S[0] <= period <= PERIOD_S[1]:
        notes.append(f"its times make one cycle {period:g} s long, where a leg's crank turns once in "
                     f"{PERIOD_S[0]:g} to {PERIOD_S[1]:g} s: its times are read in s (times in ms need scaling)")
    return "; ".join(notes)


def path_note(points: Any, remedy: bool = True) -> str:
    """A word on a foot path, given in the leg frame, that would make a leg walk wrongly, else "".

    The spec's leg frame has the stance at the bottom, moving +x, and the swing above: the path runs
    counter-clockwise. Flagged: a path drawn clockwise (the foot pushes toward -x on the ground), and one whose
    flat part is at the top (the foot would stand on the swing's lowest point) — the span of x within the top
    tenth of the height more than twice that within the bottom tenth. ``remedy``: say how to turn the curve (a
    caller whose curve is not the user's to edit, a cycloid, says its own).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 3 or np.ptp(pts[:, 1]) <= 0.0 or np.ptp(pts[:, 0]) <= 0.0:
        return ""
    x, y = pts[:, 0], pts[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    band = 0.1 * float(np.ptp(y))
    bottom = float(np.ptp(x[y <= y.min() + band]))
    top = float(np.ptp(x[y >= y.max() - band]))
    up = top > 2.0 * bottom
    if up and area < 0.0:
        what, fix = ("its flat part is at the top and it runs clockwise in the leg frame: the foot would stand on the "
                     "swing's lowest point", "Flip it upside down (y -> -y)")
    elif up:
        what, fix = ("its flat part is at the top in the leg frame: the foot would stand on the swing's lowest point",
                     "Turn it half a turn (the paper's pantograph, output k = -1, does that)")
    elif area < 0.0:
        what, fix = ("it runs clockwise in the leg frame: the foot pushes toward -x on the ground, where the stance "
                     "moves +x", "Reverse the order of its points")
    else:
        return ""
    return f"{what}. {fix}" if remedy else what


def load_curve(path: str | Path) -> Target:
    """Read a closed curve from a CSV file (see ``curve_from_rows``); ValueError if unreadable."""
    p = Path(path)
    return curve_from_rows(list(csv.reader(io.StringIO(read_user_file(p)))), p.name)


def cycloid_params(spec: str) -> dict[str, float]:
    """``{L, H, T}`` of a ``cycloid[:L=300,H=100,T=2]`` value (defaults for those not given); ValueError if
    malformed."""
    kw = {"L": 300.0, "H": 100.0, "T": 2.0}
    if ":" in spec:
        given: set[str] = set()
        for item in spec.split(":", 1)[1].split(","):
            key, _, val = item.partition("=")
            if key.strip() not in kw or not _numeric(val):
                raise ValueError(f"bad cycloid parameter {item!r}; use cycloid:L=300,H=100,T=2")
            if key.strip() in given:
                raise ValueError(f"cycloid parameter {key.strip()} is given twice in {spec!r}")
            given.add(key.strip())
            kw[key.strip()] = float(val)
    if not all(math.isfinite(v) and v > 0 for v in kw.values()):
        raise ValueError("cycloid parameters L, H, T must be positive")
    if max(kw["L"], kw["H"]) > MAX_COORD or not 1.0 / MAX_COORD <= kw["T"] <= MAX_COORD:  # as a config's target
        raise ValueError(f"cycloid parameters L and H must be at most {MAX_COORD:g} mm and T between 1e-06 and "
                         f"{MAX_COORD:g} s")
    return kw


def parse_target(spec: str | None) -> Target:
    """A target from a command-line value: None or ``cycloid[:L=300,H=100,T=2]`` or a CSV path."""
    if spec is None or spec.split(":", 1)[0] == "cycloid":
        kw = cycloid_params(spec or "cycloid")
        return cycloid_target(kw["L"], kw["H"], kw["T"])
    return load_curve(spec)
