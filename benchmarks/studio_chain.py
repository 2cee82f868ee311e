"""The studio's X0 -> X3 with its default stage settings, run through the Run button's path (``Studio.start_run``,
the runner thread, "Use for next stage"), headless: what a designer gets who runs the four stages and passes each
automatic pick on. Prints each seed's final pick against the paper's X3 and the compute time. ``--rtclm`` does
the same for the RTCLM's two subtasks from the studio's RTCLM start (case 1's targets, h6 50 mm, h4 220 mm).

    python benchmarks/studio_chain.py            # seeds 1-5
    python benchmarks/studio_chain.py --quick    # seed 1 of X0 -> X3 and of the RTCLM (CI)
    python benchmarks/studio_chain.py --rtclm    # the RTCLM, seeds 1-5
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.analysis.evaluate import evaluate  # noqa: E402
from core.kinematics import presets  # noqa: E402

STAGES = ("predesign", "subtask1", "subtask2", "subtask3")
SHOWN = ("mse", "h_s", "S", "I")


def chain(seed: int, stages: tuple[str, ...] = STAGES, preset: str | None = None,
          shown: tuple[str, ...] = SHOWN) -> tuple[dict[str, float], float]:
    """The stages in a fresh studio (on ``preset``, else its default) with every stage's default settings but the
    seed: the last pick's metrics and the runs' compute time (s)."""
    from studio.app import Studio
    from studio.chains import find
    from studio.state import Session

    s = Studio(Session.default() if preset is None else Session.default(preset), host="127.0.0.1", port=0)
    try:
        s.session.set_playing(False)
        spent = 0.0
        for stage in stages:
            with s.session.lock:
                st = s.session.study
                st.next_stage, st.from_pick = stage, stage != stages[0]
                st.settings[stage] = replace(st.settings_for(find(s.chain(), stage)), seed=seed)
            s.start_run()
            s.runner.join(600)
            r = s.session.study.result(stage)
            if r is None or r.picked is None:
                raise RuntimeError(f"seed {seed}: {stage} ended without a pick ({s.session.study.status.message})")
            spent += float(r.timings["total"])
            if stage != stages[-1]:
                s.use_for_next(stage, None)
        return {k: float(r.metrics[k][r.picked]) for k in shown}, spent
    finally:
        s.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="seed 1 only, of both chains (CI)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 1..N (default 5)")
    ap.add_argument("--rtclm", action="store_true", help="the RTCLM's two subtasks instead")
    args = ap.parse_args()
    seeds = range(1, 2 if args.quick else args.seeds + 1)
    if args.rtclm:
        rtclm(seeds)
        return
    x3 = evaluate(presets.get("stephenson1/X3").design()).record(0)
    print("Studio X0 -> X3, default settings, automatic picks passed on (the paper's X3 first)")
    print(f"{'seed':<6}" + "".join(f"{k:>9}" for k in SHOWN) + f"{'compute (s)':>13}  smaller than X3's")
    print(f"{'X3':<6}" + "".join(f"{x3[k]:9.3f}" for k in SHOWN))
    for seed in seeds:
        m, spent = chain(seed)
        better = [k for k in SHOWN if m[k] < x3[k]]
        print(f"{seed:<6}" + "".join(f"{m[k]:9.3f}" for k in SHOWN) + f"{spent:13.2f}  {', '.join(better) or '-'}")
    if args.quick:
        rtclm(seeds)


def rtclm(seeds: range) -> None:
    from core.optimize.rtclm import H4_CASES, H6_TARGET

    shown = ("h6", "h4", "dh6", "dh4")
    print(f"Studio RTCLM from rtclm/case1, default settings, targets h6 {H6_TARGET:g} mm, h4 {H4_CASES[1]:g} mm")
    print(f"{'seed':<6}" + "".join(f"{k:>9}" for k in shown) + f"{'compute (s)':>13}  both within 0.5 mm")
    for seed in seeds:
        m, spent = chain(seed, ("rtclm1", "rtclm2"), "rtclm/case1", shown)
        ok = m["dh6"] <= 0.5 and m["dh4"] <= 0.5
        print(f"{seed:<6}" + "".join(f"{m[k]:9.3f}" for k in shown) + f"{spent:13.2f}  {'yes' if ok else 'no'}")


if __name__ == "__main__":
    t = time.perf_counter()
    main()
    print(f"({time.perf_counter() - t:.0f} s)")
