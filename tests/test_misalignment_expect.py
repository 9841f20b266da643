"""`misalignment` says a thing once: a clip just off the turn axis whose `expect:` also says turn 0
gets one finding, and an expectation on another feature still gets its own."""

from __future__ import annotations

from pathlib import Path

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.writers.usd_clip import write_usd_clip

SPECS = (
    GaitSpec("idle"),
    GaitSpec("walk", speed=1.4, turn_rate=4.0),
    GaitSpec("tip_left", turn_rate=90.0),
    GaitSpec("tip_right", turn_rate=-90.0),
    GaitSpec("back", speed=1.1, direction=180.0),
)


def _findings(tmp_path: Path, expect: str) -> list[str]:
    for spec in SPECS:
        path = tmp_path / "clips" / f"{spec.name}.usda"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_usd_clip(generate(spec), path, meters_per_unit=1.0, up_axis="y")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/walk.usda\n"
        f"    expect: {expect}\n  - path: clips/[!w]*.usda\n"
    )
    space = analyse(manifest)
    return [d.message for d in space.diagnostics if d.rule == "misalignment" and d.clips == ("walk",)]


def test_an_expect_of_zero_on_the_axis_is_one_finding(tmp_path: Path) -> None:
    [message] = _findings(tmp_path, "{turn_rate: 0}")
    assert "off the turn_rate = 0 axis" in message and "its expect: says turn_rate 0" in message


def test_an_expect_on_another_feature_is_its_own_finding(tmp_path: Path) -> None:
    found = _findings(tmp_path, "{turn_rate: 0, speed: 2.0}")
    assert len(found) == 2
    assert any("expects 2" in m for m in found) and any("off the turn_rate = 0 axis" in m for m in found)
