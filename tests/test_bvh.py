"""The BVH reader and writer: hand-made files with known answers, round trips, real CMU files
compared with the independent `bvhio` reader, and errors with their line numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data
from scipy.spatial.transform import Rotation

from blendspace_pipeline.clip import forward_kinematics
from blendspace_pipeline.detect import RigSettings
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.measure import measure
from blendspace_pipeline.procedural import GaitSpec, generate
from blendspace_pipeline.readers.bvh import read
from blendspace_pipeline.writers.bvh import write_bvh_clip

TWO_JOINTS = """HIERARCHY
ROOT Hips
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition {order}
  JOINT Spine
  {{
    OFFSET 0 10 0
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


def _write(tmp_path: Path, text: str, name: str = "t.bvh", newline: str = "\n") -> Path:
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path


@pytest.mark.parametrize(
    "order",
    ["Zrotation Xrotation Yrotation", "Xrotation Yrotation Zrotation", "Yrotation Xrotation Zrotation"],
)
def test_channel_orders_against_a_hand_computed_pose(tmp_path: Path, order: str) -> None:
    angles = "30 45 60"
    clip = read(_write(tmp_path, TWO_JOINTS.format(order=order, a=angles)))[0]
    letters = "".join(w[0] for w in order.split())
    expected = Rotation.from_euler(letters, [30, 45, 60], degrees=True)
    _, world = forward_kinematics(clip)
    assert clip.fps == pytest.approx(25.0)
    # Frame 0: the root rotates, so the spine's offset (0, 10, 0) turns with it.
    assert world[0, 1] == pytest.approx(np.array([1, 2, 3]) + expected.apply([0, 10, 0]))
    # Frame 1: the root is unrotated and only the spine rotates: its own position is unchanged.
    assert world[1, 1] == pytest.approx([1, 12, 3])
    assert clip.skeleton.names == ("Hips", "Spine")  # End Sites are not joints


def test_three_channel_root_position_channels_on_a_child_crlf_and_tabs(tmp_path: Path) -> None:
    text = (
        "HIERARCHY\nROOT\tHips\n{\n\tOFFSET 1 2 3\n\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
        "\tJOINT Arm\n\t{\n\t\tOFFSET 5 0 0\n\t\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        "\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 1 0 0\n\t\t}\n\t}\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333333\n"
        "0 0 0  7 8 9 0 0 0   \n"
    )
    clip = read(_write(tmp_path, text, newline="\r\n"))[0]
    _, world = forward_kinematics(clip)
    assert world[0, 0] == pytest.approx([1, 2, 3])  # no position channels: the OFFSET stays
    assert world[0, 1] == pytest.approx([8, 10, 12])  # position channels replace the OFFSET


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n", 4, "OFFSET needs 3"),
        ("HIERARCHY\nROOT Hips\n{\n  CHANNELS 3 Xrotation Yrotation Wrotation\n}\n", 4, "unknown channel"),
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  SCALE 1\n}\n", 5, "unexpected 'SCALE'"),
        ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n", 4, "truncated"),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n",
            7,
            "no frames",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0\n1\n2\n",
            8,
            "Frame Time",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 2 Xrotation Yrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n1 2\n3\n",
            10,
            "frame 2 has 1",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 3\nFrame Time: 0.1\n1\n2\n",
            10,
            "says 3 but the file has 2",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n1\n2\n",
            10,
            "says 1 but the file has 2",
        ),
        (
            "HIERARCHY\nROOT Hips\n{\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\nx1\n",
            9,
            "'x1' is not a number",
        ),
        ("hello\n", 1, "expected HIERARCHY"),
    ],
)
def test_errors_name_their_line(tmp_path: Path, text: str, line: int, words: str) -> None:
    with pytest.raises(ClipReadError) as caught:
        read(_write(tmp_path, text))
    assert caught.value.line == line, caught.value.render()
    assert words in caught.value.message
    assert caught.value.hint


def test_binary_garbage_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "g.bvh"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ClipReadError, match="not a text BVH"):
        read(path)


@pytest.mark.parametrize(
    "spec",
    [
        GaitSpec("walk", speed=1.4, turn_rate=30.0),
        GaitSpec("strafe", speed=1.2, direction=90.0),
        GaitSpec("spin", turn_rate=360.0, duration=1.0),
    ],
)
def test_procedural_round_trip_keeps_pose_and_features(tmp_path: Path, spec: GaitSpec) -> None:
    clip = generate(spec)
    path = tmp_path / "c.bvh"
    write_bvh_clip(clip, path)
    again = read(path)[0]
    assert again.skeleton.names == clip.skeleton.names
    assert np.abs(forward_kinematics(again)[1] - forward_kinematics(clip)[1]).max() < 1e-4
    before, after = measure(clip, RigSettings()).features, measure(again, RigSettings(units="m")).features
    for key in ("speed", "direction", "turn_rate"):
        assert after[key] == pytest.approx(before[key], abs=1e-3)


def test_writer_is_deterministic(tmp_path: Path) -> None:
    clip = generate(GaitSpec("walk", speed=1.4))
    write_bvh_clip(clip, tmp_path / "a.bvh")
    write_bvh_clip(clip, tmp_path / "b.bvh")
    assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "b.bvh").read_bytes()


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
    assert np.abs(forward_kinematics(again)[1] - forward_kinematics(clip)[1]).max() < 1e-3


def test_cmu_agrees_with_bvhio(tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio")
    source = shared_data("cmu", "131_01.bvh")
    clip = read(source)[0]
    _, world = forward_kinematics(clip)
    root = bvhio.readAsHierarchy(str(source))
    joints = {joint.Name: joint for joint, _, _ in root.layout()}
    for frame in (0, 250, 993):
        root.loadPose(frame)
        for name in ("Hips", "LeftAnkle", "RightWrist", "Head"):
            theirs = np.array(list(joints[name].PositionWorld))
            ours = world[frame, clip.skeleton.index(name)]
            assert ours == pytest.approx(theirs, abs=1e-3), (frame, name)
