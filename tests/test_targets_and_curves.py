"""The compound-cycloid target and CSV curves: formulas, resampling, and one clear error per bad file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from core.analysis.targets import compound_cycloid, curve_from_rows, cycloid_target, load_curve, parse_target, resample


def test_cycloid_formula_and_derivative() -> None:
    L, H, n = 300.0, 100.0, 400
    p, d = compound_cycloid(n, L, H)
    np.testing.assert_allclose(p[0], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p[n // 4], [L / 2, -H])  # arch apex at a quarter period
    np.testing.assert_allclose(p[n // 2], [L, 0.0], atol=1e-12)
    np.testing.assert_allclose(p[3 * n // 4], [L / 2, 0.0])  # return line at constant speed
    assert p[:, 0].min() == pytest.approx(0.0) and p[:, 0].max() == pytest.approx(L)
    # d/dtheta against central differences of the formula itself (theta = 2 pi t / T)
    h = 1e-6
    th = 2 * np.pi * np.arange(n) / n
    for i in (13, 77, 250, 333):
        s = th[i] / np.pi  # half-periods elapsed
        x = lambda s: L * (s - np.sin(2 * np.pi * s) / (2 * np.pi)) if s < 1 else L * (2 - s)  # noqa: E731
        y = lambda s: -H * (0.5 - 0.5 * np.cos(2 * np.pi * s)) if s < 1 else 0.0  # noqa: E731
        num = np.array([x(s + h / np.pi) - x(s - h / np.pi), y(s + h / np.pi) - y(s - h / np.pi)]) / (2 * h)
        np.testing.assert_allclose(d[i], num, rtol=1e-6, atol=1e-6)


def test_cycloid_target_samples_exactly() -> None:
    t = cycloid_target(250.0, 80.0, 1.5)
    np.testing.assert_array_equal(t.sample(123), compound_cycloid(123, 250.0, 80.0)[0])
    assert t.has_time and t.period == 1.5


def test_a_timed_csv_is_resampled_in_time(tmp_path: Path) -> None:
    """The target written with its times reads back as the target's own samples."""
    n_file = 600
    p, _ = compound_cycloid(n_file)
    t = np.arange(n_file) * (2.0 / n_file)
    f = tmp_path / "cyc.csv"
    f.write_text("x,y,t\n" + "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for (a, b), c in zip(p, t, strict=True)) + "\n")
    curve = load_curve(f)
    assert curve.has_time and curve.period == pytest.approx(2.0)
    # every 10th file sample lands on a resampled one: N = 60 reproduces them exactly
    np.testing.assert_allclose(curve.sample(60), p[::10], atol=1e-9)


def test_a_closing_repeat_sets_the_period() -> None:
    rows = [["0", "0", "0"], ["1", "0", "1"], ["1", "1", "2"], ["0", "1", "3"], ["0", "0", "5"]]
    c = curve_from_rows(rows)
    assert c.period == 5.0 and len(c.points) == 4
    np.testing.assert_allclose(c.sample(10)[8], [0.0, 0.5])  # t = 4: halfway along the last edge


def test_a_header_is_a_first_row_without_a_number() -> None:
    rows = [["0", "0"], ["10", "0"], ["10", "10"], ["0", "10"]]
    for head in (["x", "y"], ["x (mm)", "y (mm)"], ["foot x", "foot y"]):
        np.testing.assert_array_equal(curve_from_rows([head, *rows]).points, np.array(rows, float))


def test_times_that_start_late_give_the_same_curve() -> None:
    rows = [["0", "0", "0"], ["10", "0", "0.5"], ["10", "10", "1"], ["0", "10", "1.5"], ["0", "0", "2"]]
    late = [[x, y, str(float(t) + 1.0)] for x, y, t in rows]
    a, b = curve_from_rows(rows), curve_from_rows(late)
    assert a.period == b.period == 2.0 and b.times[0] == 0.0
    np.testing.assert_array_equal(a.sample(16), b.sample(16))


def test_an_untimed_csv_is_resampled_in_arc_length() -> None:
    square = [["x", "y"], ["0", "0"], ["10", "0"], ["10", "10"], ["0", "10"]]
    c = curve_from_rows(square)
    assert not c.has_time
    r = c.sample(8)  # perimeter 40: a point every 5 mm from the first corner
    np.testing.assert_allclose(r, [[0, 0], [5, 0], [10, 0], [10, 5], [10, 10], [5, 10], [0, 10], [0, 5]])
    np.testing.assert_allclose(resample(np.array(square[1:], float), 4), [[0, 0], [10, 0], [10, 10], [0, 10]])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x,y\n0,0\n1,0\n", "at least 4 distinct points, got 2 in 2 rows"),
        ("0,0\n0,0\n0,0\n0,0\n", "at least 4 distinct points, got 1 in 4 rows"),  # QA (session 37): "got 3"
        ("0,0\n1,0\n0,0\n1,0\n0,0\n", "at least 4 distinct points, got 2 in 5 rows"),  # it was a target
        ("0,0\n1,0\n1,abc\n0,1\n", "'abc' is not a number"),
        ("abc,0\n1,0\n1,1\n0,1\n0,0.5\n", "data row 1: 'abc' is not a number"),  # not taken for a header
        ("0,0\n1,0\n1,nan\n0,1\n", "NaN or infinite"),
        ("0,0\n1,0\n1e300,1\n0,1\n", "data row 3 has a coordinate beyond \\+-1e\\+06 mm"),  # rehearsal 8: overflowed
        ("0,0\n1,0\n2,0\n3,0\n4,0\n50,0\n", "open curve"),
        ("0,0,0\n1,0,1\n1,1,1\n0,1,3\n", "strictly increasing"),
        ("0,0,0,0\n1,0,1,1\n", "2 columns"),
        ("0,0\n1,0\n1\n0,1\n", "row 3 has 1 columns"),
        ("x,y\n", "no data rows"),
        ("0,0\n0,0\n0,0\n0,0\n0,0\n", "at least 4 distinct points, got 1 in 5 rows"),
    ],
)
def test_bad_curves_get_one_clear_error(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(ValueError, match=message) as e:
        load_curve(f)
    assert "\n" not in str(e.value) and str(e.value).startswith("bad.csv:")


def test_missing_file_and_target_specs() -> None:
    with pytest.raises(ValueError, match="cannot read curve"):
        load_curve("/nonexistent/curve.csv")
    t = parse_target("cycloid:L=200,H=50")
    np.testing.assert_allclose(t.sample(40), compound_cycloid(40, 200.0, 50.0)[0])
    assert parse_target(None).name.startswith("compound cycloid L=300 H=100")
    for bad in ("cycloid:L=abc", "cycloid:Q=3", "cycloid:H=-1"):
        with pytest.raises(ValueError):
            parse_target(bad)


def test_a_path_that_would_walk_wrongly_gets_a_word_the_paper_s_does_not() -> None:
    from core.analysis.targets import path_note
    from core.kinematics.presets.preset import PAPER_PANTOGRAPH

    leg = PAPER_PANTOGRAPH.apply(parse_target("cycloid").sample(360))  # stance at the bottom, moving +x
    assert path_note(leg) == ""
    assert path_note(leg[::-1]).startswith("it runs clockwise in the leg frame")
    # Without the pantograph the cycloid's flat part is on top: the foot would stand on the swing's lowest point.
    assert path_note(PAPER_PANTOGRAPH.apply(leg)).startswith("its flat part is at the top in the leg frame")
    assert path_note(leg * [1.0, -1.0]).startswith("its flat part is at the top and it runs clockwise")
    # A clockwise path has a negative signed area whatever it is: a diamond has no flat part either way.
    diamond = np.array([[-100.0, -80.0], [0.0, -120.0], [100.0, -80.0], [0.0, -60.0]])
    assert path_note(diamond) == "" and path_note(diamond[::-1]).startswith("it runs clockwise")
    assert path_note(np.zeros((5, 2))) == "" and path_note(np.full((5, 2), np.nan)) == ""
