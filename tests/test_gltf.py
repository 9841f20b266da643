"""glTF reader and writer: round trips, hand-built files checked against matrix maths, Fox.glb
checked against pygltflib, and broken files."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import shared_data
from scipy.spatial.transform import Rotation

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.gltf import _frame_rate, _key_interval, read
from blendspace_pipeline.writers.gltf import write_gltf_clip

Y = np.array([0.0, 1.0, 0.0])
X = np.array([1.0, 0.0, 0.0])


# --- a tiny glTF builder, independent of the writer under test ------------------------------------


class Builder:
    """Buffer views and accessors over one binary blob, and the files that hold them."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def view(self, data: bytes, stride: int | None = None) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        view: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if stride:
            view["byteStride"] = stride
        self.blob += data
        self.views.append(view)
        return len(self.views) - 1

    def accessor(self, values: Any, kind: str, *, stride: int | None = None, **extra: Any) -> int:
        array = np.asarray(values, dtype=np.float32).reshape(len(values), -1)
        if stride:  # interleave with padding so the stride is really used
            padded = np.zeros((len(array), stride // 4), dtype=np.float32)
            padded[:, : array.shape[1]] = array
            data = padded.tobytes()
        else:
            data = array.tobytes()
        accessor = {
            "bufferView": self.view(data, stride),
            "componentType": 5126,
            "count": len(array),
            "type": kind,
        }
        if kind == "SCALAR":
            accessor.update(min=[float(array.min())], max=[float(array.max())])
        accessor.update(extra)
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def raw_accessor(self, accessor: dict[str, Any]) -> int:
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def document(
        self, nodes: list[dict[str, Any]], skins: list[dict[str, Any]], animations: list[Any]
    ) -> dict[str, Any]:
        roots = [i for i in range(len(nodes)) if not any(i in n.get("children", []) for n in nodes)]
        return {
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": roots}],
            "nodes": nodes,
            "skins": skins,
            "animations": animations,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"byteLength": len(self.blob)}],
        }

    def write_glb(self, path: Path, document: dict[str, Any]) -> Path:
        text = json.dumps(document).encode()
        text += b" " * (-len(text) % 4)
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        total = 28 + len(text) + len(blob)
        path.write_bytes(
            struct.pack("<4sII", b"glTF", 2, total)
            + struct.pack("<II", len(text), 0x4E4F534A)
            + text
            + struct.pack("<II", len(blob), 0x004E4942)
            + blob
        )
        return path

    def write_gltf(self, path: Path, document: dict[str, Any], *, external: str | None = None) -> Path:
        if external:
            (path.parent / external).write_bytes(bytes(self.blob))
            document["buffers"][0]["uri"] = external.replace(" ", "%20")
        else:
            encoded = base64.b64encode(bytes(self.blob)).decode()
            document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + encoded
        path.write_text(json.dumps(document, indent=2))
        return path


def channel(node: int, path: str, sampler: int) -> dict[str, Any]:
    return {"sampler": sampler, "target": {"node": node, "path": path}}


TIMES = [0.0, 0.1, 0.2]  # keys at 10 fps: sampled at 30 fps
HIPS_KEYS = [[0.0, 1.0, 0.0], [0.3, 1.0, 0.0], [0.3, 1.0, 0.6]]
SPINE_ANGLES = [0.0, 90.0, 90.0]  # degrees about Y


def spine_keys() -> np.ndarray:
    return quat.from_axis_angle(Y, np.deg2rad(SPINE_ANGLES))


