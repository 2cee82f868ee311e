"""DRLOS-EMCMO (Ming, Gong, Wang, Jin, IEEE/CAA JAS 11(4), 2024) on arrays: EMCMO with a Q-network choosing
its operator each generation, as the spec (§4) describes PlatEMO's version.

EMCMO: the main task (P1, the output; SPEA2 under constraint domination) and the unconstrained task (P2) share
offspring for the first 20 % of the evaluations; afterwards each takes either the other's parents (N/2 at
random) or its offspring, whichever a survival test says helps. The operator (GA: N/2 children a population,
N evaluations a generation; DE: N children, 2N) is drawn at random for the first 200 generations
(gen = ceil(FE/2N)); then a Q-network (``qnet``) trained on the replayed (state, action, reward, next state)
picks it, with 5 % random choices. The state is P1's (mean summed objectives, mean CV, summed spread).

Decisions (docs/algorithms.md): PlatEMO's reward (the state's *increase*), replay policy (a full buffer keeps
its first 500 records) and success constants (/100, /50) are the defaults; ``reward = "improvement"``,
``replay = "fifo"`` and ``success = "size"`` are the spec's labelled alternatives. The state uses the members
with finite objectives and violation (undefined members would make it infinite).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve import spea2
from core.optimize.evolve.base import ArrayAlgorithm, Arrays
from core.optimize.evolve.qnet import QNet
from core.optimize.evolve.selection import tournament
from core.optimize.evolve.variation import de_rand_1, ga

F64 = NDArray[np.float64]
EXPLORE_GENS, GREEDY, GAMMA, REPLAY, SAMPLE, FIRST_STEPS, UPDATE_STEPS, PERIOD, SWITCH = \
    200, 0.95, 0.9, 500, 200, 80_000, 8_000, 50, 0.2
OPTIONS = {"reward": ("platemo", "improvement"), "replay": ("platemo", "fifo"), "success": ("platemo", "size")}


def state(a: Arrays) -> F64:
    """(mean summed objectives, mean CV, summed objective spread) of the members with finite values."""
    ok = np.isfinite(a.F).all(axis=1) & np.isfinite(a.cv)
    if not ok.any():
        return np.zeros(3)
    F, cv = a.F[ok], a.cv[ok]
    return np.array([F.sum(axis=1).mean(), cv.mean(), (F.max(axis=0) - F.min(axis=0)).sum()])


def reward(s: F64, s_next: F64, kind: str = "platemo") -> float:
    """PlatEMO's reward, the state's increase (spec pitfall 1), or the improvement (f - f') + (cv - cv') + (d' - d)."""
    if kind == "platemo":
        return float(s_next.sum() - s.sum())
    return float((s[0] - s_next[0]) + (s[1] - s_next[1]) + (s_next[2] - s[2]))


class DRLOSEMCMO(ArrayAlgorithm):
    """DRLOS-EMCMO; the output population is the main task's (P1). Options: see the module doc."""

    NAME, MIN_POP, EVEN_POP = "drlos_emcmo", 4, True

    def __init__(self, pop_size: int = 100, reward: str = "platemo", replay: str = "platemo",
                 success: str = "platemo", **kwargs: Any) -> None:
        for key, value in (("reward", reward), ("replay", replay), ("success", success)):
            if value not in OPTIONS[key]:
                raise ValueError(f"drlos_emcmo {key} must be one of {', '.join(OPTIONS[key])}, got {value!r}")
        super().__init__(pop_size=pop_size, **kwargs)
        self.reward_kind, self.replay_kind, self.success_kind = reward, replay, success

    def _initialize_advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, p, rng = self.pop_size, self.problem, self.random_state
        self.xl, self.xu = np.asarray(p.xl, dtype=np.float64), np.asarray(p.xu, dtype=np.float64)
        p1 = self.evaluate(self.initial_X())
        p2 = self.evaluate(self.repaired(rng.uniform(self.xl, self.xu, size=(n, p.n_var))))
        self.fit1, self.fit2 = spea2.fitness(p1.F, p1.cv), spea2.fitness(p2.F)
        self.arrays, self.p2 = p1, p2
        self.phase = 1
        self.max_fe = self.budget(int(1.5 * n), 2 * n)
        self.replay: list[tuple[F64, int, float, F64]] = []
        self.model: QNet | None = None
        self.since_update = 0
        self.updates = 0
        self.log(phase=1.0, action=0.0, random_action=1.0, replay=0.0, updates=0.0,
                 feasible_ratio_P1=float((p1.cv <= 0).mean()), feasible_ratio_P2=float((p2.cv <= 0).mean()))

    # Operators -------------------------------------------------------------------------------------

    def _children(self, P: Arrays, fit: F64, action: int) -> F64:
        n, rng = self.pop_size, self.random_state
        if action == 1:  # GA: N/2 children
            mates = rng.integers(0, len(P), n) if self.phase == 1 else tournament((fit,), n, rng)
            return ga(P.X[mates[: n // 2]], P.X[mates[n // 2 :]], self.xl, self.xu, rng, half=True)
        if self.phase == 1:  # DE: one child per member, differences from random members
            a, b = rng.integers(0, len(P), len(P)), rng.integers(0, len(P), len(P))
        else:
            pool = tournament((fit,), 2 * len(P), rng)
            a, b = pool[: len(P)], pool[len(P) :]
        return de_rand_1(P.X, P.X[a], P.X[b], self.xl, self.xu, rng)

    # The Q-network -----------------------------------------------------------------------------------

    def _sample(self) -> list[tuple[F64, int, float, F64]]:
        k = min(SAMPLE, len(self.replay))
        return [self.replay[i] for i in self.random_state.choice(len(self.replay), k, replace=False)]

    def _build(self) -> None:
        batch = self._sample()
        X = np.array([[*s, a] for s, a, _, _ in batch])
        Y = np.array([[r, *s2] for _, _, r, s2 in batch])
        self.model = QNet(self.random_state)
        self.model.fit(X, Y, FIRST_STEPS)
        self.updates += 1

    def _update(self) -> None:
        assert self.model is not None
        batch = self._sample()
        X = np.array([[*s, a] for s, a, _, _ in batch])
        q = self.model.predict(X)
        y = np.array([r for _, _, r, _ in batch]) + GAMMA * float(q.max())  # spec pitfall 2: a constant shift
        self.model.fit(X, np.repeat(y[:, None], 4, axis=1), UPDATE_STEPS)
        self.updates += 1

    def _choose(self, s: F64, gen: int) -> tuple[int, bool, float, float]:
        rng = self.random_state
        q1 = q2 = float("nan")
        if gen <= EXPLORE_GENS:
            return int(rng.integers(1, 3)), True, q1, q2
        if self.model is None:
            self._build()
            return int(rng.integers(1, 3)), True, q1, q2
        q = self.model.predict(np.array([[*s, 1.0], [*s, 2.0]]))
        q1, q2 = float(q[0]), float(q[1])
        if rng.random() >= GREEDY:
            return int(rng.integers(1, 3)), True, q1, q2
        return (1 if q1 >= q2 else 2), False, q1, q2

    # The loop ------------------------------------------------------------------------------------

    def _advance(self, infills: Any = None, **kwargs: Any) -> None:
        n, rng = self.pop_size, self.random_state
        p1, p2 = self.arrays, self.p2
        assert p1 is not None
        gen = math.ceil(self.evaluator.n_eval / (2 * n))
        s = state(p1)
        action, random_action, q1, q2 = self._choose(s, gen)
        c1, c2 = self._children(p1, self.fit1, action), self._children(p2, self.fit2, action)
        off = self.evaluate(self.repaired(np.vstack([c1, c2])))
        o1, o2 = off.take(np.arange(len(c1))), off.take(np.arange(len(c1), len(off)))
        succ1 = succ2 = float("nan")
        t1 = t2 = -1.0
        cuts: spea2.Cuts | None = None
        if self.phase == 1:
            pool1, pool2 = Arrays.concat(p1, o1, o2), Arrays.concat(p2, o2, o1)
            cuts = {}  # all feasible: P1's and P2's pools cut the same members
            order, self.fit1, _ = spea2.select(pool1.F, n, pool1.cv, cuts=cuts)
            new1 = pool1.take(order)
            if self.evaluator.n_eval / self.max_fe >= SWITCH:
                self.phase = 2
        else:
            d1, d2 = (100.0, 50.0) if self.success_kind == "platemo" else (float(n), float(len(o1)))
            trial2 = Arrays.concat(p2, o2)
            m2 = spea2.survivors(trial2.F, n, trial2.cv)
            succ1 = m2[: len(p2)].sum() / d1 - m2[len(p2) :].sum() / d2
            m1 = spea2.survivors(Arrays.concat(p1, o1).F, n)
            succ2 = m1[: len(p1)].sum() / d1 - m1[len(p1) :].sum() / d2
            extra1 = p2.take(rng.choice(len(p2), n // 2, replace=False)) if succ1 > 0 else o2
            pool1 = Arrays.concat(p1, o1, extra1)
            order, self.fit1, _ = spea2.select(pool1.F, n, pool1.cv)
            new1 = pool1.take(order)
            extra2 = new1.take(rng.choice(len(new1), n // 2, replace=False)) if succ2 > 0 else o1  # pitfall 7
            pool2 = Arrays.concat(p2, o2, extra2)
            t1, t2 = float(succ1 > 0), float(succ2 > 0)
        order2, self.fit2, _ = spea2.select(pool2.F, n, None, cuts=cuts)
        self.p2 = pool2.take(order2)
        self.arrays = new1
        s_next = state(new1)
        r = reward(s, s_next, self.reward_kind)
        self.replay.append((s, action, r, s_next))
        if len(self.replay) > REPLAY:
            self.replay.pop(-1 if self.replay_kind == "platemo" else 0)  # PlatEMO keeps its first 500
        if self.model is not None:
            self.since_update += 1
            if self.since_update > PERIOD:
                self._update()
                self.since_update = 0
        self.log(phase=float(self.phase), action=float(action), random_action=float(random_action), q1=q1, q2=q2,
                 s1=float(s[0]), s2=float(s[1]), s3=float(s[2]), reward=r, replay=float(len(self.replay)),
                 updates=float(self.updates), succ1=float(succ1), succ2=float(succ2), parents_to_P1=t1,
                 parents_to_P2=t2, fe_generation=float(len(off)), feasible_ratio_P1=float((new1.cv <= 0).mean()),
                 feasible_ratio_P2=float((self.p2.cv <= 0).mean()))
