"""Files the studio hands out: the design (JSON), its trajectories (CSV), the Pareto chart (HTML).

Pure: each function returns bytes (or text). The self-contained scene HTML needs the server's
scene and lives in ``studio.scene``; the session JSON in ``studio.state``.
"""

from __future__ import annotations

import io
import json
import math

import numpy as np
import plotly.graph_objects as go

from core.formats.design import design_to_dict
from core.formats.drawing import Plates
from core.formats.files import slug
from core.kinematics import presets
from studio.state import DesignView

CSV_COLUMNS = ("sample", "theta_rad", "t_s", "x_design_mm", "y_design_mm", "x_leg_mm", "y_leg_mm", "stance",
               "x_target_mm", "y_target_mm", "x_target_leg_mm", "y_target_leg_mm")


def design_json(view: DesignView) -> bytes:
    """The current design in the design JSON format (``clm simulate --design`` reads it), with the fields of
    ``clm presets show``: a preset's name, the mechanism's title, and where the values come from (a preset's
    provenance, such as the paper row and the misprint read, is kept when the design was edited)."""
    mech = view.design.mechanism
    data = {"title": mech.title, **design_to_dict(view.design), "source": "clm-studio"}
    if view.preset is not None and view.preset in presets.PRESETS:
        p = presets.get(view.preset)
        if view.edited:
            data["source"] = f"clm-studio, edited from preset {p.name} ({p.source})"
        else:
            data = {"name": p.name, **data, "source": p.source}
    return (json.dumps(data, indent=2) + "\n").encode()


def _cell(v: float) -> str:
    """A value with every digit; empty for a missing one, and 0.0 for -0.0 (a spreadsheet showed "-0")."""
    return "" if not math.isfinite(v) else repr(float(v) + 0.0)


def trajectories_csv(view: DesignView) -> bytes:
    """One row per crank sample: crank angle, time, the tracked point in the design and leg frames,
    stance (1) or swing (0), and the target in both frames (mm, rad, s; empty cells where the
    mechanism does not assemble). A target without times is given at the best cyclic shift, the target point
    each sample is compared with by the MSE (rehearsal 4: rows paired with the file's first point read errors of
    ~100 mm beside an MSE of 2.2)."""
    from core.analysis.shape import mse_phase_optimal

    sol = view.solution
    n = view.n_samples
    stance = view.stance
    target_design, target_leg = view.target_design, view.target_leg
    if not view.target.has_time and np.isfinite(sol.point[0]).all():
        k = int(mse_phase_optimal(sol.point[:1], target_design)[1][0])
        target_design, target_leg = np.roll(target_design, -k, axis=0), np.roll(target_leg, -k, axis=0)
    out = io.StringIO()
    out.write(",".join(CSV_COLUMNS) + "\n")
    period = view.target.period
    for i in range(n):
        p, q = sol.point[0, i], sol.leg[0, i]
        s = "" if stance is None else str(int(stance[i]))
        cells = [str(i), repr(float(sol.theta[i])), repr(i * period / n), _cell(p[0]), _cell(p[1]), _cell(q[0]),
                 _cell(q[1]), s, _cell(target_design[i, 0]), _cell(target_design[i, 1]),
                 _cell(target_leg[i, 0]), _cell(target_leg[i, 1])]
        out.write(",".join(cells) + "\n")
    return out.getvalue().encode()


def figure_html(fig: go.Figure, title: str) -> bytes:
    """A plotly figure as one self-contained HTML page (plotly.js inlined: works offline, no CDN)."""
    return fig.to_html(include_plotlyjs=True, full_html=True,
                       config={"displaylogo": False, "showSendToCloud": False},
                       default_width="100%", default_height="90vh").replace(
        "<head>", f"<head><title>{title}</title>", 1).encode()


SOFTWARE_NOTICE = "Software WebGL rendering detected"  # viser's notice (its client's BrowserWarning.tsx)


def notice_closed(page: str, seconds: float, title: str = SOFTWARE_NOTICE) -> str:
    """A viser page (a recorded scene) that closes the viewer's notice called ``title`` ``seconds`` after it
    appears, as the studio does on its own pages: it never closes by itself and covered the recording's top-left
    (the design's name, the first view's title) on any machine without a GPU. A page on a GPU, which never shows
    it, stops looking after a minute."""
    script = ("<script>(function(){var seen=null,start=Date.now();var t=setInterval(function(){"
              "var n=Array.prototype.filter.call(document.querySelectorAll('.mantine-Notification-root'),"
              f"function(e){{return e.textContent.indexOf({json.dumps(title)})>=0;}});"
              "var now=Date.now();if(!n.length){if(seen===null&&now-start>60000){clearInterval(t);}return;}"
              "if(seen===null){seen=now;}"
              f"if(now-seen>={int(round(1000 * max(seconds, 0.0)))}){{n.forEach(function(e){{"
              "var b=e.querySelector('button');if(b){b.click();}});clearInterval(t);}"
              "},250);})();</script>")
    end = page.rfind("</body>")
    return page + script if end < 0 else page[:end] + script + page[end:]


def parse_trajectories_csv(data: bytes) -> dict[str, np.ndarray]:
    """Columns of :func:`trajectories_csv` output as float arrays (NaN for empty cells); for tests and tools."""
    lines = data.decode().strip().splitlines()
    head = lines[0].split(",")
    rows = [[float(c) if c else math.nan for c in line.split(",")] for line in lines[1:]]
    arr = np.array(rows, dtype=np.float64)
    return {h: arr[:, k] for k, h in enumerate(head)}


def drawing_export(view: DesignView, angle: float, kind: str, plates: Plates | None = None) -> tuple[str, bytes]:
    """The shown design at the shown crank angle as a fabrication drawing: ``dxf`` (one layer per link, pivot
    holes, dimensions, and the parts sheet) or ``svg``; ValueError if it does not assemble there (the panel says so)."""
    from core.formats.drawing import drawing, dxf, svg

    d = drawing(view.design, angle)
    deg = round(math.degrees(d.angle)) % 360  # the angle drawn, in the name too: two drawings of one design differ
    name = f"{slug(view.preset or view.design.mechanism.name)}-drawing-{deg}deg.{kind}"
    plates = plates or Plates()
    return name, (svg(d, plates=plates) if kind == "svg" else dxf(d, plates)).encode()


def drawing_warnings(view: DesignView, angle: float, plates: Plates | None = None) -> list[str]:
    """What the drawing's parts sheet warns about (holes that overlap or leave a thin web; ``clm export`` prints
    the same), [] when the design does not assemble there (the export says that)."""
    from core.formats.drawing import cutting_warnings, drawing

    try:
        said = cutting_warnings(drawing(view.design, angle), plates or Plates())
    except ValueError:
        return []
    return [f"{w.text} (Pin hole Ø above the Drawing buttons)" if w.overlap else w.text for w in said]
