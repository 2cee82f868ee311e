"""Session versions 3-4: every stage result stored once, however many branches share it, its arrays packed;
(4) every target curve a study carries stored once too.

A study's pipelines (the current one and every branch) name their stage results by content hash; the
results sit once in ``study.results``. A result's pick is not part of its content (branches that picked
different members of one front share that front): it stays in the pipeline's ``picks``. Population
arrays (X, F, G, cv and every metric) are little-endian float64 in base64 with their shape: exact,
about half the size of decimal text. ``unpack_study`` gives back the version-2 shape, so everything
after it (the study's decoder, the pipeline's and the results' checks) is unchanged.

Version 4: the study's target and each branch's (the targets their stages ran against) name an uploaded
curve by content hash; the curves sit once in ``study.curves``, with every curve a pipeline's stages ran
against (by its store name), so a session carries all its curves.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import threading
from typing import Any

import numpy as np

from core.optimize.result import decode_array, encode
from studio.study_targets import stage_curve_names
from studio.target import stored_curve

ARRAYS = ("X", "F", "G", "cv")
PICK_KEYS = ("picked", "pick")
MAX_ELEMENTS = 10_000_000  # a packed array larger than this is refused before it is allocated


def pack_array(values: Any) -> dict[str, Any]:
    a = np.ascontiguousarray(decode_array(values), dtype="<f8")
    return {"shape": list(a.shape), "f64": base64.b64encode(a.tobytes()).decode("ascii")}


def unpack_array(packed: Any, where: str) -> Any:
    if not isinstance(packed, dict) or not isinstance(packed.get("f64"), str) or \
            not isinstance(packed.get("shape"), list):
        raise ValueError(f"{where}: expected a packed array {{shape, f64}}")
    shape = packed["shape"]
    if not all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= MAX_ELEMENTS for n in shape) \
            or len(shape) > 2 or int(np.prod(shape)) > MAX_ELEMENTS:
        raise ValueError(f"{where}: bad shape {shape!r}")
    try:
        raw = base64.b64decode(packed["f64"], validate=True)
    except (binascii.Error, ValueError):
        raise ValueError(f"{where}: not base64") from None
    if len(raw) != 8 * int(np.prod(shape)):
        raise ValueError(f"{where}: {len(raw)} bytes for shape {shape}")
    return encode(np.frombuffer(raw, dtype="<f8").reshape(shape))


def _content(result: dict[str, Any]) -> dict[str, Any]:
    blob = {k: v for k, v in result.items() if k not in PICK_KEYS}
    for k in ARRAYS:
        if k in blob:
            blob[k] = pack_array(blob[k])
    if isinstance(blob.get("metrics"), dict):
        blob["metrics"] = {str(k): pack_array(v) for k, v in blob["metrics"].items()}
    return blob


# Each result dict's packed content and hash, by the dict's identity: a study's results are the same dicts from one
# save to the next (``study.result_json``, a branch's data), and packing them again was most of a save. Kept for the
# dicts the last pack saw (each entry holds its dict, so an id is never another's).
_PACKED: dict[int, tuple[dict[str, Any], str, dict[str, Any]]] = {}
_PACKED_LOCK = threading.Lock()


def pack_study(study: dict[str, Any]) -> dict[str, Any]:
    """A study from ``Study.to_dict`` with its results stored once, by hash (a new dict)."""
    global _PACKED
    table: dict[str, Any] = {}
    with _PACKED_LOCK:
        cache, seen = _PACKED, {}

    def pack_pipeline(p: Any) -> Any:
        if not isinstance(p, dict):
            return p
        refs: list[str | None] = []
        for r in p.get("results", []):
            if r is None:
                refs.append(None)
                continue
            hit = cache.get(id(r))
            if hit is not None and hit[0] is r:
                key, blob = hit[1], hit[2]
            else:
                blob = _content(r)
                key = hashlib.sha256(json.dumps(blob, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:20]
            seen[id(r)] = (r, key, blob)
            table.setdefault(key, blob)
            refs.append(key)
        return {**p, "results": refs}

    curves: dict[str, Any] = {}

    def pack_target(t: Any) -> Any:
        if not isinstance(t, dict) or not isinstance(t.get("curve"), dict):
            return t
        key = hashlib.sha256(json.dumps(t["curve"], sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:20]
        curves.setdefault(key, t["curve"])
        return {**t, "curve": key}

    out = dict(study)
    out["pipeline"] = pack_pipeline(study.get("pipeline"))
    out["branches"] = [{**b, "pipeline": pack_pipeline(b.get("pipeline")),
                        **({"target": pack_target(b["target"])} if "target" in b else {})}
                       for b in study.get("branches", [])]
    if "target" in study:
        out["target"] = pack_target(study["target"])
    # The curves every stage ran against too (from this studio's store), so the file opens on another machine.
    for p in [study.get("pipeline"), *(b.get("pipeline") for b in study.get("branches", []))]:
        for name in stage_curve_names(p):
            curve = stored_curve(name)
            if curve is not None:
                curves.setdefault(name, curve)
    out["results"] = table
    if curves:
        out["curves"] = curves
    with _PACKED_LOCK:
        _PACKED = seen
    return out


def _unpack_curves(study: dict[str, Any]) -> dict[str, Any]:
    """A version-4 study with its targets' curves inline again (each the table's one object; the table stays
    for the study's decoder, which writes every curve to the store)."""
    if "curves" not in study:
        return study
    curves = study["curves"]
    if not isinstance(curves, dict) or not all(isinstance(c, dict) for c in curves.values()):
        raise ValueError("study.curves must map hashes to curves")

    def target(t: Any, where: str) -> Any:
        if not isinstance(t, dict) or not isinstance(t.get("curve"), str):
            return t
        if t["curve"] not in curves:
            raise ValueError(f"{where}: no curve {t['curve']!r} in study.curves")
        return {**t, "curve": curves[t["curve"]]}

    out = dict(study)
    if "target" in out:
        out["target"] = target(out["target"], "study.target")
    if isinstance(out.get("branches"), list):
        out["branches"] = [{**b, "target": target(b["target"], f"study.branches[{j}].target")}
                           if isinstance(b, dict) and "target" in b else b for j, b in enumerate(out["branches"])]
    return out


