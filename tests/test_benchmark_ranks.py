"""The quality tables' mean rank row and the code they name (benchmarks/algorithms.py), on cases computed by hand."""

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


def test_a_table_names_the_code_of_cached_runs_as_well_as_of_new_ones(tmp_path):
    # A cached run keeps the code it was made with; the run made now gets the current one.
    import json

    from benchmarks.algorithms import code_version, made_with, quality

    cache = tmp_path / "runs.jsonl"
    cache.write_text(json.dumps({"problem": "mw1", "algorithm": "nsga2_pymoo", "evals": 200, "seed": 1,
                                 "igd": 0.5, "hv": 0.1, "code": "0ld0ld0"}) + "\n")
    rows, codes = quality(["nsga2_pymoo"], ["mw1"], range(1, 3), 200, cache=cache)
    assert codes == {"0ld0ld0", code_version()} and code_version() != "0ld0ld0"
    assert json.loads(cache.read_text().splitlines()[1])["code"] == code_version()
    assert rows[0][0] == "mw1"
    assert made_with({"b", "a"}) == "; its runs were made with core/ as of commits a, b"
