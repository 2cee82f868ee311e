"""JSON Schemas of the file formats, generated from their msgspec Structs, for editors that validate files.

    python -m core.formats.schemas [DIR]     # (re)write DIR/*.schema.json (default assets/schemas)

``tests/test_schemas.py`` checks that the committed files equal freshly generated ones.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import msgspec

from core.formats.config_file import ConfigFile
from core.formats.design import DesignFile
from core.formats.session import SessionFile
from core.formats.study import StudyFile

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "assets" / "schemas"
FORMATS: dict[str, tuple[Any, str]] = {
    "design-config": (ConfigFile, "A CLM Studio design-run configuration (clm design CONFIG.toml)"),
    "design": (DesignFile, "A CLM Studio design (clm simulate --design FILE.json)"),
    "session": (SessionFile, "A CLM Studio session (clm-studio --session FILE.json)"),
    "study": (StudyFile, "A CLM Studio study (clm study STUDY.toml)"),
}


def schema(name: str) -> dict[str, Any]:
    t, title = FORMATS[name]
    s: dict[str, Any] = msgspec.json.schema(t)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title, **s}


def text(name: str) -> str:
    return json.dumps(schema(name), indent=2, sort_keys=True) + "\n"


def write_all(directory: str | Path = DEFAULT_DIR) -> list[Path]:
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = []
    for name in FORMATS:
        p = d / f"{name}.schema.json"
        p.write_text(text(name))
        out.append(p)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m core.formats.schemas",
                                     description="(Re)write the file formats' JSON Schemas.")
    parser.add_argument("directory", nargs="?", default=str(DEFAULT_DIR),
                        help="where to write *.schema.json (default: assets/schemas)")
    for p in write_all(parser.parse_args(argv).directory):
        print(p)


if __name__ == "__main__":
    main()
