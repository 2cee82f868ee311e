"""Finished studies (``clm study --out DIR``) as the Studies panel reads them: read-only, inside the study's own
directory, size-capped. Pure functions of the files (no viser), tested without a browser."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from core.analysis.targets import read_user_file
from core.kinematics.design import Design
from core.optimize.pipeline import Pipeline
from core.study.store import current_rows, read_study
from studio.target import TargetSpec

MAX_RUN_BYTES = 256 * 2**20
MAX_STUDIES = 200


@dataclass(frozen=True)
class StudyRun:
    """One finished cell: case, algorithm, seed, its metrics, and its result file (relative to the study)."""

    case: str
    algorithm: str
    seed: int
    metrics: dict[str, float]
    result_path: str
    title: str = ""  # the study's label of its algorithm ("NSGA-II"); its name when it has none

    @property
    def named(self) -> str:
        return self.title or self.algorithm

    @property
    def label(self) -> str:
        m = self.metrics
        # The RTCLM's are its deviations (rehearsal 6: its runs were listed without a number to choose by).
        shown = " · ".join(f"{k} {m[k]:.3g}" for k in ("mse", "S", "I", "h_s", "dh6", "dh4")
                           if isinstance(m.get(k), int | float))
        return f"{self.case} · {self.named} · seed {self.seed}" + (f" · {shown}" if shown else "")


def find_studies(folder: Path) -> list[Path]:
    """Study directories (holding ``study.sqlite``) in ``folder`` or one level below it, sorted by name."""
    if not folder.is_dir():
        # By its full path: the default "runs" read as a folder the studio should have, not one beside its start.
        raise ValueError(f"{folder.absolute()} is not a folder (a relative folder is read from where the studio "
                         "was started)" if not folder.is_absolute() else f"{folder} is not a folder")
    found = [folder] if (folder / "study.sqlite").is_file() else []
    for d in sorted(folder.iterdir()):
        if d.is_dir() and (d / "study.sqlite").is_file():
            found.append(d)
        if len(found) >= MAX_STUDIES:
            break
    return found


def study_rows(directory: Path) -> tuple[str, list[dict[str, Any]]]:
    """(study name, the rows of its current cells) from ``study.sqlite``, opened read-only
    (``core.study.store.read_study``); ValueError if it is not a study. Each row gains ``title``: the study file's
    label of its algorithm (``NSGA-II``), as the report names it."""
    meta, rows = read_study(directory)
    study = meta.get("study")  # clm study keeps its name and the algorithms' labels in meta "study"
    name = study.get("name") if isinstance(study, dict) and isinstance(study.get("name"), str) else directory.name
    labels = study.get("labels") if isinstance(study, dict) else None
    labels = labels if isinstance(labels, dict) else {}
    # The study as its file last ran, as its report counts it: not the runs of removed seeds or changed settings.
    kept = current_rows(study if isinstance(study, dict) else None, rows)
    # In the study file's order, its reference marked, as the report has them (rehearsal 6: alphabetical, IMTCMO
    # before the reference NSGA-II, and nothing said which one the others are compared with).
    listed = study.get("algorithms") if isinstance(study, dict) else None
    order: list[Any] = listed if isinstance(listed, list) else []
    ref = study.get("reference") if isinstance(study, dict) else None
    rank = {a: k for k, a in enumerate(order)}
    cases = {c: k for k, c in enumerate(dict.fromkeys(r["case"] for r in kept))}  # within each case, in its place
    kept = sorted(kept, key=lambda r: (cases[r["case"]], rank.get(r["algorithm"], len(rank)), r["algorithm"],
                                       r["seed"]))

    def title(a: str) -> str:
        return str(labels.get(a, a)) + (" (reference)" if a == ref else "")

    return str(name), [dict(r, title=title(r["algorithm"])) for r in kept]


def flat_metrics(m: dict[str, Any]) -> dict[str, float]:
    """A run's numbers: its pick's metrics (mse, S, I, h_s, ...) and the run's own (feasible ratio, time, ...)."""
    out = {k: float(v) for k, v in (m.get("pick") or {}).items() if isinstance(v, int | float)}
    out.update({k: float(v) for k, v in m.items() if isinstance(v, int | float) and not isinstance(v, bool)})
    return out


