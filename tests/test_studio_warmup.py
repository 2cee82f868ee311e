"""``clm-studio --warm-up`` (studio.warmup): after it, no run of any algorithm on any stage of any topology
compiles or loads another numba kernel, so a fresh install's first Run starts at once."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from core.kinematics.kernel_cache import is_warm, mark_warm, warm_mark
from core.kinematics.presets import PRESETS, get
from core.optimize.algorithms import ALGORITHMS
from studio.chains import chain_for
from studio.state import DEFAULT_PRESET

ROOT = Path(__file__).resolve().parents[1]

# In a fresh process (this one has compiled kernels for other tests): the warm-up through the CLI, then every
# algorithm on every stage of every topology at other sizes and seed, and the Q-network; any kernel that gains a
# signature after the warm-up is one it missed.
CHECK = """
import io, json, sys, contextlib
import numba
import numpy as np

def signatures():
    out = {}
    for name, mod in list(sys.modules.items()):
        if name.startswith(("core.", "studio.")):
            for key, value in list(vars(mod).items()):
                if isinstance(value, numba.core.registry.CPUDispatcher):
                    out[f"{name}.{key}"] = len(value.signatures)
    return out

from studio.serve import main
text = io.StringIO()
with contextlib.redirect_stdout(text):
    code = main(["--warm-up"])
before = signatures()

from core.optimize.algorithms import ALGORITHMS
from core.optimize.evolve.qnet import QNet
from core.optimize.pipeline import Pipeline
from studio.chains import RunSettings, chain_for, stage_spec
from studio.state import Session

from studio.warmup import first_presets
session = Session.default()
for preset in first_presets():
    view = session.load_preset(preset)
    for name in ALGORITHMS:
        for stage in chain_for(view.design.mechanism):
            spec = stage_spec(stage, RunSettings(stage.name, name, 20, 3, 7), view.target)
            run = Pipeline([spec], view.design).stage(0)
            try:
                run.setup()
            except ValueError:  # C-TAEA and AGE-MOEA(-II) refuse the RTCLM's single objective by name
                continue
            run.run()
from core.analysis.targets import compound_cycloid
from studio.target import Curve
view = session.load_preset("stephenson1/X3")
pts = compound_cycloid(40)[0] * 1.1  # an uploaded curve without times: compared at the best cyclic shift
target = view.target.with_curve(Curve("up.csv", tuple(map(tuple, pts.tolist())), None, 2.0))
for stage in chain_for(view.design.mechanism)[:2]:
    Pipeline([stage_spec(stage, RunSettings(stage.name, "nsga2", 20, 3, 7), target)], view.design).stage(0).run()
net = QNet(np.random.default_rng(5))
rows = np.random.default_rng(6).random((30, 4))
net.fit(rows, rows, 5)
net.predict(rows[:3])
after = signatures()
print(json.dumps({"code": code, "text": text.getvalue(),
                  "missed": sorted(k for k, v in after.items() if v > before.get(k, 0))}))
"""


def test_after_the_warm_up_no_stage_and_no_algorithm_compiles_a_kernel():
    r = subprocess.run([sys.executable, "-c", CHECK], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["code"] == 0
    assert out["missed"] == []
    lines = out["text"].splitlines()
    assert lines[0].startswith("CLM Studio: compiling") and lines[-1].startswith("CLM Studio: kernels ready")
    assert [line.split()[:2] for line in lines[1:1 + len(ALGORITHMS)]] == [[DEFAULT_PRESET, a] for a in ALGORITHMS]


def test_the_warm_up_runs_every_algorithm_on_the_opening_design_and_every_topology_s_stages():
    from studio.warmup import first_presets, warm_up

    presets = first_presets()
    mechanisms = [get(p).mechanism.name for p in presets]
    assert presets[0] == DEFAULT_PRESET and len(set(mechanisms)) == len(mechanisms)
    assert {get(p).mechanism.name for p in PRESETS} == set(mechanisms)  # every topology the studio offers
    said: list[str] = []
    mark = warm_mark()
    if mark is not None:
        mark.unlink(missing_ok=True)  # this warm-up, not an earlier one, must leave it
    done = warm_up(said.append)
    expected = [(DEFAULT_PRESET, a, s.name) for a in ALGORITHMS for s in chain_for(get(DEFAULT_PRESET).mechanism)]
    for p in presets[1:]:
        expected += [(p, "nsga2", s.name) for s in chain_for(get(p).mechanism)]
    expected += [(DEFAULT_PRESET, "nsga2", f"{s.name} (curve target)")
                 for s in chain_for(get(DEFAULT_PRESET).mechanism)[:2]]
    assert done == expected
    assert any(p.startswith("rtclm") for p, _, _ in done)  # the RTCLM's stages have kernels of their own
    assert mark is None or is_warm()  # the studio no longer says its first runs will compile


def test_the_studio_says_at_its_start_that_its_first_runs_will_compile_until_the_warm_up_ran(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A QA session's first CMOES run took 86 s, 80 of them compiling, and nothing at the start had said so.
    from studio.serve import cold_note

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # a fresh cache: nothing compiled
    note = cold_note()
    assert note is not None and "not compiled yet" in note and "clm-studio --warm-up" in note
    mark = warm_mark()
    assert mark is not None and mark.parent.parent == tmp_path
    mark_warm()
    assert mark.exists() and cold_note() is None
    mark.write_text("0.1")  # compiled by another numba: its kernels compile again
    assert cold_note() is not None
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/proc/no-such-cache")  # unwritable: the warm-up's mark is skipped
    mark_warm()
    assert cold_note() is not None
