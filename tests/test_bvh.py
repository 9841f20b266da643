"""The BVH reader and writer: hand-made files with answers worked out by hand, round trips,
real CMU files compared with the independent `bvhio` reader, and errors with their line numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data
from scipy.spatial.transform import Rotation

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers.bvh import read, read_header
from blendspace_pipeline.writers.bvh import write_bvh_clip

TWO_JOINTS = """HIERARCHY
ROOT Hips
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition {order}
  JOINT Spine
  {{
    OFFSET {offset}
    CHANNELS 3 {order}
    End Site
    {{
      OFFSET 0 5 0
    }}
  }}
}}
MOTION
Frames: 2
Frame Time: 0.04
1 2 3 {a} 0 0 0
1 2 3 0 0 0 {a}
"""

# Position channels on a child, a two-channel joint, an order per joint: bvhio must agree.
MIXED = """HIERARCHY
ROOT Hips
{
  OFFSET 1 1 1
  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
  JOINT Arm
  {
    OFFSET 5 0 0
    CHANNELS 6 Xposition Yposition Zposition Xrotation Zrotation Yrotation
    JOINT Hand
    {
      OFFSET 0 3 0
      CHANNELS 2 Zrotation Xrotation
      End Site
      {
        OFFSET 0 1 0
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.1
1 2 3 10 20 30 7 8 9 40 50 60 70 80
-4 0 2 -100 5 170 0 1 0 0 0 0 -35 15
"""


def _write(tmp_path: Path, text: str, name: str = "t.bvh", newline: str = "\n") -> Path:
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path


def _rig_scale(clip: Clip) -> float:
    """The largest extent of the skeleton on frame 0: what "1e-4 of the rig" is relative to."""
    return float(np.ptp(forward_kinematics(clip)[1][0], axis=0).max())


def _assert_same_pose(a: Clip, b: Clip) -> None:
    error = np.abs(forward_kinematics(a)[1] - forward_kinematics(b)[1]).max()
    assert error < 1e-4 * _rig_scale(a), error


@pytest.mark.parametrize(
    ("order", "expected"),
    [
        # R = R[order[0]] R[order[1]] R[order[2]], every angle 90 deg, applied to the OFFSET (10, 0, 0).
        # XYZ: Rz (10,0,0) = (0,10,0); Ry keeps it; Rx (0,10,0) = (0,0,10).
        ("Xrotation Yrotation Zrotation", (0, 0, 10)),
        # ZXY: Ry (10,0,0) = (0,0,-10); Rx -> (0,10,0); Rz -> (-10,0,0).
        ("Zrotation Xrotation Yrotation", (-10, 0, 0)),
        # YXZ: Rz -> (0,10,0); Rx -> (0,0,10); Ry -> (10,0,0).
        ("Yrotation Xrotation Zrotation", (10, 0, 0)),
        # ZYX: Rx keeps (10,0,0); Ry -> (0,0,-10); Rz keeps it.
        ("Zrotation Yrotation Xrotation", (0, 0, -10)),
    ],
)
def test_rotation_orders_against_hand_worked_positions(
    tmp_path: Path, order: str, expected: tuple[int, int, int]
) -> None:
    clip = read(_write(tmp_path, TWO_JOINTS.format(order=order, a="90 90 90", offset="10 0 0")))[0]
    _, world = forward_kinematics(clip)
    assert world[0, 1] == pytest.approx(np.array([1, 2, 3]) + np.array(expected), abs=1e-9)


@pytest.mark.parametrize(
    "order",
    [
        "Zrotation Xrotation Yrotation",
        "Xrotation Yrotation Zrotation",
        "Yrotation Xrotation Zrotation",
        "Zrotation Yrotation Xrotation",
        "Yrotation Zrotation Xrotation",
    ],
)
def test_channel_orders_with_distinct_angles(tmp_path: Path, order: str) -> None:
    clip = read(_write(tmp_path, TWO_JOINTS.format(order=order, a="30 45 60", offset="0 10 0")))[0]
    letters = "".join(w[0] for w in order.split())
    expected = Rotation.from_euler(letters, [30, 45, 60], degrees=True)  # upper case: intrinsic
    _, world = forward_kinematics(clip)
    assert clip.fps == pytest.approx(25.0)
    # Frame 0: the root rotates, so the spine's offset (0, 10, 0) turns with it.
    assert world[0, 1] == pytest.approx(np.array([1, 2, 3]) + expected.apply([0, 10, 0]))
    # Frame 1: the root is unrotated and only the spine rotates: its own position is unchanged.
    assert world[1, 1] == pytest.approx([1, 12, 3])
    assert clip.skeleton.names == ("Hips", "Spine")  # End Sites are not joints
    assert clip.meters_per_unit is None and clip.up_axis is None  # BVH does not say


def test_three_channel_root_position_channels_on_a_child_crlf_and_tabs(tmp_path: Path) -> None:
    text = (
        "HIERARCHY\nROOT\tHips\n{\n\tOFFSET 1 2 3\n\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
        "\tJOINT Arm\n\t{\n\t\tOFFSET 5 0 0\n\t\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        "\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 1 0 0\n\t\t}\n\t}\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333333\n"
        "0 0 0  7 8 9 0 0 0   \n"
    )
    path = _write(tmp_path, text, newline="\r\n")
    clip = read(path)[0]
    _, world = forward_kinematics(clip)
    assert world[0, 0] == pytest.approx([1, 2, 3])  # no position channels: the OFFSET stays
    assert world[0, 1] == pytest.approx([8, 10, 12])  # position channels replace the OFFSET
    assert clip.skeleton.rest_translations[1] == pytest.approx([5, 0, 0])
    assert read_header(path).joints[1].end_site == (1.0, 0.0, 0.0)  # kept for writers


def test_classic_mac_line_endings_read_like_unix_ones(tmp_path: Path) -> None:
    text = TWO_JOINTS.format(order="Zrotation Xrotation Yrotation", a="30 45 60", offset="0 10 0")
    unix = read(_write(tmp_path, text))[0]
    mac = tmp_path / "mac.bvh"
    mac.write_bytes(text.replace("\n", "\r").encode())
    clip = read(mac)[0]
    assert clip.frame_count == unix.frame_count and clip.skeleton.names == unix.skeleton.names
    assert np.array_equal(clip.rotations, unix.rotations)


def test_mixed_layout_agrees_with_bvhio(tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio")
    path = _write(tmp_path, MIXED)
    clip = read(path)[0]
    _, world = forward_kinematics(clip)
    root = bvhio.readAsHierarchy(str(path))
    joints = {joint.Name: joint for joint, _, _ in root.layout()}
    for frame in range(2):
        root.loadPose(frame)
        for index, name in enumerate(clip.skeleton.names):
            theirs = np.array(list(joints[name].PositionWorld))
            assert world[frame, index] == pytest.approx(theirs, abs=1e-5), (frame, name)  # bvhio: float32


def test_compact_braces_several_roots_wrapped_frames_and_reordered_header(tmp_path: Path) -> None:
    text = (
        "HIERARCHY\nROOT A {\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
        " End Site {\n  OFFSET 0 1 0\n }\n}\nROOT B {\n OFFSET 4 0 0\n CHANNELS 1 Yrotation\n"
        " JOINT C {\n  OFFSET 0 0 2\n }\n}\n"
        "MOTION\nFrame Time: 0.5\nFrames: 2\n1 2\n3 90\n0 0 0\n0\n"  # frames wrapped over lines
    )
    path = _write(tmp_path, text)
    clip = read(path)[0]
    assert clip.skeleton.names == ("A", "B", "C") and clip.skeleton.parents == (-1, -1, 1)
    assert clip.fps == pytest.approx(2.0)
    _, world = forward_kinematics(clip)
    assert world[0, 0] == pytest.approx([1, 2, 3])
    assert world[0, 2] == pytest.approx([4 + 2, 0, 0])  # Ry(90) turns (0, 0, 2) into (2, 0, 0)
    assert world[1, 2] == pytest.approx([4, 0, 2])
    # The writer keeps this layout (C has no channels at all) and refuses what it cannot express.
    out = tmp_path / "out.bvh"
    write_bvh_clip(clip, out, template=path)
    _assert_same_pose(clip, read(out)[0])
    clip.rotations[:, 2] = Rotation.from_euler("X", [[0.0], [5.0]], degrees=True).as_quat()
    with pytest.raises(ValueError, match=r"'C'.*\(none\)"):
        write_bvh_clip(clip, out, template=path)


def test_numbers_numpy_does_not_parse_fall_back_to_python(tmp_path: Path) -> None:
    text = "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n1_0\n20\n"
    clip = read(_write(tmp_path, text))[0]
    assert Rotation.from_quat(clip.rotations[:, 0]).as_euler("XYZ", degrees=True)[:, 0] == pytest.approx(
        [10, 20]
    )


def _one_joint(motion: str, channels: str = "CHANNELS 1 Xrotation") -> str:
    return f"HIERARCHY\nROOT Hips\n{{\n {channels}\n}}\nMOTION\n{motion}"


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n", 4, "OFFSET needs 3"),
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 nan 0\n}\n", 4, "OFFSET needs 3"),
        ("HIERARCHY\nROOT Hips\n{\n  CHANNELS 3 Xrotation Yrotation Wrotation\n}\n", 4, "unknown channel"),
        ("HIERARCHY\nROOT Hips\n{\n  CHANNELS 3 Xrotation Yrotation\n}\n", 4, "says 3 but lists 2"),
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  SCALE 1\n}\n", 5, "unexpected 'SCALE'"),
        ("HIERARCHY\nJOINT Hips\n{\n}\n", 2, "JOINT outside any ROOT"),
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n\n\n", 4, "truncated"),
        ("HIERARCHY\nROOT Hips\n{\n}\n}\n", 5, "unbalanced"),
        ("HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\nMOTION\nFrames: 1\n", 5, "before the hierarchy"),
        (_one_joint("Frames: 1\n"), 7, "MOTION header is incomplete"),
        (_one_joint("Frames: 1\nFrameTime 0.1\n1\n"), 8, "expected 'Frames:'"),
        (_one_joint("Frames: 0\nFrame Time: 0.1\n"), 7, "no frames"),
        (_one_joint("Frames: 1\nFrame Time: 0.1\n\n", "OFFSET 0 0 0"), 6, "no CHANNELS"),
        (_one_joint("Frames: two\nFrame Time: 0.1\n1\n2\n"), 7, "not a whole number"),
        (_one_joint("Frames: 2\nFrame Time: 0\n1\n2\n"), 8, "Frame Time"),
        (
            _one_joint("Frames: 2\nFrame Time: 0.1\n1 2\n3\n", "CHANNELS 2 Xrotation Yrotation"),
            10,
            "frame 2 has 1",
        ),
        (_one_joint("Frames: 3\nFrame Time: 0.1\n1\n2\n"), 10, "says 3 but the file has 2"),
        (_one_joint("Frames: 1\nFrame Time: 0.1\n1\n2\n"), 10, "says 1 but the file has 2"),
        (_one_joint("Frames: 2\nFrame Time: 0.1\n\n1\n\nx1\n"), 12, "'x1' is not a number"),
        (_one_joint("Frames: 2\nFrame Time: 0.1\n1\nnan\n"), 10, "'nan' is not a finite number"),
        ("hello\n", 1, "expected HIERARCHY"),
        ("", 1, "truncated"),
    ],
)
def test_errors_name_their_line(tmp_path: Path, text: str, line: int, words: str, newline: str) -> None:
    path = _write(tmp_path, text, newline=newline)
    with pytest.raises(ClipReadError) as caught:
        read(path)
    rendered = caught.value.render()
    assert rendered.startswith(f"{path}:{line}: "), rendered
    assert words in caught.value.message
    assert "\n    hint: " in rendered


def test_frames_mismatch_says_expected_and_found(tmp_path: Path) -> None:
    text = TWO_JOINTS.format(order="Zrotation Xrotation Yrotation", a="0 0 0", offset="0 1 0")
    with pytest.raises(ClipReadError) as caught:
        read(_write(tmp_path, text.replace("Frames: 2", "Frames: 5")))
    assert "'Frames:' says 5 but the file has 2 frames" in caught.value.message
    assert caught.value.line == 20  # the last frame present


def test_binary_garbage_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "g.bvh"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ClipReadError, match="not a text BVH"):
        read(path)


@pytest.mark.parametrize(
    ("spec", "options"),
    [
        (GaitSpec("walk", speed=1.4, turn_rate=30.0), {}),
        (GaitSpec("strafe", speed=1.2, direction=90.0), {}),
        (GaitSpec("spin", turn_rate=360.0, duration=1.0), {}),
        # Z up, centimetres, a ground-level Root joint: the moving Hips is not a root.
        (GaitSpec("backward", speed=1.0, direction=180.0), {"up": "z", "meters_per_unit": 0.01}),
        (GaitSpec("arc", speed=2.0, turn_rate=-45.0), {"with_root_joint": True, "root_yaw_offset": 30.0}),
    ],
)
def test_procedural_round_trip_keeps_pose_and_features(
    tmp_path: Path, spec: GaitSpec, options: dict[str, object]
) -> None:
    clip = generate(spec, **options)  # type: ignore[arg-type]
    path = tmp_path / "c.bvh"
    write_bvh_clip(clip, path)
    again = read(path)[0]
    assert again.skeleton.names == clip.skeleton.names
    assert again.skeleton.parents == clip.skeleton.parents
    _assert_same_pose(clip, again)
    # BVH drops the unit and the up axis: give them back as a manifest's `skeleton:` would.
    units = clip.meters_per_unit or 1.0
    before = measure(clip, RigSettings()).features
    after = measure(again, RigSettings(units=units, up=clip.up_axis or "y")).features
    assert before.keys() == after.keys()
    for key, value in before.items():
        assert after[key] == pytest.approx(value, abs=1e-3), key


def test_writer_is_deterministic_and_leaves_no_temporary_files(tmp_path: Path) -> None:
    clip = generate(GaitSpec("walk", speed=1.4))
    write_bvh_clip(clip, tmp_path / "a.bvh")
    write_bvh_clip(clip, tmp_path / "b.bvh")
    assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "b.bvh").read_bytes()
    assert "-0.000000" not in (tmp_path / "a.bvh").read_text()
    broken = generate(GaitSpec("walk", speed=1.4))
    broken.rotations[3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        write_bvh_clip(broken, tmp_path / "c.bvh")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bvh", "b.bvh"]


def test_default_layout_six_channels_on_moving_joints_only(tmp_path: Path) -> None:
    clip = generate(GaitSpec("walk", speed=1.4), with_root_joint=True)
    write_bvh_clip(clip, tmp_path / "r.bvh")
    channels = {j.name: j.channels for j in read_header(tmp_path / "r.bvh").joints}
    assert len(channels["Root"]) == 6 and len(channels["Hips"]) == 6  # Hips moves under Root
    assert channels["Spine"] == ("Zrotation", "Xrotation", "Yrotation")


def test_template_must_match_the_skeleton(tmp_path: Path) -> None:
    source = tmp_path / "src.bvh"
    write_bvh_clip(generate(GaitSpec("walk", speed=1.4)), source)
    other = generate(GaitSpec("walk", speed=1.4), with_root_joint=True)
    with pytest.raises(ValueError, match="does not have the joints"):
        write_bvh_clip(other, tmp_path / "out.bvh", template=source)
    moving = read(source)[0]
    moving.translations[:, moving.skeleton.index("Spine"), 0] += np.linspace(0.0, 1.0, moving.frame_count)
    with pytest.raises(ValueError, match=r"'Spine'.*no position channels"):
        write_bvh_clip(moving, tmp_path / "out.bvh", template=source)
    assert not (tmp_path / "out.bvh").exists()


def test_template_with_a_two_channel_joint_and_position_channels_on_a_child(tmp_path: Path) -> None:
    source = _write(tmp_path, MIXED, name="mixed.bvh")
    clip = read(source)[0]
    out = tmp_path / "out.bvh"
    write_bvh_clip(clip, out, template=source)
    assert out.read_text().split("MOTION")[0] == MIXED.split("MOTION")[0]
    _assert_same_pose(clip, read(out)[0])
    hand = clip.skeleton.index("Hand")
    clip.rotations[:, hand] = Rotation.from_euler("Y", [[0.0], [20.0]], degrees=True).as_quat()
    with pytest.raises(ValueError, match=r"'Hand'.*\(ZX\) do not have"):
        write_bvh_clip(clip, out, template=source)


@pytest.mark.parametrize("name", ["131_01.bvh", "131_02.bvh"])
def test_cmu_template_round_trip_keeps_the_header(tmp_path: Path, name: str) -> None:
    source = shared_data("cmu", name)
    clip = read(source)[0]
    assert clip.fps == pytest.approx(120.0, rel=1e-4) and clip.skeleton.joint_count == 31
    out = tmp_path / name
    write_bvh_clip(clip, out, template=source)
    original = source.read_text().replace("\r", "").split("MOTION")[0]
    assert [line.rstrip() for line in original.splitlines()] == out.read_text().split("MOTION")[
        0
    ].splitlines()
    again = read(out)[0]
    _assert_same_pose(clip, again)
    assert np.abs(again.translations - clip.translations).max() < 1e-6  # %.6f of file values
    # A second generation changes nothing: the writer is a fixed point of read + write.
    write_bvh_clip(again, tmp_path / "twice.bvh", template=source)
    assert (tmp_path / "twice.bvh").read_bytes() == out.read_bytes()


def test_cmu_template_with_other_bone_lengths_writes_the_clip_offsets(tmp_path: Path) -> None:
    source = shared_data("cmu", "131_01.bvh")
    clip = read(source)[0].trimmed(0, 50)
    clip.translations = clip.translations * 1.5  # a taller actor: every OFFSET changes
    clip.skeleton = type(clip.skeleton)(
        clip.skeleton.names,
        clip.skeleton.parents,
        clip.skeleton.rest_translations * 1.5,
        clip.skeleton.rest_rotations,
    )
    out = tmp_path / "tall.bvh"
    write_bvh_clip(clip, out, template=source)
    again = read(out)[0]
    _assert_same_pose(clip, again)
    assert [j.channels for j in read_header(out).joints] == [j.channels for j in read_header(source).joints]
    assert [j.end_site for j in read_header(out).joints] == [j.end_site for j in read_header(source).joints]


@pytest.mark.parametrize("name", ["131_01.bvh", "131_02.bvh"])
def test_cmu_agrees_with_bvhio(name: str) -> None:
    bvhio = pytest.importorskip("bvhio")
    source = shared_data("cmu", name)
    clip = read(source)[0]
    _, world = forward_kinematics(clip)
    root = bvhio.readAsHierarchy(str(source))
    joints = {joint.Name: joint for joint, _, _ in root.layout()}
    assert tuple(joints) == clip.skeleton.names
    for frame in (0, 250, clip.frame_count - 1):
        root.loadPose(frame)
        for name in ("Hips", "LeftAnkle", "RightWrist", "Head", "LThumb"):
            theirs = np.array(list(joints[name].PositionWorld))
            ours = world[frame, clip.skeleton.index(name)]
            assert ours == pytest.approx(theirs, abs=1e-3), (frame, name)  # bvhio computes in float32