def unpack_study(study: Any) -> Any:
    """The version-2 shape of a packed study (results inline, picks set); ValueError naming the problem.
    A version-2 study (results inline) passes through unchanged."""
    if not isinstance(study, dict):
        return study
    study = _unpack_curves(study)
    if "results" not in study:
        return study
    table = study["results"]
    if not isinstance(table, dict):
        raise ValueError("study.results must map hashes to stage results")

    unpacked: dict[str, dict[str, Any]] = {}  # each result's arrays unpacked once, shared by the branches naming it

    def result(key: Any, pick: Any, where: str) -> Any:
        if key is None or isinstance(key, dict):  # nothing, or a version-2 result written inline
            return key
        if not isinstance(key, str) or not isinstance(table.get(key), dict):
            raise ValueError(f"{where}: no stage result {key!r} in study.results")
        if key not in unpacked:
            blob = dict(table[key])
            for k in ARRAYS:
                if k in blob:
                    blob[k] = unpack_array(blob[k], f"study.results[{key}].{k}")
            if isinstance(blob.get("metrics"), dict):
                blob["metrics"] = {m: unpack_array(v, f"study.results[{key}].metrics.{m}")
                                   for m, v in blob["metrics"].items()}
            unpacked[key] = blob
        return {**unpacked[key], "picked": pick}

    def unpack_pipeline(p: Any, where: str) -> Any:
        if not isinstance(p, dict) or not isinstance(p.get("results"), list):
            return p
        picks = p.get("picks")
        picks = picks if isinstance(picks, list) and len(picks) == len(p["results"]) else [None] * len(p["results"])
        return {**p, "results": [result(k, picks[j], f"{where}.results[{j}]") for j, k in enumerate(p["results"])]}

    out = {k: v for k, v in study.items() if k != "results"}
    out["pipeline"] = unpack_pipeline(study.get("pipeline"), "study.pipeline")
    branches = study.get("branches")
    if isinstance(branches, list):
        out["branches"] = [{**b, "pipeline": unpack_pipeline(b.get("pipeline"), f"study.branches[{j}].pipeline")}
                           if isinstance(b, dict) else b for j, b in enumerate(branches)]
    return out
