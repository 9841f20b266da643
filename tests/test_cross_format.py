"""The same procedural clip written as BVH, USD and glTF by our own writers measures the same
through each reader, and matches its construction ground truth."""

from __future__ import annotations

from pathlib import Path

import pytest

from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.gltf import write_gltf_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

SPECS = [
    GaitSpec("arc", speed=1.2, turn_rate=60.0, duration=2.0),
    GaitSpec("strafe", speed=1.5, direction=-90.0),
    GaitSpec(
        "back_turn",
        speed=1.0,
        direction=180.0,
        turn_rate=-30.0,
        start_heading=40.0,
        start_position=(3.0, -2.0),
    ),
]


@pytest.mark.parametrize("spec", SPECS, ids=[s.name for s in SPECS])
@pytest.mark.parametrize(("up", "meters_per_unit"), [("y", 1.0), ("z", 0.01)])
def test_every_format_measures_the_same(
    tmp_path: Path, spec: GaitSpec, up: str, meters_per_unit: float
) -> None:
    clip = generate(spec, up=up, meters_per_unit=meters_per_unit)
    write_bvh_clip(clip, tmp_path / "c.bvh")
    write_usd_clip(clip, tmp_path / "c.usda")
    write_gltf_clip(clip, tmp_path / "c.glb")
    # BVH carries no unit or up axis: the manifest's `skeleton:` says them.
    settings = {
        "c.bvh": RigSettings(units=meters_per_unit, up=up),
        "c.usda": RigSettings(),
        "c.glb": RigSettings(),
    }
    measured = {name: measure(read_clips(tmp_path / name)[0], s).features for name, s in settings.items()}
    truth = {"speed": spec.signed_speed, "turn_rate": spec.turn_rate, "direction": spec.direction}
    for name, features in measured.items():
        assert features["speed"] == pytest.approx(truth["speed"], rel=0.03), name
        assert features["turn_rate"] == pytest.approx(truth["turn_rate"], abs=1.5), name
        assert angle_between(features["direction"], truth["direction"]) < 1.5, name
        for key in ("speed", "turn_rate", "duration"):
            assert features[key] == pytest.approx(measured["c.usda"][key], abs=1e-3), (name, key)
        assert angle_between(features["direction"], measured["c.usda"]["direction"]) < 1e-3, name


def angle_between(a: float, b: float) -> float:
    """Absolute difference of two angles in degrees, across the +-180 seam."""
    return abs((a - b + 180.0) % 360.0 - 180.0)
