"""The published JSON Schemas are generated from the format Structs and are current; the Structs accept what
the product writes and reads."""

from __future__ import annotations

import tomllib
from pathlib import Path

import msgspec
import pytest

from core.formats import schemas
from core.formats.config_file import ConfigFile
from core.formats.design import DesignFile, design_to_dict
from core.kinematics.presets import PRESETS

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", sorted(schemas.FORMATS))
def test_committed_schema_is_current(name):
    committed = ROOT / "assets" / "schemas" / f"{name}.schema.json"
    assert committed.read_text() == schemas.text(name), "run: python -m core.formats.schemas"


@pytest.mark.parametrize("path", sorted((ROOT / "assets" / "configs").glob("*.toml")), ids=lambda p: p.name)
def test_every_shipped_config_decodes_through_the_struct(path):
    msgspec.convert(tomllib.loads(path.read_text()), ConfigFile, strict=True)


def test_every_preset_as_written_decodes_through_the_design_struct():
    for p in PRESETS.values():
        d = {"name": p.name, "source": p.source, **design_to_dict(p.design())}
        f = msgspec.convert(d, DesignFile, strict=True)
        assert f.mechanism == p.mechanism.name


def test_the_schemas_describe_required_keys_and_ranges():
    design = schemas.schema("design")
    assert design["$defs"]["DesignFile"]["required"] == ["mechanism", "params"]
    cfg = schemas.schema("design-config")["$defs"]["ConfigFile"]["properties"]
    assert cfg["seed"]["minimum"] == 0 and cfg["seed"]["maximum"] == 2**32 - 1
    assert "hierarchical" in cfg["method"]["enum"] and cfg["method"]["default"] == "hierarchical"