def two_joint_file(
    tmp_path: Path,
    interpolation: str = "LINEAR",
    *,
    container: str = ".glb",
    stride: int | None = None,
    normalized_rotations: bool = False,
    sparse_translations: bool = False,
    external: str | None = None,
    with_skin: bool = True,
) -> Path:
    """Hips (root joint) > Spine: Hips translation keys, Spine rotation keys."""
    builder = Builder()
    times = builder.accessor(TIMES, "SCALAR")
    if sparse_translations:
        # Base all zero (no bufferView); keys 1 and 2 replaced; key 0 is then (0, 0, 0).
        indices = builder.view(np.array([1, 2], dtype=np.uint16).tobytes())
        values = builder.view(np.asarray(HIPS_KEYS[1:], dtype=np.float32).tobytes())
        translations = builder.raw_accessor(
            {
                "componentType": 5126,
                "count": 3,
                "type": "VEC3",
                "sparse": {
                    "count": 2,
                    "indices": {"bufferView": indices, "componentType": 5123},
                    "values": {"bufferView": values},
                },
            }
        )
    else:
        translations = builder.accessor(HIPS_KEYS, "VEC3", stride=stride)
    if normalized_rotations:
        shorts = np.round(spine_keys() * 32767).astype(np.int16)
        rotations = builder.raw_accessor(
            {
                "bufferView": builder.view(shorts.tobytes()),
                "componentType": 5122,
                "normalized": True,
                "count": 3,
                "type": "VEC4",
            }
        )
    else:
        rotations = builder.accessor(spine_keys(), "VEC4")
    nodes = [
        {"name": "Hips", "translation": [0.0, 1.0, 0.0], "children": [1]},
        {"name": "Spine", "translation": [0.0, 0.25, 0.0]},
    ]
    samplers = [
        {"input": times, "output": translations, "interpolation": interpolation},
        {"input": times, "output": rotations, "interpolation": interpolation},
    ]
    animation = {
        "name": "tiny",
        "samplers": samplers,
        "channels": [channel(0, "translation", 0), channel(1, "rotation", 1)],
    }
    document = builder.document(nodes, [{"joints": [0, 1]}] if with_skin else [], [animation])
    if container == ".glb":
        return builder.write_glb(tmp_path / "tiny.glb", document)
    return builder.write_gltf(tmp_path / "tiny.gltf", document, external=external)


def assert_same_rotations(a: np.ndarray, b: np.ndarray, atol: float = 1e-6) -> None:
    np.testing.assert_allclose(np.abs(np.sum(a * b, axis=-1)), 1.0, atol=atol)


# --- sampling ---------------------------------------------------------------------------------------


def test_linear_keys_are_interpolated_at_30_fps(tmp_path: Path) -> None:
    [clip] = read(two_joint_file(tmp_path, "LINEAR"))
    assert clip.name == "tiny" and clip.fps == 30.0 and clip.frame_count == 7
    assert clip.skeleton.names == ("Hips", "Spine") and clip.skeleton.parents == (-1, 0)
    assert (clip.meters_per_unit, clip.up_axis) == (1.0, "y")
    assert any("30 fps" in note for note in clip.notes)
    hips = clip.translations[:, 0]
    np.testing.assert_allclose(hips[:, 0], [0.0, 0.1, 0.2, 0.3, 0.3, 0.3, 0.3], atol=1e-6)
    np.testing.assert_allclose(hips[:, 2], [0.0, 0.0, 0.0, 0.0, 0.2, 0.4, 0.6], atol=1e-6)
    expected = quat.from_axis_angle(Y, np.deg2rad([0.0, 30.0, 60.0, 90.0, 90.0, 90.0, 90.0]))
    assert_same_rotations(clip.rotations[:, 1], expected)
    # Joints a channel leaves alone keep their rest transform.
    np.testing.assert_allclose(clip.translations[:, 1], np.tile([0.0, 0.25, 0.0], (7, 1)))


@pytest.mark.parametrize(
    ("interval", "fps"),
    [
        (0.1, 30.0),  # 10 fps keys sample at 30
        (1 / 120, 120.0),
        (float(np.float32(1 / 24)), 24.0),
        (0.5, 24.0),  # keys every 12 frames at 24 fps or every 15 at 30: the first common rate
        (0.125, 24.0),  # every 3 frames at 24 fps
        (0.1001, 30000 / 1001),  # every 3 frames at 29.97 fps
        # Keys further apart than half a second are poses: a still keyed on Blender's first and
        # last scene frames (249 frames at 30, 25 or 29.97 fps: read at 24, 24 and 120 before).
        (249 / 30, 30.0),
        (float(np.float32(249 / 30)), 30.0),
        (249 / 25, 30.0),
        (249 * 1.001 / 30, 30.0),
        (7.77, 30.0),
    ],
)
def test_the_keys_interval_gives_the_rate_they_were_keyed_at(interval: float, fps: float) -> None:
    assert _frame_rate([interval], []) == fps


# Key times written to 3 or 4 decimals (at 2, steps differ by 10 ms: 24 fps alternates 0.04 and
# 0.05 s, no regular step to read).
ROUNDED = [
    (fps, decimals) for fps in (24.0, 30.0, 60.0, 120.0, 24000 / 1001, 30000 / 1001) for decimals in (3, 4)
]


