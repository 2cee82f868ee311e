"""Decoding user files through msgspec Structs, with our error style: one line that names the key path.

``decode(data, Type)`` turns msgspec's "Expected `int` >= 1 - at `$.stages[2].n_gen`" into
``stages[2].n_gen: must be >= 1, got 0``; unknown keys list the known ones, enums their choices. Before
decoding, ``check_tree`` refuses non-finite numbers and nesting deeper than any of our formats needs.
"""

from __future__ import annotations

import math
import re
from typing import Any, TypeVar

import msgspec
from msgspec import inspect as mi

from core.kinematics.checks import MAX_SAMPLES  # noqa: F401  (the formats' cap is the API's)

T = TypeVar("T")
MAX_DEPTH = 32
MAX_SEED = 2**32 - 1
MAX_POP = 100_000  # members per generation (~50 kB each in a design stage: ~5 GB at the cap)
MAX_GEN = 1_000_000  # generations of a stage

_KINDS = {"int": "an integer", "float": "a number", "str": "a string", "bool": "true or false", "array": "an array",
          "object": "a table", "null": "nothing"}
_AT = re.compile(r" - at `\$(.*)`$")
_SEG = re.compile(r"\.([A-Za-z_][A-Za-z_0-9]*)|\[(\d+|\.\.\.)\]")


def kind(v: Any) -> str:
    """How a value reads in a message: ``a string``, ``an integer``, ``a table``..."""
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
            dict: "a table"}.get(type(v), type(v).__name__)


def join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json.loads``'s ``object_pairs_hook`` refusing a repeated key: a hand-edited file with "r1" twice
    silently took the last value (msgspec and ``json`` both do)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"key {key!r} appears twice in one object")
        out[key] = value
    return out


def check_tree(data: Any, path: str = "", depth: int = 0) -> None:
    """ValueError for a non-finite number or nesting deeper than ``MAX_DEPTH`` anywhere in ``data``."""
    if depth > MAX_DEPTH:
        raise ValueError(f"{path or 'file'}: nested deeper than {MAX_DEPTH} levels")
    if isinstance(data, float) and not math.isfinite(data):
        raise ValueError(f"{path}: must be finite, got {data}")
    if isinstance(data, dict):
        for k, v in data.items():
            check_tree(v, join(path, str(k)), depth + 1)
    elif isinstance(data, list):
        for i, v in enumerate(data):
            check_tree(v, join(path, i), depth + 1)


def _segments(raw: str) -> list[str | int]:
    return [m.group(1) if m.group(1) is not None else (int(m.group(2)) if m.group(2).isdigit() else "...")
            for m in _SEG.finditer(raw)]


def _value(data: Any, segs: list[str | int]) -> Any:
    for s in segs:
        if isinstance(s, int) and isinstance(data, list) and s < len(data):
            data = data[s]
        elif isinstance(s, str) and isinstance(data, dict) and s in data:
            data = data[s]
        else:
            return None
    return data


def _type_at(t: Any, segs: list[str | int]) -> Any:
    """The msgspec type info at a path (Structs by field name, lists by index, dicts by any key), or None."""
    info: Any = mi.type_info(t) if not isinstance(t, mi.Type) else t
    for s in segs:
        if isinstance(info, mi.UnionType):  # step into the member that can hold this segment
            fits = (mi.StructType, mi.DictType) if isinstance(s, str) else (mi.ListType, mi.VarTupleType, mi.DictType)
            info = next((x for x in info.types if isinstance(x, fits)), None)
        if isinstance(info, mi.StructType) and isinstance(s, str):
            info = next((f.type for f in info.fields if f.encode_name == s), None)
        elif isinstance(info, mi.ListType | mi.VarTupleType) and isinstance(s, int):
            info = info.item_type
        elif isinstance(info, mi.DictType):
            info = info.value_type
        else:
            return None
    return info


def _unwrap(info: Any, want: type = mi.StructType) -> Any:
    """The Struct (or another kind ``want``) inside an optional or union type."""
    if isinstance(info, mi.UnionType):
        inner = [x for x in info.types if isinstance(x, want)]
        return inner[0] if len(inner) == 1 else info
    return info


def _name(path: str) -> str:
    return path or "file"


def message(err: msgspec.ValidationError, data: Any, t: Any, prefix: str = "") -> str:
    """msgspec's validation error as one line in our style (see the module doc)."""
    text = str(err)
    m = _AT.search(text)
    raw = m.group(1) if m else ""
    body = text[: m.start()] if m else text
    segs = _segments(raw)
    path = prefix
    for s in segs:
        path = join(path, s) if s != "..." else f"{path}[...]"
    got = _value(data, segs)
    if mm := re.match(r"Object contains unknown field `(.+)`", body):
        info = _unwrap(_type_at(t, segs))
        known = ", ".join(sorted(f.encode_name for f in info.fields)) if isinstance(info, mi.StructType) else ""
        return f"{join(path, mm.group(1))}: unknown key" + (f"; known: {known}" if known else "")
    if mm := re.match(r"Object missing required field `(.+)`", body):
        return f"{join(path, mm.group(1))}: missing"
    if mm := re.match(r"Invalid enum value (.+)", body):
        info = _unwrap(_type_at(t, segs), mi.LiteralType)
        choices = ", ".join(str(v) for v in info.values) if isinstance(info, mi.LiteralType) else ""
        return f"{_name(path)}: {mm.group(1)} is not one of {choices}" if choices else f"{_name(path)}: {body}"
    if mm := re.match(r"Expected `(\w+)` (>=|>|<=|<) (\S+)$", body):
        bound = mm.group(3)
        shown = bound if mm.group(1) == "int" else f"{float(bound):g}"
        return f"{_name(path)}: must be {mm.group(2)} {shown}, got {got!r}"
    if mm := re.match(r"Expected `array` of length (\d+), got (\d+)", body):
        return f"{_name(path)}: expected {mm.group(1)} items, got {mm.group(2)}"
    if mm := re.match(r"Expected `(.+)`, got `(\w+)`", body):
        wanted = [w.strip() for w in mm.group(1).split("|") if w.strip() != "null"]
        if wanted == ["bool"]:
            return f"{_name(path)}: expected true or false, got {got!r}"
        words = " or ".join(_KINDS.get(w, w) for w in wanted)
        return f"{_name(path)}: expected {words}, got {kind(got) if got is not None else _KINDS.get(mm.group(2))}"
    if mm := re.match(r"Expected `str` of length >= (\d+)", body):
        return f"{_name(path)}: must not be empty"
    return f"{_name(path)}: {body[:1].lower()}{body[1:]}"


def decode(data: Any, t: type[T], prefix: str = "") -> T:
    """``data`` (parsed TOML or JSON) as ``t``; ValueError with one line naming the key path otherwise."""
    check_tree(data, prefix)
    try:
        return msgspec.convert(data, t, strict=True)
    except msgspec.ValidationError as e:
        raise ValueError(message(e, data, t, prefix)) from None
