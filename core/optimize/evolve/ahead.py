"""Children of a one-at-a-time MOEA/D loop, evaluated ahead in one batch with the same results.

CMOEMT's task 2 and MOEA/D-CMT make a child, evaluate it and let it replace neighbours before the next child is
made from the populations as they now are. Evaluating one child per call costs ~0.1-0.3 ms against ~8 us a member
in a batch. No random number those loops draw depends on what the populations hold, so the children can first be
made in the loop's order (the same random numbers) from the generation's starting populations and evaluated in one
call. The loop then runs as published: a child none of whose parents a replacement has changed before its turn is
the child the loop makes, so its evaluation is used; any other child is made again from the random numbers it drew
(the generator's state is kept for each) and evaluated alone.

The evaluator counts the loop's evaluations (one per child), as the published algorithm spends them; the children
evaluated ahead and then made again (``missed``) are extra calls of the problem, reported in the trace. With
``enabled`` False every child is made again and evaluated alone: the published loop, call for call.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from core.optimize.evolve.base import Arrays

if TYPE_CHECKING:
    from core.optimize.evolve.base import ArrayAlgorithm

F64 = NDArray[np.float64]
Child = Callable[[], tuple[F64, Callable[[], bool]]]
"""Makes a child ``(1, d)`` with the algorithm's generator; returns it and a test: has a parent changed since."""


class Ahead:
    """The children of one generation's loop: :meth:`add` each in the loop's order, then :meth:`take` each in
    that order between the replacements, then :meth:`close`."""

    def __init__(self, alg: ArrayAlgorithm, enabled: bool = True) -> None:
        self.alg, self.enabled = alg, enabled
        self.rng: np.random.Generator = alg.random_state
        self.made: list[tuple[Mapping[str, Any], Child, Callable[[], bool]]] = []
        self.X: list[F64] = []
        self.Y: Arrays | None = None
        self.missed = 0

    def add(self, child: Child) -> None:
        state = self.rng.bit_generator.state
        x, changed = child()
        self.made.append((state, child, changed))
        self.X.append(x)

    def take(self, j: int) -> Arrays:
        """Child ``j`` evaluated, as the loop makes it now (call in order, after the replacements before it)."""
        if j == 0:
            self.end = self.rng.bit_generator.state  # past every child's random numbers
            if self.enabled:
                self.Y = self.alg.evaluate(self.alg.repaired(np.vstack(self.X)))
        state, child, changed = self.made[j]
        if self.Y is not None and not changed():
            return self.Y.take(np.array([j]))
        self.rng.bit_generator.state = state
        x, _ = child()
        self.rng.bit_generator.state = self.end
        if self.Y is not None:
            self.missed += 1
        return self.alg.evaluate(self.alg.repaired(x))

    def close(self) -> int:
        """Counts the loop's evaluations only; returns how many children were evaluated ahead and not used."""
        self.alg.evaluator.n_eval -= self.missed
        return self.missed
