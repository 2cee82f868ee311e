"""Study throughput on Dask: runs/min of a fixed small study with 1 and 2 workers, and the cost per task.

    python benchmarks/study.py            # 2 algorithms x subtask 2 x 8 seeds, budget 2000 (pop 100)
    python benchmarks/study.py --quick    # 2 x 1 x 4, budget 200 (CI, under a minute)

Prints per worker count: cluster start-up (s), wall time of the cells (s), runs/min, and the scaling
efficiency (runs/min with n workers / (n x runs/min with 1)); then the overhead per task: the wall
time a worker spends per task beyond the task's own run time, in the study, and for no-op tasks
(scheduler round trip). Targets (issue 12, this 2-core machine): efficiency >= 0.8, overhead <= 50 ms.
Not a test: wall-clock numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from core.formats.study import parse_study  # noqa: E402
from core.study.runner import client_for  # noqa: E402
from core.study.store import Store  # noqa: E402

CONFIG = ROOT / "assets" / "configs" / "stephenson1_cycloid.toml"


def study(n_seeds: int, budget: int, pop: int) -> dict:
    return {
        "name": "bench", "seeds": f"1..{n_seeds}",
        "algorithms": [{"name": "nsga2", "pop_size": pop}, {"name": "spea2", "pop_size": pop}],
        "cases": [{"name": "subtask2", "config": str(CONFIG), "stages": ["subtask2"], "start": "stephenson1/X1",
                   "budget": budget}],
    }


def noop(x: int) -> int:
    return x


def run(spec: dict, workers: int) -> dict[str, float]:
    from distributed import as_completed

    from core.study.cell import run_cell

    s = parse_study(spec)
    cells = [dict(c, threads=1) for c in s.cells()]
    t0 = time.perf_counter()
    with client_for(None, workers) as client:
        client.submit(noop, 0).result()  # every worker up
        client.run(lambda: __import__("core.study.cell"))  # imports paid before timing
        warm = client.map(run_cell, cells[:workers], pure=False, key=[f"warm-{i}" for i in range(workers)])
        client.gather(warm)  # numba kernels loaded in every worker
        start = time.perf_counter() - t0
        t1 = time.perf_counter()
        futures = client.map(run_cell, cells, pure=False, key=[f"cell-{c['key']}" for c in cells])
        with tempfile.TemporaryDirectory() as d:
            store = Store(d)
            task = 0.0
            for f in as_completed(futures):
                rec = f.result()
                task += rec["task_time"]
                if rec["status"] == "done":
                    store.save(rec)
            store.close()
        wall = time.perf_counter() - t1
        n = 400
        t2 = time.perf_counter()
        client.gather(client.map(noop, range(n), pure=False, key=[f"noop-{i}" for i in range(n)]))
        noop_cost = (time.perf_counter() - t2) / n
    return {"start": start, "wall": wall, "rate": 60.0 * len(cells) / wall, "n": len(cells),
            "overhead": (wall * workers - task) / len(cells), "noop": noop_cost}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a smaller study (CI)")
    args = ap.parse_args(argv)
    spec = study(4, 200, 20) if args.quick else study(8, 2000, 100)
    print(f"study: 2 algorithms x subtask 2 x {spec['seeds']} seeds, budget {spec['cases'][0]['budget']} evaluations")
    print(f"{'workers':>7} {'start (s)':>9} {'cells (s)':>9} {'runs/min':>9} {'efficiency':>10} "
          f"{'overhead/task (ms)':>18} {'no-op task (ms)':>15}")
    base = None
    for w in (1, 2):
        r = run(spec, w)
        base = base or r["rate"]
        eff = r["rate"] / (w * base)
        print(f"{w:>7} {r['start']:9.2f} {r['wall']:9.2f} {r['rate']:9.1f} {eff:10.2f} {1000 * r['overhead']:18.1f} "
              f"{1000 * r['noop']:15.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
