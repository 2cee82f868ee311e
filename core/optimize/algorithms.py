"""pymoo multi-objective algorithms that handle constraints, selectable by name with settings.

Offered (all rank infeasible members by total violation, all reproducible from a seed): ``nsga2``
(default; NSGA-II on our array-based core, ``core.optimize.evolve``), and from pymoo 0.6.2
``nsga2_pymoo`` (pymoo's NSGA-II, the reference it is tested against), ``nsga3``, ``unsga3``,
``agemoea``, ``agemoea2``, ``smsemoa``, ``spea2``, ``ctaea``, ``gde3``. Left out: MOEA/D, D-NSGA-II
and KGB (pymoo asserts they take no constraints), RVEA (keeps infeasible members it should drop),
CMOPSO (not reproducible from a seed with three objectives), R-NSGA-II/III (need reference points).

Every call builds fresh operator instances; nothing mutable is shared between runs.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from math import comb
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymoo.core.algorithm import Algorithm
from pymoo.core.repair import Repair
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.selection.tournament import TournamentSelection

from core.optimize.evolve.ranges import RANGES
from core.optimize.evolve.weights import simplex_lattice

DEFAULT_ALGORITHM = "nsga2"
DEFAULT_POP_SIZE = 200

# Options of the SBX / PM genetic algorithms (pymoo names in brackets):
#   crossover_prob (SBX prob), crossover_eta (SBX eta), mutation_prob (PM prob, per member),
#   mutation_prob_var (PM prob_var, per variable; default 1/n_var), mutation_eta (PM eta),
#   eliminate_duplicates.
GA_OPTIONS = ("crossover_prob", "crossover_eta", "mutation_prob", "mutation_prob_var", "mutation_eta",
              "eliminate_duplicates")
REF_OPTIONS = ("n_partitions",)
DE_OPTIONS = ("variant", "CR", "F")
DE_VARIANT = r"DE/(rand|best|target-to-best)/[12]/(bin|exp|line|hypercube)"  # what pymoo's DE parses


@dataclass(frozen=True)
class AlgorithmSpec:
    """An algorithm by name, its population size and its options (see ``ALGORITHMS``)."""

    name: str = DEFAULT_ALGORITHM
    pop_size: int = DEFAULT_POP_SIZE
    options: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "pop_size": self.pop_size, "options": dict(self.options)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> AlgorithmSpec:
        unknown = set(d) - {"name", "pop_size", "options"}
        if unknown:
            raise ValueError(f"unknown algorithm key {sorted(unknown)[0]!r}; known: name, pop_size, options")
        return cls(registered(str(d.get("name", DEFAULT_ALGORITHM))), int(d.get("pop_size", DEFAULT_POP_SIZE)),
                   dict(d.get("options", {})))


Build = Callable[[AlgorithmSpec, int, int, dict[str, Any]], Algorithm]


@dataclass(frozen=True)
class AlgorithmInfo:
    """How to build one algorithm: its option names, pymoo's operator defaults and a builder."""

    title: str
    options: tuple[str, ...]
    build: Build
    defaults: Mapping[str, Any] = field(default_factory=dict)


def reference_directions(n_obj: int, n_max: int, n_partitions: int | None = None) -> NDArray[np.float64]:
    """Das-Dennis directions: the most partitions giving at most ``n_max`` directions (at least 1). One objective
    has the single direction (1,) whatever the partitions (the search for the most would never end)."""
    if n_obj < 2:
        return np.ones((1, max(n_obj, 1)))
    # The CMOEAs' own lattice (the same points in the same order as pymoo's "das-dennis"); at least one partition.
    if n_partitions is None:
        return simplex_lattice(max(n_max, n_obj), n_obj)
    return simplex_lattice(comb(int(n_partitions) + n_obj - 1, n_obj - 1), n_obj)


