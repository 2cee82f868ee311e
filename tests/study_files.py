"""A tiny study file the study tests share: subtask 2 of the Stephenson-I design from the paper's X1."""

from __future__ import annotations

from pathlib import Path

CONFIG = Path(__file__).resolve().parents[1] / "assets" / "configs" / "stephenson1_cycloid.toml"


def tiny_study(*algorithms: str, pop: int = 12, seeds: str = "1..2", budget: int = 120) -> str:
    """The study's TOML text: each algorithm at population ``pop``, one case, ``budget`` evaluations a run."""
    blocks = "".join(f'[[algorithms]]\nname = "{a}"\npop_size = {pop}\n' for a in algorithms)
    return (f'name = "tiny"\nseeds = "{seeds}"\n{blocks}[[cases]]\nname = "subtask2"\nconfig = "{CONFIG}"\n'
            f'stages = ["subtask2"]\nstart = "stephenson1/X1"\nbudget = {budget}\n')
