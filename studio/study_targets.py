"""Pipelines read from a session, with every stage target made safe to open: built-in targets by name, curves
only from the studio's own content-addressed store (a session never names a file to open)."""

from __future__ import annotations

import json
from typing import Any

from core.optimize.pipeline import Pipeline
from studio.target import CURVE_DIR, STORED_CURVE, TargetSpec, curve_file


def stage_target(value: object, target: TargetSpec, where: str) -> object:
    """A stage's target option from a session, made safe to open: a built-in target (``cycloid...``) as it is,
    a curve as the studio's own content-addressed copy; anything else (any other path) is refused.

    A session never names a file to open: an uploaded curve travels inside the session as points (the
    session's target) and stages refer to it by its content hash, which resolves only inside the studio's
    target store (``CURVE_DIR``), never to a path the file chose.
    """
    if not isinstance(value, str) or value.split(":", 1)[0] == "cycloid":
        return value  # non-strings are refused by the problem's own decoder
    name = _store_name(value)
    if name is None:
        raise ValueError(f"{where}: its target names a file ({value!r}); a session carries its curve as points "
                         f"and never opens a path")
    if target.curve is not None and curve_file(target.curve).name == name:
        return str(curve_file(target.curve))
    stored = CURVE_DIR / name
    if stored.is_file():
        return str(stored)
    raise ValueError(f"{where}: its target curve ({name}) is neither this session's curve nor in this studio's "
                     f"target store; upload that curve first")


def _retarget(data: dict[str, Any], target: TargetSpec, what: str = "pipeline") -> dict[str, Any]:
    """Pipeline data whose stage targets are safe to open (:func:`stage_target`): the stages copied, the
    results shared with ``data`` (branches naming one stored result hold one copy of its arrays)."""
    out = dict(data)
    if "stages" in out:
        out["stages"] = json.loads(json.dumps(out["stages"]))
    for i, opts in _stage_options(out):
        if "target" in opts:
            opts["target"] = stage_target(opts["target"], target, f"{what} stage {i + 1}")
    return out


def _stage_options(data: Any) -> list[tuple[int, dict[str, Any]]]:
    """(stage index, its problem's options) of pipeline data as ``Pipeline.to_json`` writes it (malformed
    parts skipped: the pipeline's own decoder names them)."""
    stages = data.get("stages", []) if isinstance(data, dict) else []
    out = []
    for i, s in enumerate(stages if isinstance(stages, list) else []):
        opts = s.get("problem", {}).get("options", {}) if isinstance(s, dict) else {}
        if isinstance(opts, dict):
            out.append((i, opts))
    return out


def _store_name(value: str) -> str | None:
    """The store name (``target-<hash>.csv``) a stage's curve option ends in, or None."""
    name = value.replace("\\", "/").rsplit("/", 1)[-1]
    return name if STORED_CURVE.fullmatch(name) else None


def _pipeline_from(data: object, target: TargetSpec, what: str) -> Pipeline | None:
    if data is None:
        return None
    if not isinstance(data, dict):
        raise ValueError(f"{what} must be an object, got {type(data).__name__}")
    try:
        return Pipeline.from_dict(_retarget(data, target, what))
    except (KeyError, TypeError, IndexError) as exc:
        raise ValueError(f"{what} is malformed ({type(exc).__name__}: {exc})") from None
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None


def stage_curve_names(data: Any) -> list[str]:
    """The store names (``target-<hash>.csv``) of the curves a pipeline's stages ran against (pipeline data as
    ``Pipeline.to_json`` writes it; anything malformed names none)."""
    values = [opts.get("target") for _, opts in _stage_options(data)]
    names = [_store_name(v) for v in values if isinstance(v, str) and v.split(":", 1)[0] != "cycloid"]
    return [n for n in names if n is not None]
