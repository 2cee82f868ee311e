"""Compile the studio's numeric kernels before the first page: ``clm-studio --warm-up``.

numba compiles a kernel on its first call and caches the machine code on disk (``NUMBA_CACHE_DIR``). On a fresh
install the designer's first Run of the predesign waited ~20 s for that on a 2-core machine, and the first run of
each constrained MOEA a few seconds more, behind a progress bar that did not move. ``scripts/studio`` runs this
once per change of the sources, before the studio starts: every stage of the opening design with every algorithm
of the Algorithm dropdown, at a small population for two generations, the stages of the other topologies (the
RTCLM's problems have kernels of their own), the first two stages against an uploaded curve without times, and what
a short run may not reach:
DRLOS-EMCMO's DE action (drawn at random each generation) and its Q-network (built after generation 200). With
the cache warm it only loads it (a few seconds).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from core.analysis.targets import compound_cycloid
from core.kinematics import presets
from core.kinematics.kernel_cache import mark_warm
from core.optimize.algorithms import ALGORITHMS
from core.optimize.evolve.qnet import QNet
from core.optimize.evolve.variation import de_rand_1
from core.optimize.pipeline import Pipeline
from studio.chains import RunSettings, chain_for, stage_spec
from studio.state import DEFAULT_PRESET, Session, opening_preset
from studio.target import Curve

POP, GENERATIONS = 12, 2  # 12: the smallest population every algorithm accepts (CMOEMT needs 10)


def first_presets() -> list[str]:
    """The opening preset, then the preset each other mechanism opens on (a topology the studio can switch to)."""
    seen = {presets.get(DEFAULT_PRESET).mechanism.name: DEFAULT_PRESET}
    for name in presets.PRESETS:
        mech = presets.get(name).mechanism.name
        if mech not in seen:
            seen[mech] = opening_preset(mech)
    return list(seen.values())


def warm_up(say: Callable[[str], None] = print) -> list[tuple[str, str, str]]:
    """Run every stage of each mechanism's opening preset once, tiny: with every algorithm on the opening design,
    with NSGA-II on the others (their stages' problems; the algorithms' kernels do not depend on them). Returns
    the (preset, algorithm, stage) runs, in order."""
    session = Session.default()
    done: list[tuple[str, str, str]] = []
    for preset in first_presets():
        view = session.load_preset(preset)
        chain = chain_for(view.design.mechanism)
        for name in ALGORITHMS if preset == DEFAULT_PRESET else ("nsga2",):
            t = time.perf_counter()
            for stage in chain:
                spec = stage_spec(stage, RunSettings(stage.name, name, POP, GENERATIONS, 1), view.target)
                Pipeline([spec], view.design).stage(0).run()
                done.append((preset, name, stage.name))
            say(f"  {preset:<22} {name:<12} {time.perf_counter() - t:5.1f} s")
    # An uploaded curve without times is compared at the best cyclic shift, which has kernels of its own: the first
    # run after such an upload compiled them (~2 s, more on a busy machine).
    view = session.load_preset(DEFAULT_PRESET)
    pts = compound_cycloid(24)[0]
    target = view.target.with_curve(Curve("warm-up.csv", tuple(map(tuple, pts.tolist())), None, 2.0))
    t = time.perf_counter()
    for stage in chain_for(view.design.mechanism)[:2]:
        spec = stage_spec(stage, RunSettings(stage.name, "nsga2", POP, GENERATIONS, 1), target)
        Pipeline([spec], view.design).stage(0).run()
        done.append((DEFAULT_PRESET, "nsga2", f"{stage.name} (curve target)"))
    say(f"  {DEFAULT_PRESET:<22} {'curve target':<12} {time.perf_counter() - t:5.1f} s")
    rng = np.random.default_rng(0)
    rows = rng.random((8, 4))
    de_rand_1(rows, rows[::-1], rows[np.roll(np.arange(8), 1)], np.zeros(4), np.ones(4), rng)  # DRLOS-EMCMO's DE
    net = QNet(rng)  # action is a random choice a generation, its network is built after generation 200
    net.fit(rows, rows, 2)
    net.predict(rows[:2])
    mark_warm()  # the studio stops saying its first runs will compile (studio.serve.cold_note)
    return done
