"""End to end on the real clips in ../shared/data (skipped when that folder is absent).

Expected values come from each folder's SOURCES.md (measured by hand there), not from this tool.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import SHARED_DATA, shared_data

from blendspace_pipeline.cli import main
from blendspace_pipeline.pipeline.analysis import analyse


def _manifest(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "manifest.yaml"
    path.write_text(body.replace("@DATA", SHARED_DATA.as_posix()))
    return path


def _build(manifest: Path, out: Path) -> dict[str, object]:
    assert main(["build", str(manifest), "--out", str(out), "--format", "json", "--no-fix"]) in (0, 1)
    return json.loads(next(out.glob("*.blendspace.json")).read_text())  # type: ignore[no-any-return]


def test_godot_tps_demo_strafe_space(tmp_path: Path) -> None:
    shared_data("godot-tps-demo", "SOURCES.md")
    manifest = _manifest(
        tmp_path,
        "schema_version: 1\nname: strafe\nclips:\n"
        "  - path: '@DATA/godot-tps-demo/strafe_*-cycle.tres'\n"
        "  - path: '@DATA/godot-tps-demo/Idlecombat-cycle.tres'\n"
        "    ignore: [{rule: in-place-clip, reason: idle}]\n"
        "axes:\n  x: {feature: lateral_speed, min: -3, max: 3, divisions: 60}\n"
        "  y: {feature: forward_speed, min: -3, max: 3, divisions: 60}\n",
    )
    doc = _build(manifest, tmp_path / "out")
    samples = {s["name"]: s for s in doc["samples"]}  # type: ignore[attr-defined]
    # SOURCES.md: 1.866 m in 0.833 s = 2.24 m/s for each strafe; the idle does not move.
    expected = {
        "strafe_front-cycle": (0.0, 2.24),
        "strafe_back-cycle": (0.0, -2.24),
        # The root track moves strafe_left along -X: the robot's right when it faces +Z (see notes).
        "strafe_left-cycle": (-2.24, 0.0),
        "strafe_right-cycle": (2.24, 0.0),
        "Idlecombat-cycle": (0.0, 0.0),
    }
    for name, (x, y) in expected.items():
        assert samples[name]["features"]["lateral_speed"] == pytest.approx(x, abs=0.02)
        assert samples[name]["features"]["forward_speed"] == pytest.approx(y, abs=0.02)
    assert len(doc["triangles"]) == 4  # type: ignore[arg-type]
    # The Godot export round-trips the layout: same five points, one sign flip on x from the
    # game's own layout (player.tscn: strafe_left at (1, 0), strafe_right at (-1, 0)).
    target = tmp_path / "strafe.tres"
    assert (
        main(
            [
                "export",
                str(tmp_path / "out" / "strafe.blendspace.json"),
                "--engine",
                "godot",
                "--out",
                str(target),
            ]
        )
        == 0
    )
    text = target.read_text()
    assert text.count("blend_point_") >= 10 and "auto_triangles = false" in text


def test_godot_walk_and_run_speeds() -> None:
    from blendspace_pipeline.motion.detect import RigSettings
    from blendspace_pipeline.motion.measure import measure
    from blendspace_pipeline.readers import read_clips

    walk = read_clips(shared_data("godot-tps-demo", "walking_nogun-cycle.tres"))[0]
    run = read_clips(shared_data("godot-tps-demo", "running_nogun-cycle.tres"))[0]
    # SOURCES.md: +Z 2.177 m in 1.25 s and 3.317 m in 0.833 s.
    assert measure(walk, RigSettings()).features["speed"] == pytest.approx(2.177 / 1.25, rel=0.01)
    assert measure(run, RigSettings()).features["speed"] == pytest.approx(3.317 / 0.8333, rel=0.01)


def test_fox_is_in_place_warned_not_crashed(tmp_path: Path) -> None:
    shared_data("khronos-fox", "Fox.glb")
    manifest = _manifest(
        tmp_path, "schema_version: 1\nname: fox\nclips:\n  - path: '@DATA/khronos-fox/Fox.glb'\n"
    )
    space = analyse(manifest)
    names = sorted(s.name for s in space.samples)
    assert names == ["Fox/Run", "Fox/Survey", "Fox/Walk"]
    in_place = sorted(c for d in space.diagnostics if d.rule == "in-place-clip" for c in d.clips)
    assert in_place == names
    assert all(abs(s.clip.measurement.features["speed"]) < 0.05 for s in space.samples)
    doc = _build(manifest, tmp_path / "out")
    assert {d["rule"] for d in doc["diagnostics"]} >= {"in-place-clip"}  # type: ignore[attr-defined]


def test_cmu_walk_with_range_and_units(tmp_path: Path) -> None:
    shared_data("cmu", "131_01.bvh")
    manifest = _manifest(
        tmp_path,
        "schema_version: 1\nname: cmu\nskeleton: {units: 0.0564}\nclips:\n"
        "  - path: '@DATA/cmu/131_01.bvh'\n    name: walk_01\n    range: [2.0, 6.0]\n"
        "  - path: '@DATA/cmu/131_02.bvh'\n    name: walk_02\n    range: [3.0, 7.0]\n"
        "  - path: '@DATA/cmu/131_01.bvh'\n    name: whole_01\n",
    )
    space = analyse(manifest)
    by_name = {s.name: s.clip.measurement for s in space.samples}
    for name in ("walk_01", "walk_02", "whole_01"):
        m = by_name[name]
        assert m.meters_per_unit == pytest.approx(0.0564)
        assert m.fps == pytest.approx(120.0, rel=1e-3)
        assert 0.2 < m.features["speed"] < 2.0  # a walk, in metres per second
    assert by_name["walk_01"].features["duration"] == pytest.approx(4.0, abs=0.01)
    # SOURCES.md, whole take: about 46 units forward (chord) and -12 deg of net turn over 8.27 s;
    # "a path of about 83 units" sums the raw per-frame hip motion, sway included. Our speed
    # follows the travel in the character's own frame, so the sway cancels: between the two.
    whole = by_name["whole_01"].features
    assert whole["displacement_speed"] * whole["duration"] / 0.0564 == pytest.approx(46, rel=0.05)
    assert whole["duration"] == pytest.approx(8.27, abs=0.01)
    assert whole["turn"] == pytest.approx(-12, abs=3)
    assert 46 < whole["speed"] * whole["duration"] / 0.0564 < 83
    # Without the override the unit is read from the body: CMU's 1/0.45 inch (SOURCES.md: about
    # 0.056 m per unit), Y up, nothing guessed (issue 10: this used to be a units-doubt guess).
    detected = analyse(
        _manifest(tmp_path, "schema_version: 1\nname: c\nclips:\n  - path: '@DATA/cmu/*.bvh'\n")
    )
    assert not [d for d in detected.diagnostics if d.rule in ("units-doubt", "detection-guess")]
    for sample in detected.samples:
        assert sample.clip.measurement.meters_per_unit == pytest.approx(0.0254 / 0.45)
        assert sample.clip.measurement.up_axis == "y"


def test_godot_mirrored_strafe_rereads_where_it_was_placed(tmp_path: Path) -> None:
    """The mirrored strafe_right is written as USD; read back, it must measure at its placed
    position (its flat Godot skeleton survives the file, so the root track still decides)."""
    from blendspace_pipeline.motion.detect import RigSettings
    from blendspace_pipeline.motion.measure import measure
    from blendspace_pipeline.readers import read_clips

    shared_data("godot-tps-demo", "strafe_left-cycle.tres")
    clips = "".join(
        f"  - path: '@DATA/godot-tps-demo/{name}.tres'\n"
        for name in ("Idle-cycle", "strafe_front-cycle", "strafe_back-cycle", "strafe_left-cycle")
    )
    manifest = _manifest(
        tmp_path,
        "schema_version: 1\nname: strafe\nclips:\n" + clips + "skeleton: {mirror: {left: .L, right: .R}}\n"
        "axes:\n  x: {feature: lateral_speed, min: -3, max: 3, divisions: 60}\n"
        "  y: {feature: forward_speed, min: -3, max: 3, divisions: 60}\n",
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json"]) in (0, 1)
    doc = json.loads((out / "strafe.blendspace.json").read_text())
    [mirrored] = [s for s in doc["samples"] if s["generated"]]
    assert mirrored["name"] == "strafe_right-cycle"
    [clip] = read_clips(out / mirrored["source"])
    features = measure(clip, RigSettings()).features
    x, y = mirrored["position"]
    assert x == pytest.approx(2.2, abs=0.12)  # the mirror of strafe_left at (-2.2, 0)
    assert features["lateral_speed"] == pytest.approx(x, abs=0.02 * 6)  # 2% of the 6 m/s axis range
    assert features["forward_speed"] == pytest.approx(y, abs=0.02 * 6)
    assert features["turn_rate"] == pytest.approx(0.0, abs=1e-3)


def test_cmu_ranges_of_one_take_share_the_estimated_unit(tmp_path: Path) -> None:
    """BVH has no unit: it is estimated once per file (not per range), near the CMU 0.0564 m."""
    shared_data("cmu", "131_01.bvh")
    ranges = ([0.5, 2.0], [2.0, 4.0], [4.0, 6.0], [6.0, 8.0])
    clips = "".join(
        f"  - path: '@DATA/cmu/131_01.bvh'\n    name: part_{i}\n    range: [{a}, {b}]\n"
        for i, (a, b) in enumerate(ranges)
    )
    space = analyse(_manifest(tmp_path, "schema_version: 1\nname: c\nclips:\n" + clips))
    units = {s.clip.measurement.meters_per_unit for s in space.samples}
    assert len(units) == 1
    # SOURCES.md: the hips stand about 15 units high, about 0.056 m per unit.
    assert units.pop() == pytest.approx(0.0564, rel=0.12)
    durations = sorted(s.clip.measurement.features["duration"] for s in space.samples)
    # `range:` ends are included: [2, 4] at 120 fps lasts 2 s, not 2 s less a frame.
    assert durations == pytest.approx([1.5, 2.0, 2.0, 2.0], abs=1e-3)


def test_a_trimmed_clip_reports_the_range_it_measured(tmp_path: Path) -> None:
    """`clip.range` is the range used: the Godot walk, resampled at 30.4 fps, measures the frames
    0.263-0.987 s of `range: [0.25, 1.0]`, and its duration is theirs. A CMU take at 120 fps
    trimmed between frames says the frames it measured too."""
    shared_data("godot-tps-demo", "walking_nogun-cycle.tres")
    manifest = tmp_path / "m.yaml"
    manifest.write_text(
        "schema_version: 1\nname: trims\nclips:\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/godot-tps-demo/walking_nogun-cycle.tres', range: [0.25, 1.0], name: walk}}\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/godot-tps-demo/running_nogun-cycle.tres', name: run}}\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_01.bvh', range: [2.0037, 4.0011], name: cmu}}\n"
        "skeleton: {forward: +z}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    clips = {s["name"]: s["clip"] for s in json.loads((out / "trims.blendspace.json").read_text())["samples"]}
    walk = clips["walk"]
    assert walk["range"] == pytest.approx([10 / 38 * 1.0, 37.5 / 38], abs=0.002)  # 0.263, 0.987
    for name in ("walk", "cmu"):
        first, last = clips[name]["range"]
        assert last - first == pytest.approx(clips[name]["duration"], abs=1e-5)
    fps = clips["cmu"]["fps"]  # 1 / 0.008333 s
    assert clips["cmu"]["range"] == pytest.approx([240 / fps, 480 / fps], abs=1e-5)  # nearest frames
    assert clips["run"]["range"] is None  # not trimmed


def test_a_frame_rate_a_reader_fitted_to_the_length_is_the_set_s_rate(tmp_path: Path) -> None:
    """The Godot walk's 30 fps keys are sampled at 30.4 fps to end on its length: the same export
    as the other clips at 30 fps, not an `inconsistent-fps` finding (it was one)."""
    shared_data("godot-tps-demo", "walking_nogun-cycle.tres")
    manifest = tmp_path / "m.yaml"
    manifest.write_text(
        "schema_version: 1\nname: g\nclips:\n"
        f"  - path: '{SHARED_DATA.as_posix()}/godot-tps-demo/*-cycle.tres'\n"
        "skeleton: {forward: +z}\n"
    )
    space = analyse(manifest)
    rates = sorted({round(s.clip.measurement.fps, 2) for s in space.samples})
    assert rates[0] == 30.0 and 30.0 < rates[-1] < 30.6  # the walk's 30.4 among them
    assert not [d for d in space.diagnostics if d.rule == "inconsistent-fps"]


@pytest.mark.parametrize(("take", "window"), [("131_01", (1.0, 5.5)), ("131_02", (1.0, 5.5))])
def test_cmu_range_from_standing_reads_the_hip_line_s_turn(take: str, window: tuple[float, float]) -> None:
    """A `range:` that starts while the actor stands in a split stance, then walks: the stride
    sway fitted on the walk was extrapolated onto the stance's foot signal, and 131_01 over
    [1, 5.5] s read a turn of -75 deg where the hip line turns about 0.

    Oracle: the hip line's own facing (left hip minus right hip, turned 90 deg, Y up), averaged
    over the first and the last half second of the range (about half a stride: the sway is
    +-10 deg here), and the turn between the two."""
    import numpy as np

    from blendspace_pipeline.motion.clip import forward_kinematics
    from blendspace_pipeline.motion.detect import RigSettings
    from blendspace_pipeline.motion.measure import measure
    from blendspace_pipeline.readers import read_clips

    clip = read_clips(shared_data("cmu", f"{take}.bvh"))[0]
    measured = measure(clip, RigSettings(), window)
    _, positions = forward_kinematics(clip)
    names = list(clip.skeleton.names)
    across = positions[:, names.index("LeftHip")] - positions[:, names.index("RightHip")]
    facing = np.unwrap(np.arctan2(across[:, 0], across[:, 2]))  # Y up: ground (z, x), left turn > 0
    first, last = (round(t * clip.fps) for t in window)
    half = round(0.5 * clip.fps)
    turned = np.degrees(facing[last - half : last + 1].mean() - facing[first : first + half + 1].mean())
    assert measured.features["turn"] == pytest.approx(turned, abs=12.0)
