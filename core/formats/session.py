"""The studio's session file (JSON) as msgspec Structs: the outer shell every session is decoded through.

The design, target, walk and run settings inside are checked again by their own decoders (which name
parameters with units); stage results inside a pipeline by ``core.optimize.pipeline``. What this adds:
types and ranges of every field, finite numbers only (non-finite result values are written as strings),
bounded nesting, and branch labels that are unique and non-empty.
"""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal

from msgspec import Meta, Struct

from core.formats.typed import decode, unique_keys

SESSION_FORMAT = "clm-studio-session"
READS_VERSIONS = (1, 2, 3, 4, 5, 6)  # 1: no walk, no study; 3: stage results once, by hash (studio.session_pack);
# 4: branches keep their target and study state, curves once by hash; 5: a target may carry the RTCLM's h6 and h4
# (an older studio then says "unsupported session version 5", not "unknown target key 'h6'"); 6: the cycloid an
# uploaded curve replaced, for "Back to the compound cycloid" after a reload
MAX_SESSION_BYTES = 64 * 2**20
Label = Annotated[str, Meta(min_length=1, max_length=200)]


class PlaybackFile(Struct, forbid_unknown_fields=True, frozen=True):
    playing: bool = True
    speed: float = 1.0
    angle: float = 0.0


class BranchFile(Struct, forbid_unknown_fields=True, frozen=True):
    label: Label
    pipeline: dict[str, Any]
    target: dict[str, Any] | None = None  # what its stages ran against (checked by the target's own decoder)
    shown: Any = {}  # the study's state when the branch was left (checked by the study's decoder)
    next_stage: str | None = None
    from_pick: bool = False


class StudyFile(Struct, forbid_unknown_fields=True, frozen=True):
    # pipeline, branches and shown are checked by the study's own decoder, whose messages say more
    # ("branch 2 must be an object with a pipeline"); the schema still documents their shape.
    pipeline: Any = None
    branches: list[BranchFile | Any] = []
    viewing: str | None = None
    shown: Any = {}
    next_stage: str | None = None
    from_pick: bool = False
    settings: dict[str, dict[str, Any]] = {}
    target: dict[str, Any] | None = None  # the target the pipeline's latest run ran against
    results: dict[str, dict[str, Any]] = {}  # version 3: stage results by content hash
    curves: dict[str, dict[str, Any]] = {}  # version 4: the targets' curves by content hash


class PlatesFile(Struct, forbid_unknown_fields=True, frozen=True):
    """The drawings' pivot hole diameter and plate width (mm; width None: three holes wide)."""

    hole: float
    width: float | None = None


class SessionFile(Struct, forbid_unknown_fields=True, frozen=True):
    """A CLM Studio session: the editor's design, target, walking view and playback, and the study."""

    format: Literal["clm-studio-session"]
    version: Literal[1, 2, 3, 4, 5, 6]
    design: dict[str, Any]
    target: dict[str, Any]
    preset: str | None = None
    walk: dict[str, Any] = {}
    playback: PlaybackFile = PlaybackFile()
    study: StudyFile | None = None
    cycloid: dict[str, Any] | None = None  # version 6: the cycloid the uploaded target curve replaced
    plates: PlatesFile | None = None  # from session 30, when set: the drawings' pin holes and plate width


def parse_json(content: str | bytes) -> Any:
    """JSON text (or UTF-8 bytes, BOM allowed) -> data; ValueError for bad text, a file over 64 MB or
    nesting deep enough to exhaust the parser."""
    if len(content) > MAX_SESSION_BYTES:
        raise ValueError(f"a session is at most {MAX_SESSION_BYTES // 2**20} MB, got {len(content) / 2**20:.0f} MB")
    try:
        text = content.decode("utf-8-sig") if isinstance(content, bytes) else content
        if text.strip():
            return json.loads(text, object_pairs_hook=unique_keys)
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text ({exc.reason})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON ({exc})") from None
    except RecursionError:
        raise ValueError("not a session: nested too deep") from None
    except ValueError as exc:  # unique_keys
        raise ValueError(f"not a session: {exc}") from None
    raise ValueError("the file is empty")  # QA (session 37): "not JSON (Expecting value: line 1 column 1 (char 0))"


def check_session(data: Any) -> SessionFile:
    """The session's shell decoded and checked; ValueError with one line naming the first problem."""
    if not isinstance(data, dict):
        raise ValueError(f"a session must be a JSON object, got {type(data).__name__}")
    if data.get("format") != SESSION_FORMAT:
        if "mechanism" in data and "params" in data:  # 'clm presets show' writes these: a design, not a session
            raise ValueError("this is a design file (mechanism and params), not a studio session; a session is "
                             "what 'Download session' saves")
        if "format" not in data:  # "format None" read as Python (lab rehearsal)
            raise ValueError(f"not a studio session: it has no \"format\" (a session's is {SESSION_FORMAT!r}); a "
                             "session is what 'Download session' saves")
        raise ValueError(f"not a studio session (format {data.get('format')!r}, expected {SESSION_FORMAT!r})")
    if data.get("version") not in READS_VERSIONS or isinstance(data.get("version"), bool):
        raise ValueError(f"unsupported session version {data.get('version')!r} (this studio reads "
                         f"{', '.join(str(v) for v in READS_VERSIONS)})")
    for key in ("design", "target"):
        if key not in data:
            raise ValueError(f"session has no {key!r}")
    f = decode(data, SessionFile)
    if f.study is not None:
        seen: dict[str, int] = {}
        for j, b in enumerate(f.study.branches):
            label = b.label if isinstance(b, BranchFile) else b.get("label") if isinstance(b, dict) else None
            if not isinstance(label, str) or not label.strip():
                continue  # the study's decoder names what is wrong with this branch
            if label in seen:
                raise ValueError(f"study.branches[{j}].label: {label!r} is already the label of branch "
                                 f"{seen[label] + 1}; branch labels must be unique")
            seen[label] = j
    return f
