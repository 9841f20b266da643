"""A clip entry's own `skeleton:` settings hold for everything made from its clips.

The oracle: one set of takes, built twice. Once all Y-up in metres; once with the left turns
exported Z-up in centimetres (another DCC's convention), their entry saying `skeleton: {up: z,
units: cm}` under a top-level `skeleton: {up: y, units: m}`. The motion is the same, so every
number must be too: the samples, the clips the fixes make from the Z-up takes (mirrors, axis
clips: made, cut and measured with the entry's settings) and the blend quality maps (which play
the Z-up takes again). Before, the fixes and the maps used the top-level settings: the mirror of
a Z-up turn was measured Y-up, in metres.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_fixes import LEFT_TURNS

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.motion.clip_ops.up_axis import y_up
from blendspace_pipeline.motion.procedural import GaitSpec, generate, generate_planted
from blendspace_pipeline.writers.bvh import write_bvh_clip

SPECS = (
    *LEFT_TURNS,
    GaitSpec("turn_mid_a", speed=2.5, turn_rate=30.0, duration=1.0, stride_length=2.5),
    GaitSpec("turn_mid_b", speed=2.6, turn_rate=34.0, duration=1.0, stride_length=2.6),
)
AXES = (
    "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
    "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"
)
FIXES = "fixes: {mirror: true, axis_clips: true, too_close: merge}\n"


def _project(
    root: Path,
    other_convention: bool,
    turns: frozenset[str] = frozenset(),
    *,
    top: str = "{up: y, units: m}",
    turns_say: str | None = None,
) -> Path:
    """``turns``: the takes exported in the turns' folder (default: every name with "turn");
    ``other_convention``: those Z-up in centimetres, their entry saying so (or ``turns_say``)."""
    for folder in ("straight", "turns"):
        (root / folder).mkdir(parents=True)
    for spec in SPECS:
        turn = spec.name in turns if turns else "turn" in spec.name
        if turn and other_convention:
            clip = generate_planted(spec, up="z", meters_per_unit=0.01)
        else:
            clip = generate_planted(spec)
        write_bvh_clip(clip, root / ("turns" if turn else "straight") / f"{spec.name}.bvh")
    entry = "  - path: turns/*.bvh\n"
    said = turns_say or ("{up: z, units: cm}" if other_convention else None)
    if said:
        entry += f"    skeleton: {said}\n"
    manifest = root / "manifest.yaml"
    manifest.write_text(
        f"schema_version: 1\nname: loco\nskeleton: {top}\n"
        "clips:\n  - path: straight/*.bvh\n    ignore: [{rule: in-place-clip, reason: idle}]\n"
        + entry
        + AXES
        + FIXES
    )
    return manifest


def _build(manifest: Path) -> dict[str, object]:
    out = manifest.parent / "out"
    code = main(["build", str(manifest), "--out", str(out), "--format", "json", "--jobs", "1"])
    assert code in (0, 1)
    return json.loads((out / "loco.blendspace.json").read_text())  # type: ignore[no-any-return]


@pytest.fixture(scope="module")
def builds(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, object], dict[str, object]]:
    same = _build(_project(tmp_path_factory.mktemp("same"), other_convention=False))
    mixed = _build(_project(tmp_path_factory.mktemp("mixed"), other_convention=True))
    return same, mixed


def _samples(doc: dict[str, object]) -> dict[str, dict[str, object]]:
    return {s["name"]: s for s in doc["samples"]}  # type: ignore[attr-defined,index]


def test_every_sample_and_generated_clip_is_where_the_same_motion_puts_it(
    builds: tuple[dict[str, object], dict[str, object]],
) -> None:
    same, mixed = (_samples(doc) for doc in builds)
    assert set(same) == set(mixed)
    made = {name for name, sample in same.items() if sample["generated"]}
    # The merge of two Z-up turns (a blend), and mirrors of Z-up turns.
    assert {"merged_turn_mid_a_turn_mid_b", "turn_in_place_right"} <= made, made
    for name in same:
        expected, found = same[name]["position"], mixed[name]["position"]
        assert found == pytest.approx(expected, abs=0.02), (name, expected, found)
        for feature in ("speed", "turn_rate", "direction"):
            a, b = same[name]["features"][feature], mixed[name]["features"][feature]  # type: ignore[index]
            assert b == pytest.approx(a, abs=0.02 * (360.0 if feature != "speed" else 9.0)), (name, feature)


def test_the_blend_quality_maps_play_each_take_with_its_own_settings(
    builds: tuple[dict[str, object], dict[str, object]],
) -> None:
    same, mixed = (doc["blend_quality"]["summary"] for doc in builds)  # type: ignore[index]
    assert same.keys() == mixed.keys()
    assert "foot_skate_max" in same, same
    for key, value in same.items():
        assert mixed[key] == pytest.approx(value, rel=0.05, abs=1e-3), (key, value, mixed[key])


@pytest.mark.parametrize("options", [{}, {"with_root_joint": True, "root_yaw_offset": 90.0}])
def test_a_z_up_take_turned_y_up_is_the_y_up_take(options: dict[str, object]) -> None:
    """The oracle of `y_up`: the generator's Z-up take, turned, is its Y-up take joint for joint."""
    spec = GaitSpec("walk_turn", speed=1.4, turn_rate=30.0, duration=1.0)
    z_up = generate(spec, up="z", **options)  # type: ignore[arg-type]
    turned = y_up(z_up)
    _, expected = forward_kinematics(generate(spec, **options))  # type: ignore[arg-type]
    _, found = forward_kinematics(turned)
    assert turned.up_axis == "y" and z_up.up_axis == "z"
    np.testing.assert_allclose(found, expected, atol=1e-9)


