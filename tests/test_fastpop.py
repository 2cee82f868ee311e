"""core.optimize.fastpop: pymoo's Population.get / set, faster, with the same values and copies."""

from __future__ import annotations

import copy
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from test_multistart import CONFIG

from core.formats.config import parse_config, run_design
from core.optimize import fastpop


@pytest.fixture
def original() -> Iterator[None]:
    fastpop.uninstall()
    yield
    fastpop.install()


def population(seed: int = 0, n: int = 9) -> Population:
    rng = np.random.default_rng(seed)
    pop = Population.new("X", rng.random((n, 3)))
    fastpop.original_set(pop, "F", rng.random((n, 2)), "G", rng.normal(size=(n, 2)), "rank", rng.integers(0, 3, n))
    for i, ind in enumerate(pop):
        if i % 3 == 0:
            ind.__dict__["_CV"] = np.array([float(i)])  # some members have a cached CV, the others compute it
    pop[4].data["crowding"] = 1.5
    return pop


def dicts(pop: Population) -> list[dict[str, Any]]:
    return [copy.deepcopy({k: v for k, v in i.__dict__.items() if k != "config"}) for i in pop]


KEYS = [("X",), ("F",), ("G",), ("H",), ("CV",), ("FEAS",), ("rank",), ("crowding",), ("X", "F", "CV", "FEAS")]


@pytest.mark.parametrize("keys", KEYS)
@pytest.mark.parametrize("to_numpy", [True, False])
def test_get_returns_what_pymoo_returns(keys: tuple[str, ...], to_numpy: bool) -> None:
    a, b = population(), population()
    got = fastpop.get(a, *keys, to_numpy=to_numpy)
    want = fastpop.original_get(b, *keys, to_numpy=to_numpy)
    got, want = (got, want) if len(keys) > 1 else ((got,), (want,))
    for g, w in zip(got, want, strict=True):
        assert type(g) is type(w)
        np.testing.assert_equal(np.asarray(g, dtype=object), np.asarray(w, dtype=object))
        if to_numpy:
            assert g.dtype == w.dtype and g.shape == w.shape
    assert [d.keys() for d in dicts(a)] == [d.keys() for d in dicts(b)]  # CV cached alike


def test_set_writes_what_pymoo_writes_and_copies_views() -> None:
    a, b = population(1), population(1)
    rng = np.random.default_rng(5)
    F, G, CV = rng.random((9, 2)), rng.random((9, 4)), rng.random((9, 1))
    for pop, fn in ((a, fastpop.set), (b, fastpop.original_set)):
        fn(pop, "F", F, "G", G, "_CV", CV, "tag", "same for all", "rank", list(range(9)))
    for da, db in zip(dicts(a), dicts(b), strict=True):
        np.testing.assert_equal(da, db)
    assert not np.shares_memory(a[0].F, F) and a[0].F.flags["OWNDATA"]
    assert fastpop.set(Population.empty(0), "F", F[:0]) is None
    with pytest.raises(Exception, match="do not match"):
        fastpop.set(a, "F", F[:3])


def test_other_individual_types_use_pymoos_code() -> None:
    class Mine(Individual):
        pass

    pop = Population.create(Mine(X=np.ones(2)), Mine(X=np.zeros(2)))
    assert fastpop._members(pop) is None
    np.testing.assert_array_equal(fastpop.get(pop, "X"), [[1.0, 1.0], [0.0, 0.0]])


def test_a_design_run_is_bit_identical_with_and_without(original: None) -> None:
    cfg = parse_config({**CONFIG, "workers": 1})
    cfg = replace(cfg, stages=tuple(replace(s, starts=None) for s in cfg.stages))
    slow = run_design(cfg)
    fastpop.install()
    fast = run_design(cfg)
    for a, b in zip(slow.results, fast.results, strict=True):
        np.testing.assert_array_equal(a.X, b.X)
        np.testing.assert_array_equal(a.F, b.F)
        assert a.picked == b.picked


def test_installed_by_the_stage_module() -> None:
    import core.optimize.stage  # noqa: F401

    assert Population.get is fastpop.get and Population.set is fastpop.set
