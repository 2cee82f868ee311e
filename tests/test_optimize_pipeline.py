"""A pipeline chains stages by picks: each stage searches the spec §6 box around the previous pick."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from core.kinematics.presets import get
from core.optimize import (
    SUBTASK_STEPS,
    AlgorithmSpec,
    Pipeline,
    Progress,
    StageSpec,
    make_problem,
    search_box,
    seeded,
)
from core.optimize.box import wrap

X0 = get("stephenson1/X0").design()
ALG = AlgorithmSpec("nsga2", 10)


def stages(n_gen: int = 2) -> list[StageSpec]:
    return seeded(
        [
            StageSpec(f"subtask{k}", make_problem("path_box", width=300.0 - 5 * k), s=s, d=d, algorithm=ALG,
                      n_gen=n_gen, pick="knee" if k != 2 else "best:f1")
            for k, (s, d) in SUBTASK_STEPS.items()
        ],
        seed=11,
    )


def test_one_run_seed_gives_each_stage_its_own() -> None:
    assert [s.seed for s in stages()] == [11, 12, 13]


def test_each_stage_searches_the_spec_box_around_the_previous_pick() -> None:
    pipe = Pipeline(stages(), X0)
    res = pipe.run()
    assert [r.status for r in res] == ["complete"] * 3
    assert res[0].box.center.tolist() == search_box(X0.mechanism, X0.params[0], 0.2, 20.0).center.tolist()
    for k in (1, 2):
        prev, cur = res[k - 1], res[k]
        assert cur.parent_pick == prev.picked
        expect = search_box(X0.mechanism, prev.X[prev.picked], *SUBTASK_STEPS[k + 1])
        np.testing.assert_array_equal(cur.box.lower, expect.lower)
        np.testing.assert_array_equal(cur.box.upper, expect.upper)
        assert cur.box.contains(cur.X).all()
    assert res[1].picked == res[1].shortlist.best[0]  # stage 2's rule is best:f1


def test_same_seed_gives_the_same_picks() -> None:
    a, b = Pipeline(stages(), X0).run(), Pipeline(stages(), X0).run()
    assert [r.picked for r in a] == [r.picked for r in b]
    for ra, rb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ra.X, rb.X)


def test_rerun_from_an_earlier_pick_replaces_the_later_stages() -> None:
    pipe = Pipeline(stages(), X0)
    first = pipe.run()
    other = max(i for i in range(first[0].pop) if i != first[0].picked and first[0].feasible[i])
    again = pipe.run(start=1, pick=other)
    assert again[0] is pipe.results[0] and again[0].picked == other
    assert again[1].parent_pick == other
    # the explicit pick is stage 1's start only: stage 1 keeps its own rule's pick (best:f1) for stage 2
    assert again[1].picked == again[1].shortlist.best[0] != other and again[2].parent_pick == again[1].picked
    np.testing.assert_array_equal(again[1].box.center, wrap_like(first[0].X[other], again[1].box))
    assert len(again) == 3


def wrap_like(x: np.ndarray, box: object) -> np.ndarray:
    out = np.array(x, dtype=float)
    per = box.periodic  # type: ignore[attr-defined]
    out[per] = wrap(out[per], box.bound_lo[per])  # type: ignore[attr-defined]
    return out


def test_stepping_by_hand_record_and_select() -> None:
    pipe = Pipeline(stages(), X0)
    st = pipe.stage(0)
    st.setup()
    while st.has_next():
        st.next()
    pipe.record(0, st.result())
    with pytest.raises(ValueError, match="no member picked|pick"):
        pipe.results[0].pick()  # type: ignore[union-attr]
    # Stage 1 from a hand-picked member; its box is known before it runs.
    i = pipe.results[0].shortlist.best[1]  # type: ignore[union-attr]
    box = pipe.box(1, pick=i)
    st1 = pipe.stage(1, pick=i)
    np.testing.assert_array_equal(st1.box.lower, box.lower)
    pipe.record(1, st1.run())
    assert pipe.results[0].picked == i  # type: ignore[union-attr]
    assert len(pipe.lineage) == 2
    # Changing stage 0's pick drops stage 1, which grew from the old pick.
    knee = pipe.results[0].choose("knee")  # type: ignore[union-attr]
    j = next(k for k in range(10) if pipe.results[0].feasible[k] and k not in (i, knee))  # type: ignore[union-attr]
    pipe.select(0, j)
    assert pipe.results[1] is None and len(pipe.lineage) == 1
    start, member = pipe.parent(1)  # the designer's pick, not stage 0's rule, starts stage 1
    assert member == j and np.array_equal(start.params[0], pipe.results[0].X[j])  # type: ignore[union-attr]
    with pytest.raises(ValueError, match="needs a result of stage 1"):
        pipe.stage(2)


def test_cancel_stops_the_pipeline_with_a_partial_result() -> None:
    cancel = threading.Event()
    seen = []

    def on_gen(p: Progress) -> None:
        seen.append((p.index, p.generation))
        if len(seen) == 4:  # stage 1, generation 1 of 3
            cancel.set()

    pipe = Pipeline(stages(n_gen=3), X0)
    res = pipe.run(callback=on_gen, cancel=cancel)
    assert seen == [(0, 1), (0, 2), (0, 3), (1, 1)]
    assert [r.status for r in res] == ["complete", "cancelled"]
    assert res[1].generation == 1 and res[1].pop == 10 and res[1].picked is None
    assert pipe.results[2] is None
    # Resume from stage 1 with the same pick of stage 0.
    done = pipe.run(start=1)
    assert [r.status for r in done] == ["complete"] * 3


def test_closing_the_iterator_records_the_partial_stage() -> None:
    pipe = Pipeline(stages(n_gen=3), X0)
    it = pipe.iterate()
    for _ in range(2):
        next(it)
    it.close()
    assert pipe.results[0] is not None and pipe.results[0].status == "cancelled"
    assert pipe.results[0].generation == 2


def test_a_stage_spec_can_be_replaced_before_launching() -> None:
    pipe = Pipeline(stages(), X0)
    pipe.run()
    new = StageSpec("subtask2", make_problem("bowl"), s=0.1, d=10.0, algorithm=AlgorithmSpec("nsga3", 10), n_gen=2)
    st = pipe.stage(1, spec=new)
    res = st.run()
    pipe.record(1, res)
    assert pipe.stages[1] is new and res.settings["algorithm"]["name"] == "nsga3"
    assert pipe.results[2] is None


def test_restore_picks_sets_every_pick_and_keeps_every_result() -> None:
    pipe = Pipeline(stages(), X0)
    res = pipe.run()
    old = [r.picked for r in res]
    other = next(i for i in range(res[0].pop) if i != old[0])
    pipe.restore_picks([other, old[1], None])
    assert [r.picked for r in pipe.results] == [other, old[1], None]  # type: ignore[union-attr]
    for a, b in zip(pipe.results, res, strict=True):
        np.testing.assert_array_equal(a.X, b.X)  # type: ignore[union-attr]
        assert a.status == b.status  # type: ignore[union-attr]
    with pytest.raises(ValueError, match="2 picks for 3 stages"):
        pipe.restore_picks([old[0], old[1]])
    with pytest.raises(ValueError, match="has no member 10"):
        pipe.restore_picks([10, None, None])
