"""Godot .tres Animation reader: the TPS demo's Godot 3 clips, hand-written Godot 4 resources,
and broken files reported with their line."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.godot_tres import read

Y = np.array([0.0, 1.0, 0.0])
TPS = (
    "Idle-cycle",
    "Idlecombat-cycle",
    "running_nogun-cycle",
    "strafe_back-cycle",
    "strafe_front-cycle",
    "strafe_idle_to_forward-noexp",
    "strafe_left-cycle",
    "strafe_neu_to_left-noexp",
    "strafe_neu_to_right-noexp",
    "strafe_right-cycle",
    "walking_nogun-cycle",
)


def transform_tracks(text: str) -> dict[str, np.ndarray]:
    """Bone -> (K, 12) keys, parsed independently of the reader with plain regexes."""
    tracks = {}
    for index, bone in re.findall(r'tracks/(\d+)/path = NodePath\("[^":]*:([^"]+)"\)', text):
        kind = re.search(rf'tracks/{index}/type = "(\w+)"', text)
        if kind is None or kind.group(1) != "transform":
            continue
        keys = re.search(rf"tracks/{index}/keys = \w+\(([^)]*)\)", text)
        assert keys is not None
        tracks[bone] = np.array([float(v) for v in keys.group(1).split(",")]).reshape(-1, 12)
    return tracks


@pytest.mark.parametrize("stem", TPS)
def test_tps_demo_clips_match_their_keys(stem: str) -> None:
    path = shared_data("godot-tps-demo", f"{stem}.tres")
    text = path.read_text()
    length = float(re.search(r"^length = ([\d.]+)$", text, re.MULTILINE).group(1))  # type: ignore[union-attr]
    tracks = transform_tracks(text)
    [clip] = read_clips(path)
    assert clip.name == stem
    assert (clip.meters_per_unit, clip.up_axis, clip.skeleton.has_hierarchy) == (1.0, "y", False)
    assert set(clip.skeleton.names) == set(tracks) and len(tracks) == 145
    assert clip.frame_count == round(length * 30) + 1 and clip.duration == pytest.approx(length, abs=1e-4)
    assert clip.fps == pytest.approx(30.0, rel=0.02)
    assert all(p == -1 for p in clip.skeleton.parents)
    checked = 0
    for bone, keys in tracks.items():
        joint = clip.skeleton.index(bone)
        frames = keys[:, 0] * clip.fps
        # Key times are printed with 6 digits (14.8667 s): only keys that really sit on a frame.
        on_frame = np.abs(frames - np.round(frames)) < 1e-4
        rows, at = keys[on_frame], np.round(frames[on_frame]).astype(int)
        np.testing.assert_allclose(clip.translations[at, joint], rows[:, 2:5], atol=1e-5, err_msg=bone)
        dots = np.abs(np.sum(clip.rotations[at, joint] * quat.normalize(rows[:, 5:9]), axis=-1))
        np.testing.assert_allclose(dots, 1.0, atol=1e-5, err_msg=bone)
        checked += len(rows)
    assert checked >= 2 * len(tracks)  # every track keys at least its first and last frame


# Root displacement / length from SOURCES.md, and the travel direction as measured: forward is
# the root bone's +Z. strafe_left moves along the root bone's -X, which reads as the character's
# right (-90 deg); the game's blend space puts it at +x (SOURCES.md notes the mismatch).
EXPECTED = {
    "walking_nogun-cycle": (1.741, 0.0),
    "running_nogun-cycle": (3.98, 0.0),
    "strafe_front-cycle": (2.239, 0.0),
    "strafe_back-cycle": (-2.239, 180.0),
    "strafe_left-cycle": (2.239, -90.0),
    "strafe_right-cycle": (2.239, 90.0),
    "Idle-cycle": (0.0, 0.0),
    "Idlecombat-cycle": (0.0, 0.0),
}


@pytest.mark.parametrize("stem", sorted(EXPECTED))
def test_tps_demo_speeds_are_measured_on_the_root_bone(stem: str) -> None:
    [clip] = read(shared_data("godot-tps-demo", f"{stem}.tres"))
    speed, direction = EXPECTED[stem]
    explicit = measure(clip, RigSettings(root="root"))
    automatic = measure(clip, RigSettings())
    assert automatic.features == explicit.features and automatic.root == "root"
    assert explicit.features["speed"] == pytest.approx(speed, rel=0.05, abs=1e-3)
    assert explicit.features["direction"] == pytest.approx(direction, abs=0.5)
    assert explicit.features["turn_rate"] == pytest.approx(0.0, abs=1e-6)
    assert explicit.in_place == (speed == 0.0)


GODOT4 = """[gd_resource type="Animation" format=3 uid="uid://b2x1"]

