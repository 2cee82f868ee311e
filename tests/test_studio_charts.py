"""PNG charts drawn on the server (issue 13, item 14): `clm-charts` on a `clm design` run, and the studio's
download. Drawn by kaleido with Debian's chromium (CI installs it); skipped where no chromium exists."""

from __future__ import annotations

import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from core.cli import main as clm
from studio.charts import main as clm_charts

ROOT = Path(__file__).resolve().parents[1]
CONFIG = """
name = "charts"
mechanism = "stephenson1"
seed = 1
n_samples = 72
preset = "stephenson1/X2"
[algorithm]
name = "nsga2"
pop_size = 16
[[stages]]
name = "subtask2"
n_gen = 3
[[stages]]
name = "subtask3"
n_gen = 2
"""
needs_chromium = pytest.mark.skipif(shutil.which("chromium") is None and not Path("/usr/bin/chromium").exists(),
                                    reason="kaleido needs a chromium (CI installs Debian's)")


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


@needs_chromium
def test_clm_charts_draws_one_png_per_stage_next_to_the_csvs(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(CONFIG)
    out = tmp_path / "run"
    assert clm(["design", str(cfg), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert clm_charts([str(out)]) == 0
    written = sorted(p.name for p in out.glob("pareto-*.png"))
    assert written == ["pareto-0_subtask2.png", "pareto-1_subtask3.png"]
    assert png_size((out / written[0]).read_bytes()) == (1000, 800)
    assert capsys.readouterr().out.count("wrote ") == 2


@pytest.mark.parametrize("what", ["missing", "not-a-run"])
def test_clm_charts_refuses_what_is_not_a_run_in_one_line(tmp_path, what):
    d = tmp_path / "d"
    d.mkdir()
    if what == "not-a-run":
        (d / "result.json").write_text('{"format": "clm-session"}')
    p = subprocess.run([sys.executable, "-m", "studio.charts", str(d)], capture_output=True, text=True,
                       cwd=ROOT, timeout=60)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and p.stderr.startswith("clm-charts: error: ")
