"""The Pareto chart builder, the candidate lists and the HTML tables, without a server."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from core.kinematics import presets
from core.optimize import decision
from core.optimize.box import search_box
from studio.candidates import candidates, front_order, history_rows
from studio.figures import NO_LABEL, compact_3d, make_pareto_figure
from studio.geometry import compose, inset_positions, layout
from studio.tables import box_html, history_html

X3 = presets.get("stephenson1/X3")


def population(n: int = 40, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 2-objective population: a convex front (f2 = (1 - sqrt(f1))^2), dominated, infeasible and undefined rows."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.0, 1.0, n)
    F = np.stack([u, (1.0 - np.sqrt(u)) ** 2], 1)
    F[n // 2 :] += rng.uniform(0.05, 0.5, (n - n // 2, 2))  # dominated
    cv = np.zeros(n)
    cv[:5] = rng.uniform(0.1, 2.0, 5)  # infeasible
    F[5] = np.inf  # undefined objectives
    cv[5] = 3.0
    return F, cv


def traces(fig) -> dict:
    return {t.name: t for t in fig.data}


def test_pareto_chart_tells_feasible_infeasible_front_and_knees_apart_with_unit_labels() -> None:
    F, cv = population()
    sl = decision.shortlist(F, cv)
    fig = make_pareto_figure(F, cv, objectives=("f1", "f2"), labels={"f1": "f1 = MSE (mm)", "f2": "f2 (mm^2)"},
                             front=sl.front, knees=sl.knees, best=sl.best, shown=sl.knees[0])
    t = traces(fig)
    drawable = np.isfinite(F).all(1)
    infeasible = set(np.flatnonzero(drawable & (cv > 0)))
    assert set(t["infeasible"].customdata) == infeasible
    assert set(t["Pareto front"].customdata) == set(sl.front)
    assert set(t["dominated"].customdata) == set(np.flatnonzero(drawable & (cv <= 0))) - set(sl.front)
    colours = {t[n].marker.color for n in ("infeasible", "dominated", "Pareto front")}
    assert len(colours) == 3  # front, dominated and infeasible in three colours
    # Tick labels drawn as they are: plotly's default measured each one after every redraw, forcing a layout of the
    # whole page (the worst of a run's first second on software rendering; session 35)
    assert fig.layout.xaxis.ticklabeloverflow == fig.layout.yaxis.ticklabeloverflow == "allow"
    assert 5 not in {i for tr in fig.data for i in tr.customdata}  # undefined members are not drawn
    assert list(t["knees"].customdata) == list(sl.knees)
    # K1 is the picked member: its label is on the ring around it (set off by the ring's size), not beside it.
    assert list(t["knees"].text) == [NO_LABEL] + [f"K{j + 1}" for j in range(1, len(sl.knees))]
    picked = t["picked"]
    assert list(picked.customdata) == [sl.knees[0]] and list(picked.text) == ["K1"]
    assert (picked.x[0], picked.y[0]) == tuple(F[sl.knees[0]])
    assert fig.layout.xaxis.title.text == "f1 = MSE (mm)" and fig.layout.yaxis.title.text == "f2 (mm^2)"
    for axis, k in ((fig.layout.xaxis, 0), (fig.layout.yaxis, 1)):
        feas = F[(cv <= 0) & drawable, k]
        assert axis.range[0] < feas.min() and axis.range[1] > feas.max()


def test_three_objectives_give_a_3d_chart_and_one_objective_plots_against_the_violation() -> None:
    rng = np.random.default_rng(1)
    F3 = rng.uniform(size=(12, 3))
    fig = make_pareto_figure(F3, np.zeros(12), objectives=("a", "b", "c"), labels={"c": "c (mm/s)"},
                             front=tuple(range(12)))
    assert {type(t).__name__ for t in fig.data} == {"Scatter3d"}
    assert fig.layout.scene.zaxis.title.text == "c (mm/s)"
    # In the side panel a 3-D chart's long axis titles printed over each other: its axes carry the name and unit
    # (the panel's caption spells each objective out).
    long = {"a": "a = MSE (mm)", "b": "b = width penalty (mm^2)", "c": "c = (y_min + H)^2 (mm^2)"}
    fig = make_pareto_figure(F3, np.zeros(12), objectives=("a", "b", "c"), labels=long, front=tuple(range(12)))
    s = fig.layout.scene
    assert (s.xaxis.title.text, s.yaxis.title.text, s.zaxis.title.text) == ("a (mm)", "b (mm^2)", "c (mm^2)")
    # The side panel's (~270 px) cut even those ("b (mm", "(mm)") and printed "best" texts over each other: there the
    # axes carry names alone, and the best members' texts are on hover; the knees keep theirs.
    fig = make_pareto_figure(F3, np.zeros(12), objectives=("a", "b", "c"), labels=long, front=tuple(range(12)),
                             knees=(0,), best=(1, 2, 3))
    side = compact_3d(fig)
    s = side.layout.scene
    assert (s.xaxis.title.text, s.yaxis.title.text, s.zaxis.title.text) == ("a", "b", "c")
    t = traces(side)
    assert t["best"].mode == "markers" and t["knees"].mode == "markers+text"
    assert all(h.startswith("best ") for h in t["best"].hovertext)
    flat = make_pareto_figure(rng.uniform(size=(5, 2)), np.zeros(5), objectives=("a", "b"), front=(0,))
    assert compact_3d(flat).layout.xaxis.title.text == "a"  # a 2-D chart as it was
    F1 = rng.uniform(size=(10, 1))
    cv = np.where(np.arange(10) < 3, 1.5, 0.0)
    fig = make_pareto_figure(F1, cv, objectives=("dh6",), labels={"dh6": "|h6 - h6_t| (mm)"}, front=(3,))
    t = traces(fig)
    assert list(t["infeasible"].y) == [1.5, 1.5, 1.5]
    assert fig.layout.yaxis.title.text == "violation<br>(0 = feasible)"  # a long vertical title: two lines
    lo, hi = fig.layout.yaxis.range
    assert -0.1 < lo < 0 < 1.5 <= hi  # from 0 up: the feasible members on the floor, the violations above
    done = make_pareto_figure(F1, np.zeros(10), objectives=("dh6",), front=(3,), knees=(3,))
    lo, hi = done.layout.yaxis.range  # every member feasible: their line mid-plot (QA, session 37: on the bottom
    assert lo == -hi < 0  # edge of an empty chart), under one tick, 0: no negative violations on the axis
    assert list(done.layout.yaxis.tickvals) == [0.0]


def test_the_passed_on_member_is_marked_when_another_is_picked() -> None:
    F, cv = population()
    sl = decision.shortlist(F, cv)
    fig = make_pareto_figure(F, cv, objectives=("f1", "f2"), front=sl.front, shown=sl.front[0], passed=sl.front[1])
    t = traces(fig)
    assert list(t["passed on"].customdata) == [sl.front[1]] and list(t["picked"].customdata) == [sl.front[0]]


class FakeResult:
    """What ``candidates`` reads of a StageResult."""

    def __init__(self, F: np.ndarray, cv: np.ndarray, X: np.ndarray | None = None) -> None:
        self.F, self.cv = F, cv
        self.X = np.arange(len(F), dtype=float)[:, None] if X is None else X  # distinct designs unless given
        self.objectives = tuple(f"f{k + 1}" for k in range(F.shape[1]))
        self.shortlist = decision.shortlist(F, cv)


def test_members_that_are_the_same_design_are_listed_once():
    F, cv = population(30, 3)
    sl = decision.shortlist(F, cv)
    X = np.arange(len(F), dtype=float)[:, None]
    twin = next(i for i in sl.front if i != sl.knees[0])
    X[twin] = X[sl.knees[0]]  # the knee and a front member are one design
    cands = candidates(FakeResult(F, cv, X))  # type: ignore[arg-type]
    assert sl.knees[0] in [c.member for c in cands] and twin not in [c.member for c in cands]


@settings(max_examples=30, deadline=None)
@given(st.integers(8, 60), st.integers(0, 10_000))
def test_candidates_list_knees_then_best_then_the_front_once_each(n: int, seed: int) -> None:
    F, cv = population(n, seed)
    r = FakeResult(F, cv)
    cands = candidates(r)  # type: ignore[arg-type]
    members = [c.member for c in cands]
    sl = r.shortlist
    assert len(members) == len(set(members))
    assert len({c.label for c in cands}) == len(cands)
    assert members[: len(sl.knees)] == list(sl.knees)
    assert set(members) == set(sl.knees) | set(sl.best) | set(sl.front)
    kinds = [c.kind for c in cands]
    assert kinds == sorted(kinds, key=["knee", "best", "front"].index)
    # the tags the chart and the Pick panel show: K1, K2, ... (1-based, as the inset labels them)
    assert [c.tag for c in cands[: len(sl.knees)]] == [f"K{j + 1}" for j in range(len(sl.knees))]
    assert all(c.label.startswith(f"{c.tag} · #{c.member} · ") for c in cands)
    order = front_order(r)  # type: ignore[arg-type]
    assert np.all(np.diff(F[list(order), 0]) >= 0)


def test_with_nothing_feasible_the_least_violation_member_is_the_only_candidate() -> None:
    F = np.array([[1.0, 2.0], [0.5, 0.5], [3.0, 1.0]])
    cv = np.array([2.0, 0.5, 1.0])
    cands = candidates(FakeResult(F, cv))  # type: ignore[arg-type]
    assert [(c.member, c.kind) for c in cands] == [(1, "fallback")]


def test_box_table_lists_each_parameter_with_its_bounds_and_centre() -> None:
    box = search_box(X3.mechanism, X3.values, 0.1, 10.0, fixed=("b",))
    html = box_html(box, {p.name: p.unit for p in X3.mechanism.params})
    for j, name in enumerate(box.names):
        lo, c = float(box.lower[j]), float(box.center[j])
        assert f'data-param="{name}" data-lower="{lo!r}" data-center="{c!r}"' in html
    assert html.count("data-fixed") == 1


def test_history_rows_cover_every_stage_run_or_not() -> None:
    rows = history_rows([None, None], {"subtask1": "Subtask 1"}, ["subtask1", "subtask2"], {})
    assert [(r.title, r.status) for r in rows] == [("Subtask 1", "not run"), ("subtask2", "not run")]
    html = history_html(rows)
    assert html.count("<tr data-stage=") == 2


@settings(max_examples=40, deadline=None)
@given(st.floats(50, 500), st.floats(20, 300), st.floats(100, 1500), st.floats(50, 300))
@example(200.0, 30.0, 500.0, 100.0)  # a short design view: the inset reaches below both top views
def test_walking_view_sits_below_and_the_inset_right_of_the_leg_view(dw: float, dh: float, ww: float,
                                                                      wh: float) -> None:
    lay = layout(np.array([[0.0, 0.0], [dw, dh]]), np.array([[0.0, 0.0], [300.0, 100.0]]))
    walk = np.array([-ww, 0.0, 0.0, wh])
    comp = compose(lay, walk)
    placed = walk + np.concatenate([comp.walk_offset, comp.walk_offset])
    assert placed[3] < lay.scene[1]  # below the top views
    # ... and 1.5 gaps below the inset too, which can reach lower (its side is 0.6 x a flat leg view's width)
    assert placed[3] <= min(lay.scene[1], comp.inset[1]) - 1.5 * 60.0 + 1e-9
    assert comp.inset[0] > lay.leg[2] + lay.leg_offset[0]  # right of the leg view
    assert np.isclose(comp.inset[2] - comp.inset[0], comp.inset[3] - comp.inset[1])
    for b in (lay.scene, placed, comp.inset):
        assert np.all(comp.bounds[:2] <= b[:2] + 1e-9) and np.all(comp.bounds[2:] >= b[2:] - 1e-9)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6)), min_size=1, max_size=20))
def test_inset_positions_stay_in_the_box_and_keep_the_order(points: list[tuple[float, float]]) -> None:
    v = np.array(points)
    box = np.array([10.0, 20.0, 110.0, 120.0])
    p = inset_positions(v, box)
    assert np.all(p >= box[:2] - 1e-9) and np.all(p <= box[2:] + 1e-9)
    for k in range(2):
        order = np.argsort(v[:, k], kind="stable")
        assert np.all(np.diff(p[order, k]) >= -1e-9)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_inset_positions_park_undefined_rows_in_the_corner(bad: float) -> None:
    p = inset_positions(np.array([[1.0, 2.0], [bad, 0.0], [3.0, 4.0]]), np.array([0.0, 0.0, 1.0, 1.0]))
    assert tuple(p[1]) == (0.0, 0.0)


def test_three_objectives_project_onto_any_two():
    rng = np.random.default_rng(4)
    F, cv = rng.random((30, 3)), np.zeros(30)
    sl = decision.shortlist(F, cv)
    full = make_pareto_figure(F, cv, objectives=("a", "b", "c"), front=sl.front)
    assert full.data[0].type == "scatter3d"
    side = make_pareto_figure(F, cv, objectives=("a", "b", "c"), front=sl.front, axes=(0, 2), knees=sl.knees)
    t = traces(side)
    assert t["Pareto front"].type == "scatter" and side.layout.xaxis.title.text == "a"
    assert side.layout.yaxis.title.text == "c"
    i = t["knees"].customdata[0]
    assert (t["knees"].x[0], t["knees"].y[0]) == (F[i, 0], F[i, 2])


def test_candidate_labels_on_a_crowded_front_never_cover_each_other_and_k1_always_has_one() -> None:
    # A front crowded into a corner of the chart by far dominated members (seen with MOEA/D-CMT's predesign): every
    # label "top center" printed K1..K5 and "best ..." over each other. Now each takes the first position clear of
    # the labels before it (K1 first); one that finds none is left to the hover, which names every candidate.
    from studio.figures import _label_box, place_labels
    from studio.spots import overlaps as _overlaps

    rng = np.random.default_rng(3)
    front = np.column_stack([0.012 + 0.004 * np.linspace(0, 1, 8), 6.0 - 2.0 * np.linspace(0, 1, 8) ** 0.5])
    far = np.column_stack([rng.uniform(0.02, 0.065, 60), rng.uniform(4.0, 35.0, 60)])
    F = np.vstack([front, far])
    cv = np.zeros(len(F))
    knees, best = (3, 4, 2, 5, 1), (0, 7)
    fig = make_pareto_figure(F, cv, objectives=("fd", "f1"), front=tuple(range(8)), knees=knees, best=best)
    t = traces(fig)
    ranges = (list(fig.layout.xaxis.range), list(fig.layout.yaxis.range))
    shown = []
    for name in ("knees", "best"):
        tr = t[name]
        assert [h.split(":")[0] for h in tr.hovertext] == ([f"K{j + 1}" for j in range(5)] if name.startswith("knee")
                                                          else ["best fd", "best f1"])
        for x, y, text, pos in zip(tr.x, tr.y, tr.text, tr.textposition, strict=True):
            if text != NO_LABEL:
                px = ((x - ranges[0][0]) / np.ptp(ranges[0]) * 240.0, (y - ranges[1][0]) / np.ptp(ranges[1]) * 190.0)
                shown.append((text, _label_box(*px, text, pos)))
    assert t["knees"].text[0] == "K1"
    # The front's own point under a diamond took the hover and read "member #3": it names the candidate too, and
    # every hover gives the objectives with their names.
    hover = dict(zip(t["Pareto front"].customdata, t["Pareto front"].hovertext, strict=True))
    assert hover[3] == "K1: member #3" and hover[0] == "best fd: member #0" and hover[6] == "member #6"
    assert t["Pareto front"].hovertemplate == "%{hovertext}<br>fd: %{x:.4g}<br>f1: %{y:.4g}<extra></extra>"
    # A ringed candidate's label moves onto its ring (set off by the ring's size), in the same place: beside its
    # own marker the red ring crossed the label's first letter ("pest f1").
    ringed = traces(make_pareto_figure(F, cv, objectives=("fd", "f1"), front=tuple(range(8)), knees=knees, best=best,
                                       shown=3, passed=0))
    k1 = list(t["knees"].customdata).index(3)
    assert ringed["knees"].text[k1] == NO_LABEL and ringed["best"].text[0] == NO_LABEL
    assert list(ringed["picked"].text) == ["K1"]
    assert ringed["picked"].textposition[0] == t["knees"].textposition[k1]
    assert list(ringed["passed on"].text) == ["best fd"]
    assert list(ringed["knees"].text)[k1 + 1:] == list(t["knees"].text)[k1 + 1:]
    assert len(shown) >= 3
    for a in range(len(shown)):
        for b in range(a + 1, len(shown)):
            assert not _overlaps(shown[a][1], shown[b][1]), (shown[a][0], shown[b][0])
    # Spread out, every label fits above its marker, as before.
    spread = np.column_stack([np.linspace(0, 1, 5), np.linspace(1, 0, 5)])
    assert place_labels(spread, ["K1", "K2", "K3", "K4", "K5"], ([-0.2, 1.2], [-0.2, 1.2])) == ["top center"] * 5
    # A label that would leave the plot area (over the title or the ticks) goes to the other side.
    assert place_labels(spread[:1], ["K1"], ([-0.1, 1.1], [-0.1, 1.1])) == ["bottom center"]


def test_a_front_crowded_by_far_dominated_members_fills_the_view() -> None:
    # The view frames the front and the candidates, with the rest within one span of them; members further off
    # are cut at the plot's edge (plotly shows them on zooming out), while the front and the candidates are drawn
    # whole even on the edge.
    rng = np.random.default_rng(5)
    front = np.column_stack([0.012 + 0.004 * np.linspace(0, 1, 8), 6.0 - 2.0 * np.linspace(0, 1, 8) ** 0.5])
    far = np.column_stack([rng.uniform(0.02, 0.065, 60), rng.uniform(4.0, 35.0, 60)])
    F = np.vstack([front, far])
    fig = make_pareto_figure(F, np.zeros(len(F)), objectives=("fd", "f1"), front=tuple(range(8)), knees=(3, 4),
                             best=(0, 7), shown=3)
    (x0, x1), (y0, y1) = fig.layout.xaxis.range, fig.layout.yaxis.range
    assert x0 < front[:, 0].min() and x1 > front[:, 0].max() and y0 < front[:, 1].min() and y1 > front[:, 1].max()
    span = np.ptp(front, axis=0)
    assert x1 <= front[:, 0].max() + 1.2 * span[0] and y1 <= front[:, 1].max() + 1.2 * span[1]
    assert (far[:, 1] > y1).sum() > 40  # most of the far members are off the view ...
    t = traces(fig)
    assert t["dominated"].cliponaxis and t["infeasible"].cliponaxis is not False  # ... and cut there
    assert not any(t[n].cliponaxis for n in ("Pareto front", "knees", "best", "picked"))
    # Too few such members: the feasible ones are framed, as they were.
    one = make_pareto_figure(F, np.zeros(len(F)), objectives=("fd", "f1"), front=(0,))
    assert one.layout.yaxis.range[1] > far[:, 1].max()


def test_the_candidate_dropdown_lists_at_most_60_front_members_and_always_the_shown_one() -> None:
    # 227 entries (pop 400) took the dropdown 0.9 s to open on software rendering; the slider reaches every member.
    from studio.candidates import Candidate
    from studio.panels.pick import FRONT_LISTED, listed

    knees = tuple(Candidate(i, "knee", f"K{i + 1}", f"K{i + 1} · #{i}") for i in range(3))
    front = tuple(Candidate(i, "front", f"front {i}", f"front {i} · #{i}") for i in range(3, 230))
    cands = knees + front
    out = listed(cands, shown=100)
    kept = [c for c in out if c.kind == "front"]
    assert out[:3] == knees and FRONT_LISTED <= len(kept) <= FRONT_LISTED + 1
    assert kept[0] == front[0] and kept[-1] == front[-1] and any(c.member == 100 for c in kept)
    assert [c.member for c in kept] == sorted(c.member for c in kept)  # the front's order
    assert listed(cands[:50], shown=None) == cands[:50]


def test_the_pick_panel_compares_objectives_then_constrained_then_report_metrics_then_the_violation() -> None:
    from studio.candidates import compared_metrics

    class R:
        objectives = ("f1", "f2")
        metrics = {k: np.zeros(1) for k in ("f1", "f2", "h_s", "I", "mse", "violation", "width")}

    assert compared_metrics(R(), ("h_s", "violation")) == ("f1", "f2", "h_s", "I", "width", "violation")  # type: ignore[arg-type]
    # MSE is listed once when it is f1 ("f1 = MSE (mm)" then "MSE (mm)" read one number twice); a problem whose f1
    # is something else keeps both.
    R.metrics = {**R.metrics, "mse": np.ones(1)}
    assert compared_metrics(R(), ("h_s", "violation")) == ("f1", "f2", "h_s", "mse", "I", "width", "violation")  # type: ignore[arg-type]



def test_candidate_values_read_as_a_designer_would_say_them() -> None:
    from studio.candidates import _fmt

    assert [_fmt(v) for v in (4.08e-07, -2.9e-08, 0.0, 5.2e-4, 0.4472, 4.1017, 123456.0, float("nan"))] == \
        ["≈0", "≈0", "0", "0.00052", "0.447", "4.102", "1.23e+05", "-"]
    assert _fmt(1e-9, exact=True) == "1e-09"  # a violation: any is infeasible, and "≈0" read as feasible


def test_a_pick_row_writes_start_and_candidate_with_the_same_decimals() -> None:
    """Rehearsal 2 read "0.019" beside "0.0162" in one row: both values of a row now line up."""
    from studio.candidates import _fmt_pair

    assert _fmt_pair(0.019, 0.0162) == ("0.0190", "0.0162")
    assert _fmt_pair(4.1017, 12.3) == ("4.10", "12.30")  # 4 digits of the larger
    assert _fmt_pair(150.0, -0.0004) == ("150.0", "0.0")  # no "-0.0"
    assert _fmt_pair(0.5, float("nan")) == ("0.500", "-")
    assert _fmt_pair(2.0, 3e-7) == ("2.000", "≈0")
    assert _fmt_pair(1e-9, 0.0, exact=True) == ("1e-09", "0")  # a violation keeps every digit
    assert _fmt_pair(123456.0, 1.0) == ("1.23e+05", "1")


def test_an_objective_every_member_shares_gets_one_tick_at_its_value() -> None:
    """Subtask 1's f1-against-f2 projection (placement makes f2 = 0 for all) read "-0.006 ... 0.006" on its f2
    axis, a scale for a spread there is not: the axis now has one tick, at 0; a varying axis keeps plotly's."""
    from studio.figures import make_pareto_figure

    F = np.array([[3.6, 0.0, 0.0], [4.1, 0.0, 0.0], [4.4, 0.0, 0.0], [np.nan, 1.0, 0.0]])
    fig = make_pareto_figure(F, np.zeros(4), objectives=("f1", "f2", "f3"), front=(0,), axes=(0, 1))
    assert list(fig.layout.yaxis.tickvals) == [0.0] and list(fig.layout.yaxis.ticktext) == ["0"]
    assert fig.layout.xaxis.tickvals is None
    # Rehearsal 3's side panel cut "f2 = width penalty (mm^2)" to "idth penalty (mm^2)": broken before its unit.
    fig = make_pareto_figure(F, np.zeros(4), objectives=("f1", "f2", "f3"), front=(0,), axes=(0, 1),
                             labels={"f1": "f1 = MSE (mm)", "f2": "f2 = width penalty (mm^2)"})
    assert fig.layout.yaxis.title.text == "f2 = width penalty<br>(mm^2)"
    assert fig.layout.xaxis.title.text == "f1 = MSE (mm)"
    # A population collapsed to one point (rehearsal 4: I read "51.00152, 51.001525, 51.00153"): one tick, saying
    # how close; a real spread of 1e-4 on 51 keeps plotly's scale.
    for spread, one in ((1e-5, True), (1e-4, False)):
        G = np.array([[5.41, 51.0015], [5.41 + 1e-6, 51.0015 + spread / 2], [5.42, 51.0015 + spread]])
        fig = make_pareto_figure(G, np.zeros(3), objectives=("f1", "f2"), front=(0, 1, 2))
        assert (fig.layout.yaxis.tickvals is not None) == one
        if one:
            assert list(fig.layout.yaxis.ticktext) == ["51.0015 (all within 1e-05)"]