[resource]
resource_name = "walk"
length = 0.2
loop_mode = 1
step = 0.05
tracks/0/type = "position_3d"
tracks/0/imported = true
tracks/0/enabled = true
tracks/0/path = NodePath("Armature/Skeleton3D:root")
tracks/0/interp = 1
tracks/0/loop_wrap = true
tracks/0/keys = PackedFloat32Array(0, 1, 0, 0, 0, 0.2, 1, 0, 0, 0.4)
tracks/1/type = "rotation_3d"
tracks/1/path = NodePath("Armature/Skeleton3D:hips")
tracks/1/interp = 1
tracks/1/keys = PackedFloat32Array(0, 1, 0, 0, 0, 1, 0.1, 1, 0, 0.7071068, 0, 0.7071068)
tracks/2/type = "scale_3d"
tracks/2/path = NodePath("Armature/Skeleton3D:hips")
tracks/2/keys = PackedFloat32Array(0, 1, 1, 1, 1)
tracks/3/type = "position_3d"
tracks/3/path = NodePath("Armature/Skeleton3D:hips")
tracks/3/interp = 0
tracks/3/keys = PackedFloat32Array(0, 1, 0, 1, 0, 0.1, 1, 0, 0.9, 0)
tracks/4/type = "value"
tracks/4/path = NodePath("Label:text")
tracks/4/keys = {
"times": PackedFloat32Array(0),
"transitions": PackedFloat32Array(1),
"update": 1,
"values": ["step [1]"]
}
"""


def test_godot4_tracks_are_resampled_at_the_step_rate(tmp_path: Path) -> None:
    path = tmp_path / "walk.tres"
    path.write_text(GODOT4)
    [clip] = read(path)
    assert clip.name == "walk" and clip.fps == pytest.approx(20.0) and clip.frame_count == 5
    assert clip.skeleton.names == ("root", "hips") and not clip.skeleton.has_hierarchy
    np.testing.assert_allclose(clip.translations[:, 0, 2], [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-6)
    np.testing.assert_allclose(clip.translations[:, 1, 1], [1.0, 1.0, 0.9, 0.9, 0.9], atol=1e-6)  # nearest
    expected = quat.from_axis_angle(Y, np.deg2rad([0.0, 45.0, 90.0, 90.0, 90.0]))
    np.testing.assert_allclose(np.abs(np.sum(clip.rotations[:, 1] * expected, axis=-1)), 1.0, atol=1e-6)
    assert any("1 value" in note for note in clip.notes) and any("loops" in note for note in clip.notes)
    assert measure(clip, RigSettings(root="root")).features["speed"] == pytest.approx(2.0)


def test_godot3_pool_real_array_and_default_rate(tmp_path: Path) -> None:
    path = tmp_path / "slide.tres"
    path.write_text(
        '[gd_resource type="Animation" format=2]\n\n[resource]\nlength = 0.5\n'
        'tracks/0/type = "transform"\ntracks/0/path = NodePath("Skeleton:root")\n'
        "tracks/0/keys = PoolRealArray( 0, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1,\n"
        "  0.5, 1, 1, 0, 0, 0, 0, 0, 1, 1, 1, 1 )\n"
        'tracks/1/type = "transform"\ntracks/1/path = NodePath("Other/Skeleton:root")\n'
        "tracks/1/keys = PoolRealArray( 0, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1 )\n"
    )
    [clip] = read(path)
    assert clip.fps == 30.0 and clip.frame_count == 16
    assert clip.skeleton.names == ("Skeleton:root", "Other/Skeleton:root")  # same bone, two skeletons
    np.testing.assert_allclose(clip.translations[:, 0, 0], np.arange(16) / 15.0, atol=1e-9)
    assert any("relative to each bone's rest" in note for note in clip.notes)


def test_animation_library_yields_one_clip_per_animation(tmp_path: Path) -> None:
    body = GODOT4.split("[resource]\n", 1)[1]
    path = tmp_path / "moves.tres"
    path.write_text(
        '[gd_resource type="AnimationLibrary" load_steps=3 format=3]\n\n'
        f'[sub_resource type="Animation" id="Animation_a"]\n{body}\n'
        f'[sub_resource type="Animation" id="Animation_b"]\n{body.replace("0.4)", "0.8)")}\n'
        '[resource]\n_data = {\n&"walk": SubResource("Animation_a"),\n&"run": SubResource("Animation_b")\n}\n'
    )
    clips = read(path)
    assert [c.name for c in clips] == ["moves/walk", "moves/run"]
    assert clips[1].translations[-1, 0, 2] == pytest.approx(0.8)


def test_multi_line_strings_do_not_break_the_parse(tmp_path: Path) -> None:
    """Embedded script source spans lines and holds brackets and `name = value`-like lines."""
    script = (
        '[sub_resource type="GDScript" id="1"]\n'
        'script/source = "extends Node\n\nfunc _step(a = [1, (2\n\tprint(\\"[x\\"]"\n\n'
    )
    path = tmp_path / "scripted.tres"
    path.write_text(GODOT4.replace("[resource]\n", script + "[resource]\n", 1))
    [clip] = read(path)
    assert clip.skeleton.names == ("root", "hips")
    path.write_text(GODOT4.replace("[resource]\n", script.replace(']"\n\n', "]\n\n") + "[resource]\n", 1))
    with pytest.raises(ClipReadError, match="unterminated string") as caught:
        read(path)
    assert caught.value.line == 4


def test_other_resources_are_refused_with_a_hint(tmp_path: Path) -> None:
    path = tmp_path / "strafe.tres"
    path.write_text(
        '[gd_resource type="AnimationNodeBlendSpace2D" load_steps=3 format=2]\n\n'
        '[sub_resource type="AnimationNodeAnimation" id=1]\nanimation = "strafe_left"\n\n'
        "[resource]\nblend_point_0/node = SubResource( 1 )\nblend_point_0/pos = Vector2( 1, 0 )\n"
    )
    with pytest.raises(ClipReadError, match="AnimationNodeBlendSpace2D") as caught:
        read_clips(path)
    assert caught.value.line == 1 and caught.value.hint and "Animation .tres" in caught.value.hint


def broken(tmp_path: Path, old: str, new: str) -> ClipReadError:
    path = tmp_path / "broken.tres"
    text = GODOT4.replace(old, new, 1)
    assert text != GODOT4
    path.write_text(text)
    with pytest.raises(ClipReadError) as caught:
        read(path)
    assert caught.value.path == path
    return caught.value


def test_broken_lines_are_reported_with_their_number(tmp_path: Path) -> None:
    keys_line = GODOT4.splitlines().index(
        "tracks/1/keys = PackedFloat32Array(0, 1, 0, 0, 0, 1, 0.1, 1, 0, 0.7071068, 0, 0.7071068)"
    )
    error = broken(tmp_path, "0.1, 1, 0, 0.7071068", "0.1, 1, 0, 0.70x1068")
    assert error.line == keys_line + 1 and "0.70x1068" in error.message
    error = broken(tmp_path, "0.1, 1, 0, 0.7071068, 0, 0.7071068", "0.1, 1, 0, 0.7071068, 0")
    assert error.line == keys_line + 1 and "multiple of 6" in error.message
    error = broken(tmp_path, "step = 0.05", "step 0.05")
    assert error.line == 7
    error = broken(tmp_path, '"values": ["step [1]"]\n}\n', '"values": ["step [1]"]\n')
    assert error.line == GODOT4.splitlines().index("tracks/4/keys = {") + 1 and "not closed" in error.message
    error = broken(tmp_path, '[gd_resource type="Animation"', '[gd_resource type="Animation"\n')
    assert error.line == 1


def test_garbage_and_empty_files(tmp_path: Path) -> None:
    cases = {
        "binary.tres": bytes(range(256)) * 4,
        "empty.tres": b"",
        "notracks.tres": b'[gd_resource type="Animation" format=3]\n\n[resource]\nlength = 1.0\n',
    }
    for name, content in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(ClipReadError):
            read_clips(path)
