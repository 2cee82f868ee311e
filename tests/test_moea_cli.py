"""``clm moea`` on pymoo's test problems: PlatEMO's indicators, offline fronts, one-line errors."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from core.cli import main
from core.optimize.moea import PROBLEMS, feasible_front, hv_platemo, igd, reference_front, run
from core.optimize.problem_names import KNOWN


def test_indicators_by_hand():
    pf = np.array([[0.0, 1.0], [1.0, 0.0]])
    # IGD: each reference point's distance to the one member (0.5, 0.5) is sqrt(0.5).
    assert igd(np.array([[0.5, 0.5]]), pf) == pytest.approx(np.sqrt(0.5))
    assert np.isnan(igd(np.zeros((0, 2)), pf))
    # HV: (0.5, 0.5) normalised by fmax * 1.1 = 1.1 -> (0.4545..), box to (1, 1): (1 - 0.5/1.1)^2.
    assert hv_platemo(np.array([[0.5, 0.5]]), pf) == pytest.approx((1 - 0.5 / 1.1) ** 2)
    assert hv_platemo(np.array([[2.0, 2.0]]), pf) == 0.0  # outside the normalised box
    # Only feasible, non-dominated members count: (0, 0) violates, (1, 1) is dominated by (0.5, 0.5).
    F = np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]])
    np.testing.assert_array_equal(feasible_front(F, np.array([1.0, 0.0, 0.0])), [[0.5, 0.5]])


def test_the_listing_in_help_and_errors_names_exactly_the_problems(capsys):
    names = []
    for part in KNOWN.split(", "):
        first, _, last = part.partition("..")
        if not last:
            names.append(first)
            continue
        stem = first.rstrip("0123456789")
        names += [f"{stem}{i}" for i in range(int(first[len(stem):]), int(last[len(stem):]) + 1)]
    assert sorted(names) == sorted(PROBLEMS) and len(names) == len(set(names))
    assert main(["moea", "--help"]) == 0
    assert "dc3dtlz3" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("name", [p for p in PROBLEMS if p.startswith(("mw", "ctp"))])
def test_every_mw_and_ctp_front_ships_with_the_package(name):
    pf = reference_front(name)
    assert pf is not None and pf.ndim == 2 and len(pf) >= 5 and np.isfinite(pf).all()


def test_clm_moea_prints_json_with_the_budget_spent(capsys):
    assert main(["moea", "--problem", "ctp2", "--pop", "20", "--evals", "400", "--seed", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_eval"] == 400 and out["problem"] == "ctp2" and out["algorithm"] == "nsga2"
    assert 0 <= out["feasible"] <= 20 and out["reference_points"] > 0


def test_the_population_written_out_gives_the_printed_igd_and_hv(capsys, tmp_path):
    # QA (session 37): the JSON held no front, so its IGD and HV could not be checked from the command's own output.
    path = tmp_path / "pop.csv"
    argv = ["moea", "--problem", "mw3", "--algorithm", "cmoes", "--pop", "20", "--evals", "2000", "--seed", "2"]
    assert main([*argv, "--json", "--out", str(path)]) == 0
    said = json.loads(capsys.readouterr().out)
    head, *rows = path.read_text().splitlines()
    cols = head.split(",")
    assert cols[-3:] == ["cv", "feasible", "front"] and len(rows) == said["size"]
    table = np.array([[float(v) for v in r.split(",")] for r in rows])
    F, cv, feasible, front = table[:, cols.index("f1"):-3], table[:, -3], table[:, -2], table[:, -1].astype(bool)
    assert F.shape[1] == 2 and int(feasible.sum()) == said["feasible"] > 0 and np.array_equal(feasible, cv <= 0)
    pf = reference_front("mw3")
    assert igd(F[front], pf) == said["igd"] and hv_platemo(F[front], pf) == said["hv"]
    assert np.array_equal(np.unique(F[front], axis=0), np.unique(feasible_front(F, cv), axis=0))
    assert main([*argv, "--out", str(path)]) == 2  # not replaced without --overwrite
    assert "exists; pass --overwrite" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["moea", "--problem", "mw99"], ["moea", "--problem", "mw1", "--algorithm", "nope"],
    ["moea", "--problem", "mw1", "--evals", "0"], ["moea", "--problem", "mw1", "--evals", "-5"],
    ["moea", "--problem", "mw1", "--pop", "0"], ["moea", "--problem", "mw1", "--seed", "-1"],
    ["moea", "--problem", "mw1", "--seed", str(10**30)], ["moea"], ["moea", "--problem", "mw1", "--pop", "x"],
    ["moea", "--problem", "mw1", "--algorithm", "imtcmo", "--option", "operator=de"],
    ["moea", "--problem", "mw1", "--algorithm", "gde3", "--option", "variant=nonsense"],
    ["moea", "--problem", "mw1", "--option", "crossover_prob=2"], ["moea", "--problem", "mw1", "--option", "de"],
    ["moea", "--problem", "mw1", "--algorithm", "cmoes", "--option", "operator=DE"],
    ["moea", "--problem", "mw1", "--option", "crossover_prob=0.8", "--option", "crossover_prob=0.5"],
    ["moea", "--problem", "mw1", "--overwrite"], ["moea", "--problem", "mw1", "--out", ""],
    ["moea", "--problem", "mw1", "--out", "-"], ["moea", "--problem", "mw1", "--out", "-", "--overwrite"],
])
def test_bad_arguments_are_one_line_errors(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("clm: error: ") and err.count("\n") == 1


@pytest.mark.parametrize("problem", ["mw11", "ctp3"])
def test_a_problem_s_own_nan_objectives_raise_no_numpy_warning(problem):
    # Both problems compute NaN objectives for some of CMOEMT's children (numpy warns where they do); the user
    # of the CLI gets the result line alone.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["moea", "--problem", problem, "--algorithm", "cmoemt", "--pop", "40", "--evals", "4000"]) == 0


def test_options_reach_the_algorithm_as_a_configuration_s_do(capsys):
    # MCCMO with PlatEMO's DE operator (its choice for DAS-CMOP): the same run as the library's with the option,
    # another run than the default GA one.
    argv = ["moea", "--problem", "ctp2", "--algorithm", "mccmo", "--pop", "20", "--evals", "1000", "--json"]
    assert main([*argv, "--option", "operator=de"]) == 0
    de = json.loads(capsys.readouterr().out)
    assert main(argv) == 0
    ga = json.loads(capsys.readouterr().out)
    ref = run("ctp2", "mccmo", 20, 1000, 1, {"operator": "de"})
    assert de["igd"] == ref["igd"] and de["igd"] != ga["igd"]
    # Typed as in a configuration: false is a bool, 0.5 a number.
    assert main(["moea", "--problem", "ctp2", "--pop", "20", "--evals", "400", "--option", "eliminate_duplicates=false",
                 "--option", "crossover_prob=0.5"]) == 0


def test_the_front_counts_distinct_points():
    # CMOEMT's final population holds exact copies (its tasks share members); the front is the distinct points.
    from pymoo.optimize import minimize

    from core.optimize.algorithms import AlgorithmSpec, make_algorithm
    from core.optimize.moea import feasible_front, problem_by_name

    res = minimize(problem_by_name("mw3"), make_algorithm(AlgorithmSpec("cmoemt", 40), 2, 1), ("n_eval", 4000), seed=1)
    front = feasible_front(res.pop.get("F"), res.pop.get("CV")[:, 0])
    distinct = len(np.unique(front, axis=0))
    assert 0 < distinct < len(front)  # copies on the front
    assert run("mw3", "cmoemt", 40, 4000, 1)["front_size"] == distinct


@pytest.mark.parametrize(("name", "options", "message"), [
    ("nsga2", {"mutation_eta": -1}, "option 'mutation_eta' of nsga2 must be a number in [0, inf], got -1"),
    ("nsga2", {"crossover_prob": 1.5}, "option 'crossover_prob' of nsga2 must be a number in [0, 1], got 1.5"),
    ("nsga2", {"mutation_prob": True}, "option 'mutation_prob' of nsga2 must be a number"),
    ("imtcmo", {"operator": "de"}, "unknown option 'operator' for imtcmo; it takes no options"),
])
def test_the_library_checks_option_values_as_the_cli_does(name, options, message):
    # The Python path (core.optimize.moea.run, make_algorithm) used to pass mutation_eta = -1 on to a division by
    # zero inside the mutation.
    with pytest.raises(ValueError) as e:
        run("mw3", name, 20, 400, 1, options)
    assert str(e.value).startswith(message)


def test_a_malformed_de_variant_is_named_not_pymoos_unpacking_error(capsys):
    assert main(["moea", "--problem", "mw1", "--algorithm", "gde3", "--option", "variant=DE/rand/bin"]) == 2
    assert "option 'variant' of gde3 must read DE/" in capsys.readouterr().err


@pytest.mark.parametrize(("typed", "meant"), [("NSGA-II", "'nsga2' (NSGA-II)"), ("nsga-2", "'nsga2' (NSGA-II)"),
                                               ("MOEA/D-CMT", "'moead_cmt' (MOEA/D-CMT)"),
                                               ("DRLOS-EMCMO", "'drlos_emcmo' (DRLOS-EMCMO)")])
def test_a_published_algorithm_name_gets_its_registered_name_suggested(typed, meant, capsys):
    """Rehearsal 3: the studio lists "MOEA/D-CMT (paper)", which `clm moea`, configs and studies refused with the
    whole list and no hint; the message now names the registered name to type."""
    from core.optimize.algorithms import unknown_algorithm

    assert main(["moea", "--problem", "mw3", "--algorithm", typed, "--evals", "100"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"clm: error: unknown algorithm {typed!r}; did you mean {meant}? Known: nsga2, ")
    assert "did you mean" not in unknown_algorithm("xyz")


def test_a_run_that_compiled_kernels_says_how_much_of_its_time_that_was(capsys, monkeypatch):
    # Lab rehearsal: CMOES's first run on a fresh machine read 36.5 s (0.6 s after); students would report it 90x
    # slower than NSGA-II. The compile time is the real CompileTimer's, made to read 12.3 s here.
    from core.kinematics import kernel_cache

    monkeypatch.setattr(kernel_cache.CompileTimer, "seconds", property(lambda self: 12.3))
    assert main(["moea", "--problem", "ctp2", "--pop", "20", "--evals", "200"]) == 0
    out = capsys.readouterr().out
    assert "IGD " in out and "(lower is better)" in out and "(higher is better)" in out
    assert out.rstrip().endswith(" s (12.3 s of it compiling numba kernels, which later runs of this code load from "
                                 "its cache)")
    assert main(["moea", "--problem", "ctp2", "--pop", "20", "--evals", "200", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["compile_time"] == 12.3
    monkeypatch.setattr(kernel_cache.CompileTimer, "seconds", property(lambda self: 0.0))
    assert main(["moea", "--problem", "ctp2", "--pop", "20", "--evals", "200"]) == 0
    assert "compiling" not in capsys.readouterr().out


def test_an_igd_without_a_feasible_member_and_a_budget_overshot_are_said(capsys):
    # Lab rehearsal: "IGD -" and 3077 evaluations of a 3000 budget were left to guess.
    assert main(["moea", "--problem", "mw1", "--pop", "20", "--evals", "110", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "IGD - (no feasible member at the end: nothing to measure)" in out
    assert "120 evaluations (the generation that reached --evals 110 ran to its end)" in out


def test_an_algorithm_name_is_taken_in_any_case_as_problem_names_are(capsys):
    # Lab rehearsal: `--problem MW3` was taken and `--algorithm CMOES` refused with a did-you-mean.
    assert main(["moea", "--problem", "MW3", "--algorithm", "NSGA2", "--pop", "20", "--evals", "100", "--json",
                 "--option", "crossover_prob=0.5"]) == 0
    assert json.loads(capsys.readouterr().out)["algorithm"] == "nsga2"