def finished_runs(rows: list[dict[str, Any]]) -> list[StudyRun]:
    """The done cells with their metrics, HV and IGD+ among them (measured in each case's normalised space, as the
    report measures them: the Studies panel offered neither, though the report's table starts with them)."""
    from core.study.stats import run_values

    quality: dict[int, dict[str, float]] = {}
    for case in dict.fromkeys(r["case"] for r in rows):
        for r, v in run_values([r for r in rows if r["case"] == case]):
            quality[id(r)] = {k: v[k] for k in ("hv", "igd_plus") if k in v}
    return [StudyRun(r["case"], r["algorithm"], int(r["seed"]), {**flat_metrics(r["metrics"] or {}),
                                                                 **quality.get(id(r), {})},
                     r["result_path"], str(r.get("title") or ""))
            for r in rows if r["status"] == "done" and r["result_path"]]


def picked_design(directory: Path, run: StudyRun) -> Design:
    """The design a run picked in its last stage; only a file inside the study directory is read."""
    return picked(directory, run)[0]


def picked(directory: Path, run: StudyRun) -> tuple[Design, str | None]:
    """The design a run picked in its last stage, and the target that stage ran against (its problem's ``target``
    option, ``cycloid:L=..`` or a CSV path; None for a problem without one, the RTCLM's); ValueError naming the
    problem. Only a file inside the study directory is read."""
    root = directory.resolve()
    path = (root / run.result_path).resolve()
    if root not in path.parents:
        raise ValueError(f"{run.result_path!r} is outside the study directory")
    data = json.loads(read_user_file(path, MAX_RUN_BYTES, what="study run"))
    if not isinstance(data, dict) or not isinstance(data.get("pipeline"), dict):
        raise ValueError(f"{run.result_path}: not a run with a pipeline")
    pipe = Pipeline.from_dict(data["pipeline"])
    last = next((r for r in reversed(pipe.results) if r is not None and r.pop > 0), None)
    if last is None:
        raise ValueError(f"{run.result_path}: the run has no result to pick from")
    i = last.picked if last.picked is not None else last.shortlist.first
    if i is None:
        raise ValueError(f"{run.result_path}: the run picked nothing")
    problem = last.settings.get("problem")
    options = problem.get("options") if isinstance(problem, dict) else None
    target = options.get("target") if isinstance(options, dict) else None
    return last.pick(i), target if isinstance(target, str) else None


def same_target(ran: str, current: str) -> bool:
    """True if two ``target`` options name the same target: equal cycloid parameters (to 1e-9), or the same
    curve file name (a study keeps its own copy of an uploaded curve, under the name it had)."""
    from core.analysis.targets import cycloid_params

    cyc = [t.split(":", 1)[0] == "cycloid" for t in (ran, current)]
    if all(cyc):
        try:
            a, b = cycloid_params(ran), cycloid_params(current)
        except ValueError:
            return ran == current
        return all(abs(a[k] - b[k]) <= 1e-9 * max(1.0, abs(b[k])) for k in a)
    return not any(cyc) and Path(ran).name == Path(current).name


def target_words(option: str) -> str:
    """A ``target`` option as the Target panel says it (``compound cycloid L = 300 mm, H = 100 mm, T = 2 s``, or
    ``curve ellipse.csv``)."""
    from core.analysis.targets import cycloid_params

    if option.split(":", 1)[0] == "cycloid":
        try:
            p = cycloid_params(option)
        except ValueError:
            return option
        return TargetSpec(p["L"], p["H"], p["T"]).label()  # as the Target panel says the editor's
    return f"curve {Path(option).name}"
