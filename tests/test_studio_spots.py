"""Where a label goes (studio/spots.py), shared by the bench chart, the Pareto chart and the scene: hand-made boxes,
and the Pareto chart's rule checked on random crowds of candidates."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.spots import cover, covers, first_clear, overlaps, spill


def test_boxes_by_hand() -> None:
    a, b, c = (0.0, 0.0, 2.0, 1.0), (1.0, 0.5, 3.0, 2.0), (2.0, 0.0, 3.0, 1.0)
    assert overlaps(a, b) and cover(a, b) == 0.5  # 1 wide, 0.5 high
    assert not overlaps(a, c) and cover(a, c) == 0.0  # touching edges share no area
    assert spill(a, (0.0, 0.0, 2.0, 1.0)) == 0.0 and spill(b, (0.0, 0.0, 2.0, 1.0)) == 1.0 + 1.0
    assert first_clear([a, b, c], [(0.5, 0.2, 0.6, 0.3)]) == 1 and first_clear([a], [a]) is None
    # Summed over what is taken, for many tries at once: the same areas as one at a time.
    np.testing.assert_allclose(covers([a, b, c], [b, c]), [cover(a, b) + cover(a, c), cover(b, b) + cover(b, c),
                                                           cover(c, b) + cover(c, c)])
    assert covers([a], []).tolist() == [0.0] and covers([], [a]).shape == (0,)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=1, max_size=9),
       st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), max_size=30))
def test_a_pareto_label_avoids_candidates_then_the_front_s_dots_and_stays_beside_its_marker(pts, front) -> None:
    from studio.figures import DOT_PX, FAR_COST, MARKER_PX, PLOT_PX, POSITIONS, _label_box, place_labels

    xy, dots_xy = np.array(pts), np.array(front).reshape(-1, 2)
    texts = [f"K{k + 1}" if k < 5 else f"best f{k - 4}" for k in range(len(xy))]
    got = place_labels(xy, texts, ([0.0, 1.0], [0.0, 1.0]), dots_xy)
    px, dpx = xy * np.array(PLOT_PX), dots_xy * np.array(PLOT_PX)
    r, d, plot = MARKER_PX, DOT_PX, (0.0, 0.0, *PLOT_PX)
    dots = [(x - d, y - d, x + d, y + d) for x, y in dpx]
    labels = []
    for (x, y), text, pos in zip(px, texts, got, strict=True):
        own = (x - r, y - r, x + r, y + r)  # a marker on the same spot is its own: no label can avoid it
        others = [m for m in ((qx - r, qy - r, qx + r, qy + r) for qx, qy in px) if m != own]
        boxes = {p: _label_box(x, y, text, p) for p in POSITIONS}
        free = [p for p in POSITIONS if not any(overlaps(boxes[p], b) for b in labels)]
        inside = [p for p in free if spill(boxes[p], plot) == 0.0]
        if pos is None:  # only when every position covers a label placed before it
            assert not free
            continue
        assert pos in free  # never over another label
        marks = {p: sum(cover(boxes[p], m) for m in others) for p in inside}
        hidden = {p: sum(cover(boxes[p], t) for t in dots) + (FAR_COST if p.startswith("far") else 0.0)
                  for p in inside}
        if not inside:
            assert pos == free[0]
            labels.append(boxes[pos])
            continue
        slack = max(hidden.values()) / 1e4  # a candidate's marker outweighs every dot: by 1e4 a px²
        if any(v == 0.0 for v in marks.values()):  # some spot is clear of every other candidate: one of those,
            assert marks[pos] <= slack  # hiding the fewest dots (near its marker unless that hides more)
            assert hidden[pos] <= min(hidden[p] for p in inside if marks[p] == 0.0) + 1e-9
        else:
            assert marks[pos] <= min(marks.values()) + slack + 1e-9
        labels.append(boxes[pos])
