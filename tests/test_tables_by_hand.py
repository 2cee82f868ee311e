"""The Metrics panel's rows and the small HTML tables, on hand-built evaluations and results (a mutation audit
of studio/metrics.py and studio/tables.py: units, colours, stance samples and reasons a design fails)."""

from __future__ import annotations

import math
import re
from types import SimpleNamespace

import numpy as np

from core.analysis.evaluate import gait_verdict
from core.optimize.box import Box
from studio.candidates import HistoryRow
from studio.metrics import (
    Row,
    feature_labels,
    metric_rows,
    metrics_html,
    min_transmission_angle,
    shape_error,
    stance_mask,
    why_infeasible,
)
from studio.tables import BETTER, WORSE, box_html, compare_html, history_html, verdict_html


def evaluation(**kw: object) -> SimpleNamespace:
    """One member's evaluation, every metric a different round number (so a row reading the wrong one shows)."""
    ev = dict(feasible=np.array([True]), kinematic_violation=np.array([0.0]), path_violation=np.array([0.0]),
              constraints=np.array([[-1.0, -1.0, -1.0, -1.0, -1.0]]), mse_phase=np.array([np.nan]),
              mse=np.array([3.0]), h_s=np.array([4.0]), S=np.array([1.5]), I=np.array([0.25]),
              theta1=np.array([math.pi / 6]), theta2=np.array([math.pi / 4]), l_s=np.array([250.0]),
              h_m=np.array([90.0]), h_bar=np.array([40.0]), obstacle=(25.0, 30.0), psi2=np.array([0.625]),
              psi4=np.array([0.125]), width=np.array([280.0]), y_min=np.array([-101.0]))
    ev.update(kw)
    return SimpleNamespace(**ev)


def solution() -> SimpleNamespace:
    return SimpleNamespace(violation=np.array([0.0]), crank_margin=np.array([3.0]),
                           dyad_margin=np.array([[7.0, 2.0, np.nan]]),
                           mu_min=np.array([[0.5, 1.0]]), mu_max=np.array([[2.9, 2.0]]))


def row(rows: tuple[Row, ...], key: str) -> Row:
    return next(r for r in rows if r.key == key)


# Rows -----------------------------------------------------------------------------------------------------


def test_rows_show_angles_in_degrees_and_probabilities_in_percent():
    rows = metric_rows(solution(), evaluation())
    shown = {r.key: (r.text(), r.unit) for r in rows}
    assert shown["theta1"] == ("30.0", "deg") and shown["theta2"] == ("45.0", "deg")
    assert shown["psi2"] == ("62.5", "%") and shown["psi4"] == ("12.5", "%")
    assert row(rows, "psi2").label == "ψ₂(25, 30)"
    assert shown["width"] == ("280.00", "mm") and shown["l_s"] == ("250.00", "mm")
    assert shown["h_s"] == ("4.00", "mm") and shown["mse"] == ("3.00", "mm")
    # The closest approach of any dyad: the smallest finite margin.
    assert shown["dyad_margin"] == ("2.00", "mm")
    # min(mu, 180 - mu) over dyads and cycle: 180 - 2.9 rad = 0.2416 rad = 13.8 deg.
    assert shown["mu_min"] == (f"{math.degrees(math.pi - 2.9):.1f}", "deg")


def test_the_worst_transmission_angle_counts_both_ends_of_the_range():
    sol = SimpleNamespace(mu_min=np.array([[1.2, np.nan]]), mu_max=np.array([[2.5, np.nan]]))
    assert min_transmission_angle(sol) == math.pi - 2.5
    sol = SimpleNamespace(mu_min=np.array([[0.3]]), mu_max=np.array([[1.6]]))
    assert min_transmission_angle(sol) == 0.3


def test_a_value_shows_its_digits_and_infinities_read_none_and_minus_inf():
    assert Row("k", "k", 1.23456, digits=2).text() == "1.23"
    assert Row("k", "k", math.inf).text() == "none"
    assert Row("k", "k", -math.inf).text() == "-inf"
    assert Row("k", "k", None).text() == "-" and Row("k", "k", True).text() == "yes"


def test_the_shape_error_is_the_best_shift_one_when_there_is_one():
    assert shape_error(evaluation(mse_phase=np.array([np.nan]), mse=np.array([3.0]))) == 3.0
    assert shape_error(evaluation(mse_phase=np.array([2.0]), mse=np.array([3.0]))) == 2.0


