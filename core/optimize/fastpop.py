"""Faster ``Population.get`` / ``Population.set`` for pymoo 0.6 (same values, same copies).

pymoo keeps a population as an array of ``Individual`` objects and reads or writes an attribute
of every member through ``Individual.get`` / ``Individual.set``, which call ``hasattr`` first
(running a property such as ``CV`` twice). At population 200 these loops were about 30 % of a
stage's CPU time (the problems themselves are vectorized). :func:`install` replaces the two
methods by versions that touch the plain attributes behind pymoo's ``X``, ``F``, ``G``, ``H``
properties (and other plain attributes) directly and call pymoo's own code for everything else:
other keys, keyword options, subclasses of ``Individual``. ``tests/test_fastpop.py`` checks
both against pymoo's originals and that a whole design run is bit-identical.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pymoo.core.individual import Individual
from pymoo.core.population import Population, interleaving_args

# pymoo properties that only read or write the attribute behind them.
SLOTS = {"X": "_X", "F": "_F", "G": "_G", "H": "_H"}

original_get = Population.get
original_set = Population.set


def _members(pop: Any) -> list[Individual] | None:
    """The members as a list, or None if any is not a plain Individual (then pymoo's code runs)."""
    if pop.ndim != 1:
        return None
    inds = pop.tolist()
    return inds if all(type(i) is Individual for i in inds) else None


def _cv(ind: Individual) -> Any:
    cv = ind.__dict__["_CV"]
    return cv if (cv is not None and ind.config["cache"]) else ind.CV


def _values(inds: list[Individual], key: str) -> list[Any]:
    slot = SLOTS.get(key)
    if slot is not None:
        return [i.__dict__[slot] for i in inds]
    if key == "CV":
        return [_cv(i) for i in inds]
    if key == "FEAS":
        return [_cv(i) <= i.config.get("cv_eps", 0.0) for i in inds]
    return [i.get(key) for i in inds]


def get(self: Any, *args: str, to_numpy: bool = True, **kwargs: Any) -> Any:
    inds = _members(self) if not kwargs else None
    if inds is None:
        return original_get(self, *args, to_numpy=to_numpy, **kwargs)
    res = [_values(inds, key) for key in args]
    out = [np.array(v) for v in res] if to_numpy else res
    return out[0] if len(args) == 1 else tuple(out)


def set(self: Any, *args: Any, **kwargs: Any) -> Any:  # noqa: A001 - pymoo's method name
    inds = _members(self) if self.size else None
    if inds is None:
        return original_set(self, *args, **kwargs)
    kwargs = interleaving_args(*args, kwargs=kwargs)
    n = len(inds)
    for key, values in kwargs.items():
        is_iterable = hasattr(values, "__len__") and not isinstance(values, str)
        if is_iterable and len(values) != n:
            raise Exception("Population Set Attribute Error: Number of values and population size do not match!")
        # A plain attribute (not a property) is what Individual.set's hasattr/setattr would write.
        slot = SLOTS.get(key) or (key if key.startswith("_") and key in inds[0].__dict__ else None)
        for k, ind in enumerate(inds):
            val = values[k] if is_iterable else values
            if isinstance(val, np.ndarray) and not val.flags["OWNDATA"]:
                val = val.copy()  # pymoo copies views (its issue #455)
            if slot is not None:
                ind.__dict__[slot] = val
            else:
                ind.set(key, val)
    return self


def install() -> bool:
    """Patch pymoo's Population; False (and nothing patched) if its Individual has another layout."""
    probe = Individual()
    if not all(s in probe.__dict__ for s in (*SLOTS.values(), "_CV")) or not isinstance(probe.config, dict):
        return False
    Population.get = get
    Population.set = set
    return True


def uninstall() -> None:
    Population.get = original_get
    Population.set = original_set