@pytest.mark.parametrize(("fps", "decimals"), ROUNDED)
def test_key_times_written_to_a_few_decimals_read_at_their_rate(fps: float, decimals: int) -> None:
    """Exporters that round key times: 24 fps at 3 decimals read 23.976 (one rounded step fits it
    a little better), 60 at 3 decimals 58.8. A regular channel's span over its key count is the
    step; NTSC rates keyed exactly still read as such."""
    rounded = np.round(np.arange(2 * round(fps) + 1) / fps, decimals).astype(np.float32).astype(np.float64)
    exact = (np.arange(2 * round(fps) + 1) / fps).astype(np.float32).astype(np.float64)
    expected = fps if fps == round(fps) or decimals >= 4 else None
    for times, want in ((exact, fps), (rounded, expected)):
        if want is None:
            continue  # NTSC keys rounded to 2-3 decimals: either rate is within the rounding
        assert _frame_rate([_key_interval(times)], []) == pytest.approx(want, rel=1e-9), (fps, decimals)


def test_hand_keys_on_uneven_frames_are_no_regular_step() -> None:
    """Keys on frames 0, 2, 4, 7, 9, 11 at 24 fps: their span over their count (an average step
    of 2.2 frames) read them at 120 fps; the median step reads 24."""
    times = np.array([0, 2, 4, 7, 9, 11], dtype=np.float64) / 24.0
    assert _frame_rate([_key_interval(times)], []) == 24.0


def test_step_keys_hold_until_the_next_key(tmp_path: Path) -> None:
    [clip] = read(two_joint_file(tmp_path, "STEP"))
    hips = clip.translations[:, 0]
    np.testing.assert_allclose(hips[:, 0], [0.0, 0.0, 0.0, 0.3, 0.3, 0.3, 0.3], atol=1e-6)
    np.testing.assert_allclose(hips[:, 2], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6], atol=1e-6)
    expected = quat.from_axis_angle(Y, np.deg2rad([0.0, 0.0, 0.0, 90.0, 90.0, 90.0, 90.0]))
    assert_same_rotations(clip.rotations[:, 1], expected)


@pytest.mark.parametrize(
    "options",
    [
        {"stride": 16},
        {"normalized_rotations": True},
        {"container": ".gltf"},
        {"container": ".gltf", "external": "tiny data.bin"},
    ],
    ids=["byteStride", "normalized-int16", "data-uri", "external-bin"],
)
def test_accessor_layouts_read_the_same_keys(tmp_path: Path, options: dict[str, Any]) -> None:
    (tmp_path / "reference").mkdir()
    [reference] = read(two_joint_file(tmp_path / "reference", "LINEAR"))
    [clip] = read(two_joint_file(tmp_path, "LINEAR", **options))
    np.testing.assert_allclose(clip.translations, reference.translations, atol=1e-6)
    atol = 1e-4 if options.get("normalized_rotations") else 1e-6
    assert_same_rotations(clip.rotations, reference.rotations, atol=atol)


def test_sparse_accessor_replaces_the_listed_elements(tmp_path: Path) -> None:
    [clip] = read(two_joint_file(tmp_path, "LINEAR", sparse_translations=True))
    np.testing.assert_allclose(clip.translations[0, 0], [0.0, 0.0, 0.0])  # the zero base
    np.testing.assert_allclose(clip.translations[3, 0], HIPS_KEYS[1], atol=1e-6)
    np.testing.assert_allclose(clip.translations[6, 0], HIPS_KEYS[2], atol=1e-6)


def test_missing_external_buffer_is_reported(tmp_path: Path) -> None:
    path = two_joint_file(tmp_path, container=".gltf", external="tiny.bin")
    (tmp_path / "tiny.bin").unlink()
    with pytest.raises(ClipReadError, match=r"buffers\[0\].*tiny\.bin") as caught:
        read(path)
    assert caught.value.hint and ".bin" in caught.value.hint


# --- hierarchy folding, checked against plain 4x4 matrices --------------------------------------------


def trs_matrix(translation: Any, rotation: Any, scale: Any) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_quat(rotation).as_matrix() @ np.diag(scale)
    matrix[:3, 3] = translation
    return matrix


