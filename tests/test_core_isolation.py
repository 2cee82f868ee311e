"""`core` stays headless: importing it and every submodule pulls in neither viser, plotly nor studio."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Run in a fresh interpreter: this test process may already have imported the studio.
PROBE = """
import importlib, json, pkgutil, sys
import core
names = ["core"]
for m in pkgutil.walk_packages(core.__path__, "core."):
    if m.name.endswith("__main__"):
        continue  # running a package's __main__ is not importing it
    importlib.import_module(m.name)
    names.append(m.name)
print(json.dumps({"imported": names, "loaded": sorted(sys.modules)}))
"""


def test_core_and_every_submodule_import_without_viser_plotly_or_studio():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    on_disk = {
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for p in (ROOT / "core").rglob("*.py")
        if p.name != "__main__.py"
    }
    missed = sorted(on_disk - set(out["imported"]))
    # A folder without __init__.py is no regular package: walk_packages skips it and setuptools won't install it.
    assert missed == [], f"not importable as package modules: {missed}"
    forbidden = [m for m in out["loaded"] if m.split(".")[0] in {"viser", "plotly", "studio"}]
    assert forbidden == []