def test_a_constraint_is_unmet_above_zero_and_not_defined_when_unreadable():
    # The review of session 29: the studio counted NaN as "unmet" where clm evaluate says "not defined" (one rule
    # now, core's gait_verdict).
    ev = evaluation(constraints=np.array([[0.0, -1.0, 0.5, np.nan, 0.0]]))
    assert gait_verdict(ev.constraints[0]) == (("theta2",), ("h_bar",))
    rows = metric_rows(solution(), ev)
    assert row(rows, "gait").text() == "1 unmet; 1 not defined"
    assert row(rows, "gait").note == ("take-off angle theta2 >= 15 deg; not defined (h_bar): no well-defined bench "
                                      "trajectory")
    none = metric_rows(solution(), evaluation(constraints=np.full((1, 5), np.nan)))
    assert row(none, "gait").text() == "5 not defined"
    met = metric_rows(solution(), evaluation(constraints=np.zeros((1, 5))))
    assert row(met, "gait").text() == "all met" and row(met, "gait").note == "Eq. 30-31 all met"


def test_why_not_names_the_first_reason_that_applies():
    assert why_infeasible(evaluation()) == ""
    off = np.array([False])
    assert why_infeasible(evaluation(feasible=off, kinematic_violation=np.array([1.5]))).startswith(
        "does not assemble over the whole cycle (shortfall 1.5 mm)")
    # A small shortfall keeps its digits: "0.00 mm" beside "does not assemble" read as a contradiction.
    assert why_infeasible(evaluation(feasible=off, kinematic_violation=np.array([4.171e-05]))).startswith(
        "does not assemble over the whole cycle (shortfall 4.17e-05 mm)")
    assert why_infeasible(evaluation(feasible=off, path_violation=np.array([np.inf]))) == "the foot path is not finite"
    assert why_infeasible(evaluation(feasible=off)) == (
        "no single landing/take-off pair, or the foot path crosses itself")


def test_the_stance_samples_run_from_landing_to_take_off_inclusive():
    times = np.full((1, 8), np.nan)
    times[0, :2] = (0.5, 1.0)  # landing at a quarter of the 2 s cycle, take-off at half
    ev = evaluation(times=times, period=2.0)
    np.testing.assert_array_equal(np.flatnonzero(stance_mask(ev, 8)), [2, 3, 4])
    times[0, :2] = (1.5, 0.5)  # across the cycle's end
    np.testing.assert_array_equal(np.flatnonzero(stance_mask(ev, 8)), [0, 1, 2, 6, 7])


def test_feature_points_closer_than_four_percent_of_their_spread_share_a_label():
    pts = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 3.0], [50.0, 50.0], [50.0, 60.0],
                    [np.nan, np.nan], [0.0, 2.0], [20.0, 0.0]])
    labels = dict(feature_labels(evaluation(points=pts[None])))
    # spread 100 mm: 3 mm and 2 mm apart merge, 10 mm and 20 mm apart do not; they are near, not on one spot
    # (within 0.5 % of the spread), so they are listed: "=" claimed they coincide (QA, session 38)
    assert set(labels) == {"t1,t7", "t2,t3", "t4", "t5", "t8"}
    pts[6] = [0.0, 0.4]  # t7 now 0.4 mm from t1: the same spot
    assert set(dict(feature_labels(evaluation(points=pts[None])))) == {"t1=t7", "t2,t3", "t4", "t5", "t8"}


def test_the_table_html_carries_each_rows_unit():
    html = metrics_html(metric_rows(solution(), evaluation()))
    assert re.search(r'data-key="psi2".*?data-value="62.5".*?<td style="opacity:0.7">%</td>', html)
    assert re.search(r'data-key="theta1".*?data-value="30.0".*?<td style="opacity:0.7">deg</td>', html)


# Tables ---------------------------------------------------------------------------------------------------


def cell(table: str, metric: str) -> str:
    m = re.search(rf'<tr data-metric="{metric}">.*?<td style="([^"]*)" data-candidate=', table)
    assert m is not None
    return m.group(1)


