"""``clm-studio --warm-up`` (studio.warmup): after it, no run of any algorithm on any stage of the opening design
compiles or loads another numba kernel, so a fresh install's first Run starts at once."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from core.optimize.algorithms import ALGORITHMS
from studio.chains import chain_for
from studio.state import Session

ROOT = Path(__file__).resolve().parents[1]

# In a fresh process (this one has compiled kernels for other tests): the warm-up through the CLI, then every
# algorithm on every stage at other sizes and seed, and the Q-network; any kernel that gains a signature after
# the warm-up is one it missed.
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

session = Session.default()
for name in ALGORITHMS:
    for stage in chain_for(session.view.design.mechanism):
        spec = stage_spec(stage, RunSettings(stage.name, name, 20, 3, 7), session.view.target)
        run = Pipeline([spec], session.view.design).stage(0)
        run.setup()
        while run.has_next():
            run.next()
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
    assert [line.split()[0] for line in lines[1:-1]] == list(ALGORITHMS)  # one line an algorithm, in order


def test_the_warm_up_runs_every_algorithm_on_every_stage():
    from studio.warmup import warm_up

    said: list[str] = []
    done = warm_up(said.append)
    chain = chain_for(Session.default().view.design.mechanism)
    assert done == [(a, s.name) for a in ALGORITHMS for s in chain]
    assert len(said) == len(ALGORITHMS)