def test_a_merge_of_takes_read_with_other_settings_is_skipped_and_says_why(tmp_path: Path) -> None:
    """No blend of a Y-up take and a Z-up one is baked: the fix says which two, and how each is read."""
    zup = frozenset(spec.name for spec in SPECS if "turn" in spec.name) - {"turn_mid_a"}
    doc = _build(_project(tmp_path, other_convention=True, turns=zup))
    assert "merged_turn_mid_a_turn_mid_b" not in _samples(doc)
    skipped = [d for d in doc["diagnostics"] if d["rule"] == "fix-skipped"]  # type: ignore[attr-defined]
    assert any(
        "turn_mid_a and turn_mid_b are read with different `skeleton:` settings" in d["message"]
        for d in skipped
    ), skipped


def test_takes_stated_as_they_read_merge_with_takes_left_to_detection(tmp_path: Path) -> None:
    """`up: y, units: m` on one entry and nothing on the other read the same Y-up metre takes: the
    merge compares what each read (stated, or measured), not what the manifest wrote."""
    split = frozenset(spec.name for spec in SPECS if "turn" in spec.name) - {"turn_mid_a"}
    doc = _build(
        _project(tmp_path, other_convention=False, turns=split, top="{}", turns_say="{up: y, units: m}")
    )
    samples = _samples(doc)
    assert "merged_turn_mid_a_turn_mid_b" in samples
    assert not [d for d in doc["diagnostics"] if d["rule"] == "fix-skipped"]  # type: ignore[attr-defined]
    # Measured as it was made (up axis and unit as its sources read), not detected again: a merge
    # made Y up had been read -Y up from a blended body, and its file could not be written (exit 3).
    detected = [n for n in samples["merged_turn_mid_a_turn_mid_b"]["clip"]["notes"] if "detected" in n]  # type: ignore[index]
    assert not detected and any("detected" in n for n in samples["walk_fwd"]["clip"]["notes"]), detected  # type: ignore[index]


@pytest.mark.parametrize("where", ["entry", "top"])
def test_a_dropped_rest_frame_is_dropped_once(tmp_path: Path, where: str) -> None:
    """`tpose: drop` cuts the source's rest frame; the clips made from it start on motion and keep
    every frame (their measurement cut one more, and said it was a rest pose)."""
    (tmp_path / "clips").mkdir()
    for spec in SPECS[:5]:
        clip = generate_planted(spec)
        if spec.name == "turn_in_place_left":
            clip = generate(spec, tpose_first_frame=True)
        write_bvh_clip(clip, tmp_path / "clips" / f"{spec.name}.bvh")
    drop = "    skeleton: {tpose: drop}\n" if where == "entry" else ""
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: loco\n"
        + ("skeleton: {tpose: drop}\n" if where == "top" else "")
        + "clips:\n  - path: clips/*.bvh\n    ignore: [{rule: in-place-clip, reason: idle}]\n"
        + drop
        + AXES
        + "fixes: {mirror: true}\n"
    )
    samples = _samples(_build(manifest))
    source, mirror = samples["turn_in_place_left"]["clip"], samples["turn_in_place_right"]["clip"]
    assert mirror["frames"] == source["frames"] and mirror["duration"] == source["duration"]
    assert not [n for n in mirror["notes"] if "rest/T-pose" in n], mirror["notes"]
    # Fed back as a source (the build's BVH, with its provenance), it keeps every frame too.
    shutil.copy(tmp_path / "out" / "clips" / "turn_in_place_right.bvh", tmp_path / "clips")
    again = _samples(_build(manifest))["turn_in_place_right"]
    assert not again["generated"] and again["clip"]["frames"] == mirror["frames"]