def test_a_better_candidate_value_is_green_a_worse_red_and_an_equal_or_neutral_one_plain():
    t = compare_html([("MSE", "4.0", "3.0"), ("h_s", "2", "3"), ("I", "1.5", "1.50"), ("width", "1", "9"),
                      ("S", "-", "2")], "start", "#3", {"MSE", "h_s", "I", "S"})
    assert cell(t, "MSE").endswith(BETTER) and cell(t, "h_s").endswith(WORSE)
    for neutral in ("I", "width", "S"):
        assert BETTER not in cell(t, neutral) and WORSE not in cell(t, neutral)


def test_the_search_box_row_lists_lower_centre_upper_and_greys_a_fixed_parameter():
    box = Box(names=("r1", "b"), lower=np.array([20.0, 1.0]), upper=np.array([60.0, 1.0]),
              center=np.array([40.0, 1.0]), bound_lo=np.array([0.0, 0.0]), bound_hi=np.array([100.0, 2.0]),
              periodic=np.array([False, False]), fixed=np.array([False, True]))
    html = box_html(box, {"r1": "mm"})
    assert 'data-param="r1" data-lower="20.0" data-center="40.0" data-upper="60.0">' in html
    assert 'data-param="b" data-lower="1.0" data-center="1.0" data-upper="1.0" data-fixed>' in html
    r1, b = html.split('data-param="b"')
    # r1's box covers 20 % to 60 % of its global bounds, in the free colour; the fixed one is grey
    assert "left:20.0%;width:40.0%;height:8px;background:#1f77b4" in r1
    assert "background:#bbb" in b and "#1f77b4" not in b


def test_an_angle_in_the_search_box_is_written_as_the_editor_writes_it():
    # g = 3.26 in the Parameters panel read -3.023 in the box (3.26 - 2 pi): the box keeps angles in [-pi, pi].
    import math

    c = 3.26 - 2 * math.pi
    box = Box(names=("g", "r1"), lower=np.array([c - 0.2, 20.0]), upper=np.array([c + 0.2, 60.0]),
              center=np.array([c, 40.0]), bound_lo=np.array([-math.pi, 0.0]), bound_hi=np.array([math.pi, 100.0]),
              periodic=np.array([True, False]), fixed=np.array([False, False]))
    units = {"g": "rad", "r1": "mm"}

    def cells(html: str, name: str) -> list[str]:
        row = html.split(f'data-param="{name}"')[1].split("</tr>")[0]
        return re.findall(r'<td style="text-align:right[^"]*">([^<]*)</td>', row)

    near = box_html(box, units, near={"g": 3.26, "r1": 540.0})
    assert cells(near, "g") == ["3.06", "3.26", "3.46"] and cells(near, "r1") == ["20", "40", "60"]  # lengths stay
    assert f'data-center="{c!r}"' in near  # the box itself is not changed
    assert cells(box_html(box, units), "g") == [f"{c - 0.2:.4g}", f"{c:.4g}", f"{c + 0.2:.4g}"]
    assert ">start</th>" in near and ">centre</th>" not in near  # on predesign's global box it is not the middle


def test_the_lineage_table_shows_feasible_and_front_counts_in_their_columns():
    rows = [HistoryRow("subtask1", "Subtask 1", "complete", "30", 17, 5, "K1", "MSE 3.1", "from X3")]
    html = history_html(rows)
    nums = re.findall(r'<td style="text-align:right[^"]*">([^<]*)</td>', html)
    assert nums == ["30", "17", "5", "K1"]


def test_a_feasible_member_gets_the_tick_and_an_infeasible_one_names_what_it_misses():
    def unmet(i: int, labels: dict[str, str] | None = None) -> list[str]:
        return [f"{(labels or {}).get('h_s', 'h_s')} 8.72 > 6.5"] if i == 1 else []

    r = SimpleNamespace(cv=np.array([0.0, 0.4, 0.2]), unmet=unmet)
    ok, bad, vague = (verdict_html(r, i, "subtask2") for i in range(3))
    assert 'data-feasible="true"' in ok and "✓ #0 meets subtask2's constraints" in ok
    assert 'data-feasible="false"' in bad and "h_s 8.72 &gt; 6.5" in bad
    assert 'data-feasible="false"' in vague and "violation 0.2" in vague
    # By the problem's labels, as the table under it names the metrics (session 30).
    assert "f4 = h_s (mm) 8.72 &gt; 6.5" in verdict_html(r, 1, "subtask2", labels={"h_s": "f4 = h_s (mm)"})