def test_armature_above_the_skin_and_nodes_between_joints_are_folded(tmp_path: Path) -> None:
    """Armature (not a joint: turned -90 deg about X, scaled 0.01, moving) > Hips > Offset (not a
    joint) > Spine, with the skin listing Spine before Hips."""
    frames = 3
    times = np.arange(frames) / 30.0
    armature_t = np.array([[1.0, 0.0, 2.0], [1.2, 0.0, 2.0], [1.4, 0.1, 2.0]])
    hips_t = np.array([[0.0, 0.0, 95.0], [3.0, 1.0, 95.0], [6.0, 0.0, 94.0]])
    hips_r = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.deg2rad([0.0, 20.0, 40.0]))
    spine_r = quat.from_axis_angle(X, np.deg2rad([10.0, -15.0, 5.0]))
    armature = {"rotation": list(quat.from_axis_angle(X, -np.pi / 2)), "scale": [0.01, 0.01, 0.01]}
    offset = {
        "translation": [0.0, 0.0, 12.0],
        "rotation": list(quat.from_axis_angle(Y, 0.3)),
        "scale": [2.0, 2.0, 2.0],
    }
    spine = {"translation": [0.0, 0.0, 20.0]}
    builder = Builder()
    when = builder.accessor(times, "SCALAR")
    outputs = [
        builder.accessor(armature_t, "VEC3"),
        builder.accessor(hips_t, "VEC3"),
        builder.accessor(hips_r, "VEC4"),
        builder.accessor(spine_r, "VEC4"),
    ]
    nodes = [
        {"name": "Armature", **armature, "children": [1]},
        {"name": "Hips", "children": [2]},
        {"name": "Offset", **offset, "children": [3]},
        {"name": "Spine", **spine},
    ]
    targets = [(0, "translation"), (1, "translation"), (1, "rotation"), (3, "rotation")]
    animation = {
        "samplers": [{"input": when, "output": o} for o in outputs],
        "channels": [channel(node, path, i) for i, (node, path) in enumerate(targets)],
    }
    path = builder.write_glb(
        tmp_path / "folded.glb", builder.document(nodes, [{"joints": [3, 1]}], [animation])
    )
    [clip] = read(path)
    assert clip.name == "folded"
    assert clip.skeleton.names == ("Hips", "Offset", "Spine") and clip.skeleton.parents == (-1, 0, 1)
    assert any("folded into the root joints" in note for note in clip.notes)
    _, positions = forward_kinematics(clip)
    for frame in range(frames):
        world = trs_matrix(armature_t[frame], armature["rotation"], armature["scale"])
        world = world @ trs_matrix(hips_t[frame], hips_r[frame], [1.0] * 3)
        np.testing.assert_allclose(positions[frame, 0], world[:3, 3], atol=1e-6)
        world = world @ trs_matrix(offset["translation"], offset["rotation"], offset["scale"])
        np.testing.assert_allclose(positions[frame, 1], world[:3, 3], atol=1e-6)
        world = world @ trs_matrix(spine["translation"], spine_r[frame], [1.0] * 3)
        np.testing.assert_allclose(positions[frame, 2], world[:3, 3], atol=1e-6)


def test_without_skins_the_animated_node_hierarchy_is_used(tmp_path: Path) -> None:
    [clip] = read(two_joint_file(tmp_path, with_skin=False))
    assert clip.skeleton.names == ("Hips", "Spine") and clip.skeleton.parents == (-1, 0)


# --- writer round trips -------------------------------------------------------------------------------


def to_y_up_metres(clip: Clip, positions: np.ndarray) -> np.ndarray:
    metres = positions * (clip.meters_per_unit or 1.0)
    if clip.up_axis == "z":  # (x, y, z) Z-up -> (x, z, -y) Y-up
        return np.stack([metres[..., 0], metres[..., 2], -metres[..., 1]], axis=-1)
    return metres


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize(("up", "meters_per_unit"), [("y", 1.0), ("z", 0.01)])
def test_round_trip_keeps_positions_and_features(
    tmp_path: Path, suffix: str, up: str, meters_per_unit: float
) -> None:
    spec = GaitSpec("arc", speed=1.6, direction=20.0, turn_rate=45.0, duration=1.2, fps=30.0)
    clip = generate(spec, up=up, meters_per_unit=meters_per_unit)
    path = tmp_path / f"arc{suffix}"
    write_gltf_clip(clip, path)
    [back] = read_clips(path)
    assert back.name == "arc" and back.fps == clip.fps and back.frame_count == clip.frame_count
    assert (back.meters_per_unit, back.up_axis) == (1.0, "y")
    assert back.skeleton.names == clip.skeleton.names and back.skeleton.parents == clip.skeleton.parents
    expected = to_y_up_metres(clip, forward_kinematics(clip)[1])
    np.testing.assert_allclose(forward_kinematics(back)[1], expected, atol=2e-5)
    original, read_back = measure(clip, RigSettings()).features, measure(back, RigSettings()).features
    for name in ("speed", "direction", "turn_rate", "forward_speed", "lateral_speed"):
        assert read_back[name] == pytest.approx(original[name], abs=1e-3), name
    assert read_back["speed"] == pytest.approx(1.6, rel=0.02)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind


