"""A design configuration's output stage: the mirror flag is read and checked like every other key."""

from __future__ import annotations

import pytest

from core.formats.config import parse_config


def with_(output: dict) -> dict:  # type: ignore[type-arg]
    """A small valid configuration with the given output table."""
    return {
        "mechanism": "stephenson1",
        "output": output,
        "stages": [{"name": "predesign", "box": "global", "n_gen": 2, "pick": "best:f1"}],
    }


def test_output_mirror_is_read() -> None:
    c = parse_config(with_({"k": -1.0, "ox": 0.0, "oy": 0.0, "mirror": True}))
    assert c.start.output.mirror and c.start.output.k == -1.0
    assert not parse_config(with_({"k": -1.0})).start.output.mirror


def test_output_mirror_must_be_a_boolean() -> None:
    with pytest.raises(ValueError, match="output.mirror: must be true or false, got 'yes'"):
        parse_config(with_({"k": 1.0, "mirror": "yes"}))


def test_an_output_stage_is_the_identity_exactly_when_k_is_1_and_not_mirrored_whatever_its_centre() -> None:
    import numpy as np

    from core.kinematics.model import OutputStage

    p = np.array([[12.0, -40.0], [0.0, 3.5]])
    for stage, identity in ((OutputStage(), True), (OutputStage(1.0, 150.0, -20.0), True),
                            (OutputStage(-1.0, 150.0, 0.0), False), (OutputStage(1.0, 0.0, 0.0, True), False),
                            (OutputStage(2.0), False)):
        assert stage.is_identity == identity
        assert np.allclose(stage.apply(p), p) == identity  # the map itself agrees
    assert OutputStage(-1.0, 150.0, 0.0).describe() == "k = -1 about (150, 0) mm"
