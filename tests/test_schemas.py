"""The published JSON Schemas are generated from the format Structs and are current; the Structs accept what
the product writes and reads."""

from __future__ import annotations

import re
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


@pytest.mark.parametrize("bad, why", [(float("nan"), "must be finite, got nan"),
                                      (-3.0, "is a length and must be > 0 mm, got -3 mm"),
                                      (2e6, "must be within +-1e+06 mm, got 2e+06 mm")])
def test_a_design_no_reader_takes_back_is_not_written(bad, why):
    # Rehearsal 8: design_to_dict wrote NaN and negative lengths that design_from_dict then refused, far from
    # where the file was made. Every member that is written reads back.
    from core.formats.design import design_from_dict
    from core.kinematics.design import Design

    good = PRESETS["fourbar/chebyshev"].design()
    assert design_from_dict(design_to_dict(good)).named() == good.named()
    spec = next(p for p in good.mechanism.params if p.kind == "length")
    params = good.params.copy()
    params[0, good.mechanism.param_names.index(spec.name)] = bad
    with pytest.raises(ValueError, match=rf"^cannot write fourbar member 0: {spec.name} .*{re.escape(why)}"):
        design_to_dict(Design(good.mechanism, params, good.output))