def test_writer_is_deterministic_and_refuses_unknown_units(tmp_path: Path) -> None:
    clip = generate(GaitSpec("walk", speed=1.4, duration=0.5))
    first, second = tmp_path / "a.glb", tmp_path / "b.glb"
    write_gltf_clip(clip, first)
    write_gltf_clip(clip, second)
    assert first.read_bytes() == second.read_bytes()
    clip.meters_per_unit = None
    with pytest.raises(ValueError, match="metres per unit"):
        write_gltf_clip(clip, tmp_path / "c.glb")
    write_gltf_clip(clip, tmp_path / "c.glb", meters_per_unit=1.0)
    clip.up_axis = None
    with pytest.raises(ValueError, match="up axis"):
        write_gltf_clip(clip, tmp_path / "d.glb", meters_per_unit=1.0)
    with pytest.raises(ValueError, match=r"\.glb or \.gltf"):
        write_gltf_clip(clip, tmp_path / "d.fbx", meters_per_unit=1.0, up_axis="y")


# --- bad files --------------------------------------------------------------------------------------


def test_cubicspline_is_refused_with_a_pointer(tmp_path: Path) -> None:
    builder = Builder()
    times = builder.accessor(TIMES, "SCALAR")
    values = builder.accessor(np.zeros((9, 3)), "VEC3")  # in-tangent, value, out-tangent per key
    animation = {
        "samplers": [{"input": times, "output": values, "interpolation": "CUBICSPLINE"}],
        "channels": [channel(0, "translation", 0)],
    }
    document = builder.document([{"name": "Hips"}], [{"joints": [0]}], [animation])
    with pytest.raises(ClipReadError, match=r"animations\[0\]\.samplers\[0\].*CUBICSPLINE") as caught:
        read(builder.write_glb(tmp_path / "cubic.glb", document))
    assert caught.value.hint and "linear" in caught.value.hint


