"""Running one studio stage to its end in a test, as the studio's runner does."""

from __future__ import annotations

import threading
from typing import Any

from studio.chains import RunSettings, chain_for, find
from studio.runner import Runner
from studio.state import Session


def run_stage(session: Session, name: str, pop: int = 12, gens: int = 3, seed: int = 5) -> tuple[Any, ...]:
    """Run stage ``name`` from the editor's design with these settings; returns the mechanism's chain."""
    session.study.settings[name] = RunSettings(name, pop_size=pop, n_gen=gens, seed=seed)
    done = threading.Event()
    runner = Runner(session.lock, lambda: session.study, lambda p: None, done.set)
    chain = chain_for(session.view.design.mechanism)
    stage, view = find(chain, name), session.view
    runner.start(lambda st: st.plan(stage, st.settings_for(stage), view.design, view.target, False, chain))
    assert done.wait(60), "the run did not finish"
    runner.join(10)
    return chain