def _sbx_pm(opts: dict[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    o = {**defaults, **opts}
    sbx_kw = {"n_offsprings": 1} if o.get("sbx_one_child") else {}
    return {
        "crossover": SBX(prob=float(o["crossover_prob"]), eta=float(o["crossover_eta"]), **sbx_kw),
        "mutation": PM(prob=float(o.get("mutation_prob", 0.9)), eta=float(o["mutation_eta"]),
                       prob_var=None if o.get("mutation_prob_var") is None else float(o["mutation_prob_var"])),
        "eliminate_duplicates": bool(o.get("eliminate_duplicates", True)),
    }


# Fresh selection / survival operators per algorithm. pymoo's own defaults are instances
# shared by every run, and some keep state (SPEA2's normalisation bounds leak between runs).
def _ops_nsga2() -> dict[str, Any]:
    from pymoo.algorithms.moo.nsga2 import binary_tournament
    from pymoo.operators.survival.rank_and_crowding import RankAndCrowding

    return {"selection": TournamentSelection(func_comp=binary_tournament), "survival": RankAndCrowding()}


def _ops_nsga3() -> dict[str, Any]:
    from pymoo.algorithms.moo.nsga3 import comp_by_cv_then_random

    return {"selection": TournamentSelection(func_comp=comp_by_cv_then_random)}


def _ops_unsga3() -> dict[str, Any]:
    from pymoo.algorithms.moo.unsga3 import comp_by_rank_and_ref_line_dist

    return {"selection": TournamentSelection(func_comp=comp_by_rank_and_ref_line_dist)}


def _ops_age() -> dict[str, Any]:
    from pymoo.algorithms.moo.nsga2 import binary_tournament

    return {"selection": TournamentSelection(func_comp=binary_tournament)}


def _ops_sms() -> dict[str, Any]:
    from pymoo.algorithms.moo.sms import LeastHypervolumeContributionSurvival, cv_and_dom_tournament

    return {"selection": TournamentSelection(func_comp=cv_and_dom_tournament),
            "survival": LeastHypervolumeContributionSurvival()}


def _ops_spea2() -> dict[str, Any]:
    from pymoo.algorithms.moo.spea2 import SPEA2Survival, spea_binary_tournament

    return {"selection": TournamentSelection(func_comp=spea_binary_tournament),
            "survival": SPEA2Survival(normalize=True)}


def _ops_ctaea() -> dict[str, Any]:
    from pymoo.algorithms.moo.ctaea import RestrictedMating, comp_by_cv_dom_then_random

    return {"selection": RestrictedMating(func_comp=comp_by_cv_dom_then_random)}



def _ga(cls_path: str, ops: Callable[[], dict[str, Any]], front_geometry: bool = False) -> Build:
    def build(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
        if front_geometry and n_obj < 2:  # AGE-MOEA(-II) fits the front's curvature: pymoo divides by zero on one
            raise ValueError(f"{spec.name} needs at least two objectives (it estimates the shape of the Pareto "
                             f"front); this problem has {n_obj}")
        cls = _import(cls_path)
        return cls(pop_size=spec.pop_size, seed=seed, **_sbx_pm(opts, ALGORITHMS[spec.name].defaults), **ops())

    return build


def _ref(cls_path: str, ops: Callable[[], dict[str, Any]], fixed_pop: bool = False) -> Build:
    def build(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
        cls = _import(cls_path)
        if fixed_pop and n_obj < 2:  # C-TAEA's population is its set of reference directions
            raise ValueError(f"{spec.name} needs at least two objectives (its population is one member per "
                             f"reference direction); this problem has {n_obj}")
        parts = opts.pop("n_partitions", None)
        dirs = reference_directions(n_obj, spec.pop_size, parts)
        kept = len(dirs) if fixed_pop else max(spec.pop_size, len(dirs))
        if parts is not None and kept != spec.pop_size:  # two settings that disagree: say so, don't pick one
            fits = len(reference_directions(n_obj, spec.pop_size))
            raise ValueError(f"{spec.name}: n_partitions = {parts} gives {len(dirs)} reference directions for {n_obj} "
                             f"objectives, so the population would be {kept}, not pop_size = {spec.pop_size}; set "
                             f"pop_size = {kept}, or leave n_partitions out (pop_size alone takes the largest lattice "
                             f"that fits: {fits} directions here)")
        kw = {**_sbx_pm(opts, ALGORITHMS[spec.name].defaults), **ops()}
        if fixed_pop:
            return cls(dirs, seed=seed, **kw)
        return cls(dirs, pop_size=max(spec.pop_size, len(dirs)), seed=seed, **kw)

    return build


def _array_nsga2(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.nsga2 import NSGA2

    o = {**ALGORITHMS[spec.name].defaults, **opts}
    return NSGA2(pop_size=spec.pop_size, seed=seed, crossover_prob=float(o["crossover_prob"]),
                 crossover_eta=float(o["crossover_eta"]), mutation_prob=float(o.get("mutation_prob", 0.9)),
                 mutation_prob_var=None if o.get("mutation_prob_var") is None else float(o["mutation_prob_var"]),
                 mutation_eta=float(o["mutation_eta"]), eliminate_duplicates=bool(o.get("eliminate_duplicates", True)))


def _imtcmo(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.imtcmo import IMTCMO

    return IMTCMO(pop_size=spec.pop_size, seed=seed)


def _cmoemt(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.cmoemt import CMOEMT

    return CMOEMT(pop_size=spec.pop_size, seed=seed, variant=str(opts.get("variant", "platemo")),
                  ahead=_flag(opts, "ahead", True))


def _flag(opts: dict[str, Any], key: str, default: bool) -> bool:
    v = opts.get(key, default)
    if not isinstance(v, bool):
        raise ValueError(f"option {key!r} must be true or false, got {v!r}")
    return v


def _drlos_emcmo(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.drlos_emcmo import DRLOSEMCMO

    return DRLOSEMCMO(pop_size=spec.pop_size, seed=seed, reward=str(opts.get("reward", "platemo")),
                      replay=str(opts.get("replay", "platemo")), success=str(opts.get("success", "platemo")))


def _cmoes(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.cmoes import CMOES

    return CMOES(pop_size=spec.pop_size, seed=seed, operator=str(opts.get("operator", "ga")))


def _mccmo(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.mccmo import MCCMO

    return MCCMO(pop_size=spec.pop_size, seed=seed, operator=str(opts.get("operator", "ga")))


def _moead_cmt(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from core.optimize.evolve.moead_cmt import MOEADCMT

    return MOEADCMT(pop_size=spec.pop_size, seed=seed, ahead=_flag(opts, "ahead", True))


def _de(spec: AlgorithmSpec, n_obj: int, seed: int, opts: dict[str, Any]) -> Algorithm:
    from pymoo.algorithms.moo.gde3 import GDE3
    from pymoo.operators.survival.rank_and_crowding import RankAndCrowding

    F = opts.get("F")
    return GDE3(pop_size=spec.pop_size, variant=str(opts.get("variant", "DE/rand/1/bin")),
                CR=float(opts.get("CR", 0.5)), F=tuple(F) if isinstance(F, (list, tuple)) else F, seed=seed,
                survival=RankAndCrowding())


def _import(path: str) -> type:
    module, name = path.rsplit(".", 1)
    from importlib import import_module

    cls: type = getattr(import_module(module), name)
    return cls


_MOO = "pymoo.algorithms.moo."
_SBX15 = {"crossover_prob": 0.9, "crossover_eta": 15.0, "mutation_eta": 20.0}
_SBX30 = {"crossover_prob": 1.0, "crossover_eta": 30.0, "mutation_eta": 20.0}

ALGORITHMS: dict[str, AlgorithmInfo] = {
    "nsga2": AlgorithmInfo("NSGA-II", GA_OPTIONS, _array_nsga2, _SBX15),
    "nsga2_pymoo": AlgorithmInfo("NSGA-II (pymoo)", GA_OPTIONS, _ga(_MOO + "nsga2.NSGA2", _ops_nsga2), _SBX15),
    "nsga3": AlgorithmInfo("NSGA-III", GA_OPTIONS + REF_OPTIONS, _ref(_MOO + "nsga3.NSGA3", _ops_nsga3), _SBX30),
    "unsga3": AlgorithmInfo("U-NSGA-III", GA_OPTIONS + REF_OPTIONS, _ref(_MOO + "unsga3.UNSGA3", _ops_unsga3), _SBX30),
    "agemoea": AlgorithmInfo("AGE-MOEA", GA_OPTIONS, _ga(_MOO + "age.AGEMOEA", _ops_age, True), _SBX15),
    "agemoea2": AlgorithmInfo("AGE-MOEA2", GA_OPTIONS, _ga(_MOO + "age2.AGEMOEA2", _ops_age, True), _SBX15),
    "smsemoa": AlgorithmInfo("SMS-EMOA", GA_OPTIONS, _ga(_MOO + "sms.SMSEMOA", _ops_sms), _SBX15),
    "spea2": AlgorithmInfo("SPEA2", GA_OPTIONS, _ga(_MOO + "spea2.SPEA2", _ops_spea2), _SBX15),
    "ctaea": AlgorithmInfo("C-TAEA", GA_OPTIONS + REF_OPTIONS, _ref(_MOO + "ctaea.CTAEA", _ops_ctaea, fixed_pop=True),
                           {**_SBX30, "sbx_one_child": True}),
    "gde3": AlgorithmInfo("GDE3", DE_OPTIONS, _de),
    "cmoemt": AlgorithmInfo("CMOEMT", ("variant", "ahead"), _cmoemt),
    "cmoes": AlgorithmInfo("CMOES", ("operator",), _cmoes),
    "drlos_emcmo": AlgorithmInfo("DRLOS-EMCMO", ("reward", "replay", "success"), _drlos_emcmo),
    "imtcmo": AlgorithmInfo("IMTCMO", (), _imtcmo),
    "mccmo": AlgorithmInfo("MCCMO", ("operator",), _mccmo),
    "moead_cmt": AlgorithmInfo("MOEA/D-CMT", ("ahead",), _moead_cmt),
}


def algorithm_names() -> tuple[str, ...]:
    return tuple(ALGORITHMS)


def registered(name: str) -> str:
    """The registered name a name reads in any case (``CMOES`` -> ``cmoes``), else the name unchanged (refused with
    :func:`unknown_algorithm` later): configs, sessions and ``clm moea`` take the same spellings."""
    return next((k for k in ALGORITHMS if k == str(name).lower()), name)


def _plain(text: str) -> str:
    return re.sub(r"[^0-9a-z]", "", text.casefold())


def suggestion(name: str) -> str:
    """``did you mean 'moead_cmt' (MOEA/D-CMT)?`` for a name that is a registered algorithm's published title or
    its name in other spelling (``NSGA-II``, ``nsga-2``, ``MOEA/D-CMT``), else the nearest names by spelling, else ""
    (the studio shows titles that configs do not take, so a student typed them)."""
    import difflib

    plain = _plain(str(name))
    same = [k for k, a in ALGORITHMS.items() if plain in (_plain(k), _plain(a.title))]
    near = same or difflib.get_close_matches(plain, [_plain(k) for k in ALGORITHMS], n=3, cutoff=0.6)
    names = [k for k in ALGORITHMS if k in same or _plain(k) in near]
    return "did you mean " + " or ".join(f"{k!r} ({ALGORITHMS[k].title})" for k in names) + "?" if names else ""


def unknown_algorithm(name: object) -> str:
    """The one-line refusal of an algorithm name: ``unknown algorithm 'NSGA-II'; did you mean 'nsga2' (NSGA-II)?
    Known: ...``."""
    hint = suggestion(str(name))
    known = ", ".join(ALGORITHMS)
    return f"unknown algorithm {name!r}; " + (f"{hint} Known: {known}" if hint else f"known: {known}")


def validate(spec: AlgorithmSpec) -> None:
    """Raise ValueError naming the problem if the spec cannot be built."""
    if spec.name not in ALGORITHMS:
        raise ValueError(unknown_algorithm(spec.name))
    if not isinstance(spec.pop_size, int) or isinstance(spec.pop_size, bool) or spec.pop_size < 2:
        raise ValueError(f"algorithm pop_size must be an integer >= 2, got {spec.pop_size!r}")
    info = ALGORITHMS[spec.name]
    for key, value in spec.options.items():
        if key not in info.options:
            known = ", ".join(info.options)
            raise ValueError(f"unknown option {key!r} for {spec.name}; " + (f"known: {known}" if known else
                                                                             "it takes no options"))
        if key == "variant" and spec.name == "gde3" and not re.fullmatch(DE_VARIANT, str(value)):
            raise ValueError(f"option 'variant' of gde3 must read DE/<rand|best|target-to-best>/<1|2>/"
                             f"<bin|exp|line|hypercube>, got {value!r}")
        if key in RANGES and value is not None:
            lo, hi = RANGES[key]
            values = value if isinstance(value, (list, tuple)) else [value]
            for v in values:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                    raise ValueError(f"option {key!r} of {spec.name} must be a number in [{lo:g}, {hi:g}], got {v!r}")


def make_algorithm(spec: AlgorithmSpec, n_obj: int, seed: int, repair: Repair | None = None) -> Algorithm:
    """A fresh pymoo algorithm for ``n_obj`` objectives, seeded.

    Args:
        spec: name, population size and options.
        n_obj: number of objectives (reference-direction algorithms need it).
        seed: the algorithm's random seed (pymoo draws every random number from it).
        repair: applied to every new member before evaluation (initial sample and offspring).
    """
    validate(spec)
    alg = ALGORITHMS[spec.name].build(spec, n_obj, int(seed), dict(spec.options))
    if repair is not None:
        # Set on every holder: GDE3 builds its DE mating without the algorithm's repair.
        for holder in (alg, getattr(alg, "initialization", None), getattr(alg, "mating", None)):
            if holder is not None and hasattr(holder, "repair"):
                holder.repair = repair
    return alg