def test_garbage_and_truncated_glb_are_clip_read_errors(tmp_path: Path) -> None:
    good = tmp_path / "good.glb"
    write_gltf_clip(generate(GaitSpec("walk", speed=1.4, duration=0.5)), good)
    data = good.read_bytes()
    cases = {
        "noise.glb": bytes(np.random.default_rng(1).integers(0, 256, 4000, dtype=np.uint8)),
        "magic-noise.glb": b"glTF" + bytes(np.random.default_rng(2).integers(0, 256, 4000, dtype=np.uint8)),
        "half.glb": data[: len(data) // 2],
        "header.glb": data[:10],
        "empty.glb": b"",
        "json-cut.glb": struct.pack("<4sIIII", b"glTF", 2, 120, 100, 0x4E4F534A)
        + b'{"asset": {"vers'
        + b" " * 84,
        "bin-cut.glb": data[:8] + struct.pack("<I", len(data) - 200) + data[12:-200],
        "no-json.glb": struct.pack("<4sIIII", b"glTF", 2, 24, 4, 0x004E4942) + b"\0" * 4,
    }
    for name, content in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(ClipReadError) as caught:
            read_clips(path)
        assert caught.value.path == path, name


def test_broken_json_reports_line_and_bad_references_name_the_pointer(tmp_path: Path) -> None:
    broken = tmp_path / "broken.gltf"
    broken.write_text('{\n  "asset": {"version": "2.0"},\n  "nodes": [,]\n}\n')
    with pytest.raises(ClipReadError) as caught:
        read(broken)
    assert caught.value.line == 3
    path = two_joint_file(tmp_path, container=".gltf")
    document = json.loads(path.read_text())
    document["animations"][0]["samplers"][1]["output"] = 42
    path.write_text(json.dumps(document))
    with pytest.raises(ClipReadError, match=r"animations\[0\]\.samplers\[1\]\.output.*accessors\[42\]"):
        read(path)
    document["asset"]["version"] = "1.0"
    path.write_text(json.dumps(document))
    with pytest.raises(ClipReadError, match="version"):
        read(path)


def test_animation_of_other_objects_only_is_refused(tmp_path: Path) -> None:
    builder = Builder()
    times = builder.accessor(TIMES, "SCALAR")
    values = builder.accessor(HIPS_KEYS, "VEC3")
    nodes = [{"name": "Hips"}, {"name": "Lamp"}]
    animation = {"samplers": [{"input": times, "output": values}], "channels": [channel(1, "translation", 0)]}
    document = builder.document(nodes, [{"joints": [0]}], [animation])
    with pytest.raises(ClipReadError, match="skin"):
        read(builder.write_glb(tmp_path / "lamp.glb", document))


# --- Fox.glb (Khronos sample) -------------------------------------------------------------------------


def test_fox_animations() -> None:
    clips = read_clips(shared_data("khronos-fox", "Fox.glb"))
    assert [c.name for c in clips] == ["Fox/Survey", "Fox/Walk", "Fox/Run"]
    for clip, duration in zip(clips, (3.4167, 0.7083, 1.1583), strict=True):
        assert clip.fps == 24.0
        assert clip.duration == pytest.approx(duration, abs=1.0 / 24)
        assert clip.frame_count == round(duration * 24) + 1
        assert clip.skeleton.joint_count == 24 and clip.skeleton.names[:3] == (
            "_rootJoint",
            "b_Root_00",
            "b_Hip_01",
        )
        assert np.isfinite(forward_kinematics(clip)[1]).all()
        features = measure(clip, RigSettings()).features
        assert abs(features["speed"]) < 0.05 and abs(features["turn_rate"]) < 1.0  # in place


def pygltflib_world_positions(path: Path, animation_name: str, key: int) -> dict[str, np.ndarray]:
    """World positions of every node at key ``key``, from pygltflib's parse and 4x4 matrices."""
    pygltflib = pytest.importorskip("pygltflib")
    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()

    def values(index: int, width: int) -> np.ndarray:
        accessor = gltf.accessors[index]
        view = gltf.bufferViews[accessor.bufferView]
        start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
        return np.frombuffer(blob, np.float32, accessor.count * width, start).reshape(-1, width)

    local = {}
    for index, node in enumerate(gltf.nodes):
        local[index] = [
            node.translation or [0.0, 0.0, 0.0],
            node.rotation or [0.0, 0.0, 0.0, 1.0],
            node.scale or [1.0, 1.0, 1.0],
        ]
    animation = next(a for a in gltf.animations if a.name == animation_name)
    for item in animation.channels:
        sampler = animation.samplers[item.sampler]
        assert values(sampler.input, 1)[key, 0] == pytest.approx(key / 24.0, abs=1e-5)
        slot = {"translation": 0, "rotation": 1, "scale": 2}[item.target.path]
        local[item.target.node][slot] = values(sampler.output, 3 if slot != 1 else 4)[key]
    world: dict[str, np.ndarray] = {}

    def visit(index: int, parent: np.ndarray) -> None:
        matrix = parent @ trs_matrix(*local[index])
        world[gltf.nodes[index].name] = matrix[:3, 3]
        for child in gltf.nodes[index].children or []:
            visit(child, matrix)

    for root in gltf.scenes[gltf.scene or 0].nodes:
        visit(root, np.eye(4))
    return world


@pytest.mark.parametrize(("name", "key"), [("Survey", 40), ("Walk", 9), ("Run", 12)])
def test_fox_world_positions_match_pygltflib(name: str, key: int) -> None:
    path = shared_data("khronos-fox", "Fox.glb")
    expected = pygltflib_world_positions(path, name, key)
    clip = next(c for c in read(path) if c.name == f"Fox/{name}")
    _, positions = forward_kinematics(clip)
    for joint, joint_name in enumerate(clip.skeleton.names):
        np.testing.assert_allclose(positions[key, joint], expected[joint_name], atol=1e-3, err_msg=joint_name)
