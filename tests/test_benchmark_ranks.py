"""The quality tables' mean rank row (benchmarks/algorithms.py), on a case computed by hand."""

from __future__ import annotations

import numpy as np

from benchmarks.algorithms import mean_ranks

NAN = float("nan")


def test_mean_rank_by_median_igd_with_infeasible_runs_as_the_worst_and_shared_ties():
    igds = [
        # medians 0.2; 0.1 (its NaN run is +inf, above both others); +inf (two of three runs infeasible)
        [[0.1, 0.2, 0.3], [0.05, NAN, 0.1], [NAN, NAN, 0.01]],
        # medians 1, 1, 0.5: the first two share ranks 2 and 3
        [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5]],
    ]
    np.testing.assert_allclose(mean_ranks(igds), [(2 + 2.5) / 2, (1 + 2.5) / 2, (3 + 1) / 2])


def test_an_algorithm_without_a_feasible_run_anywhere_ranks_last_everywhere():
    igds = [[[0.3], [0.2], [NAN]], [[0.1], [0.4], [NAN]]]
    np.testing.assert_allclose(mean_ranks(igds), [1.5, 1.5, 3.0])
