"""Where a label goes (studio/spots.py), shared by the bench chart, the Pareto chart and the scene: hand-made boxes,
and the Pareto chart's rule checked on random crowds of candidates."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.spots import cover, first_clear, least_cover, overlaps, spill


def test_boxes_by_hand() -> None:
    a, b, c = (0.0, 0.0, 2.0, 1.0), (1.0, 0.5, 3.0, 2.0), (2.0, 0.0, 3.0, 1.0)
    assert overlaps(a, b) and cover(a, b) == 0.5  # 1 wide, 0.5 high
    assert not overlaps(a, c) and cover(a, c) == 0.0  # touching edges share no area
    assert spill(a, (0.0, 0.0, 2.0, 1.0)) == 0.0 and spill(b, (0.0, 0.0, 2.0, 1.0)) == 1.0 + 1.0
    assert first_clear([a, b, c], [(0.5, 0.2, 0.6, 0.3)]) == 1 and first_clear([a], [a]) is None
    assert least_cover([a, b], [(1.5, 0.0, 2.0, 1.0)]) == 1  # a covers 0.5 * 1, b 0.5 * 0.5
    assert least_cover([a, a], [a]) == 0 and least_cover([], [a]) is None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=1, max_size=9))
def test_a_pareto_label_takes_a_clear_spot_inside_else_the_one_over_least_of_the_other_markers(pts) -> None:
    from studio.figures import MARKER_PX, PLOT_PX, POSITIONS, _label_box, place_labels

    xy = np.array(pts)
    texts = [f"K{k + 1}" if k < 5 else f"best f{k - 4}" for k in range(len(xy))]
    got = place_labels(xy, texts, ([0.0, 1.0], [0.0, 1.0]))
    px = xy * np.array(PLOT_PX)
    r, plot = MARKER_PX, (0.0, 0.0, *PLOT_PX)
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
        clear = [p for p in inside if not any(overlaps(boxes[p], m) for m in others)]
        if clear:
            assert pos == clear[0]
        elif inside:
            least = min(sum(cover(boxes[p], m) for m in others) for p in inside)
            assert sum(cover(boxes[pos], m) for m in others) == least
        labels.append(boxes[pos])
