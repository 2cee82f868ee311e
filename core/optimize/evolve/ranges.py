"""The closed ranges of the numeric algorithm options, checked however an algorithm is made: a config, the CLI, the
studio, ``make_algorithm`` or a class built directly (``NSGA2(crossover_eta=-1)`` divided by zero)."""

from __future__ import annotations

from math import inf

RANGES = {"crossover_prob": (0.0, 1.0), "mutation_prob": (0.0, 1.0), "mutation_prob_var": (0.0, 1.0),
          "CR": (0.0, 1.0), "crossover_eta": (0.0, inf), "mutation_eta": (0.0, inf), "F": (0.0, inf)}
