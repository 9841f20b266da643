"""Blender as a real DCC (`bpy` from PyPI): it writes FBX from the shared BVH and glTF clips and our
FBX reader measures them as it measures the sources; it imports every generated GLB and USD clip
and its joint world positions match ours within 1 mm on every frame.

Blender runs in a subprocess per test (it owns global state and is ~370 MB of native code); the
tests skip when `bpy` (or, for FBX, `pufbx`) cannot be imported."""

from __future__ import annotations

import json
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data
from test_fixes import _build, _project

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.notes import HELD_MARK
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip

MM = 1e-3


@cache
def _bpy_problem() -> str | None:
    """Why Blender cannot run here, or None."""
    try:
        done = subprocess.run(
            [sys.executable, "-c", "import bpy; print(bpy.app.version_string)"],
            capture_output=True,
            text=True,
            timeout=300,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return f"bpy did not start: {error}"
    return None if done.returncode == 0 else f"bpy cannot be imported: {done.stderr.strip()[-300:]}"


@pytest.fixture
def blender() -> None:
    problem = _bpy_problem()
    if problem:
        pytest.skip(problem)


@pytest.fixture
def fbx() -> None:
    pytest.importorskip("pufbx", reason="the FBX extra (pufbx) is not installed")


# Runs inside Blender: argv[1] is a JSON list of jobs.
_SCRIPT = r"""
import json, sys
import bpy

def reset(fps):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.fps = int(round(fps))
    bpy.context.scene.render.fps_base = round(fps) / fps

for job in json.loads(sys.argv[1]):
    reset(job.get("fps", 24))
    source = job["source"]
    if source.endswith(".bvh"):
        bpy.ops.import_anim.bvh(filepath=source, global_scale=job.get("scale", 1.0),
                                frame_start=job.get("frame_start", 1),
                                update_scene_fps=True, update_scene_duration=True)
    elif source.endswith((".glb", ".gltf")):
        bpy.ops.import_scene.gltf(filepath=source)
    else:
        bpy.ops.wm.usd_import(filepath=source)
    if job.get("rename"):  # names that say nothing, as a hand-built rig's: Bone, Bone.001, ...
        (armature,) = [o for o in bpy.data.objects if o.type == "ARMATURE"]
        bones = list(armature.data.bones)
        for i, bone in enumerate(bones):
            bone.name = f"tmp{i}"
        for i, bone in enumerate(bones):
            bone.name = "Bone" if i == 0 else f"Bone.{i:03d}"
    if job["kind"] == "glb":
        bpy.ops.export_scene.gltf(filepath=job["out"], export_format="GLB")
        continue
    if job["kind"] == "usd":  # the scene's frames (Blender's default 1-250), as an artist exports
        bpy.ops.wm.usd_export(filepath=job["out"], export_animation=True)
        continue
    if job["kind"] == "fbx":
        # The take spans the clip, not the scene's default 250 frames (which would hold the last pose).
        # With "scene_end", the scene ends there instead, as an artist's scene often does.
        actions = [o.animation_data.action for o in bpy.data.objects if o.animation_data and o.animation_data.action]
        if actions:
            first, last = actions[0].frame_range
            bpy.context.scene.frame_start = job.get("scene_start", int(round(first)))
            bpy.context.scene.frame_end = job.get("scene_end", int(round(last)))
        if job.get("current"):  # the frame the scene shows: an armature-only FBX's only pose at rest
            bpy.context.scene.frame_set(job["current"])
        # Every action as its own take, sampled on every frame (no curve simplification).
        bpy.ops.export_scene.fbx(filepath=job["out"], bake_anim=True, bake_anim_simplify_factor=job.get("simplify", 0.0),
                                 add_leaf_bones=False, bake_anim_use_all_actions=job.get("all_actions", False),
                                 bake_anim_use_nla_strips=False)
        continue
    # kind == "positions": every bone's head in Blender's world, on every frame of the action.
    (armature,) = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    first, last = (int(round(f)) for f in armature.animation_data.action.frame_range)
    names = [bone.name for bone in armature.pose.bones]
    frames = []
    for frame in range(first, last + 1):
        bpy.context.scene.frame_set(frame)
        frames.append([list(armature.matrix_world @ bone.head) for bone in armature.pose.bones])
    with open(job["out"], "w") as handle:
        json.dump({"names": names, "positions": frames, "first": first}, handle)
"""


def _run_blender(jobs: list[dict[str, object]]) -> None:
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT, json.dumps(jobs)], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]


def _world_m(clip: Clip) -> np.ndarray:
    """Joint world positions in metres, in the clip's own up axis."""
    return np.asarray(forward_kinematics(clip)[1]) * (clip.meters_per_unit or 1.0)


def _common(a: Clip, b: Clip) -> tuple[list[int], list[int]]:
    names = [n for n in a.skeleton.names if n in b.skeleton.names]
    return [a.skeleton.index(n) for n in names], [b.skeleton.index(n) for n in names]


# --- FBX written by Blender, read by us --------------------------------------------------------


def test_blender_fbx_of_a_procedural_walk_measures_its_known_speed(
    tmp_path: Path, blender: None, fbx: None
) -> None:
    # Truth by construction: 1.4 m/s forward, no turn, written as BVH in metres.
    spec = GaitSpec("walk", speed=1.4, duration=2.0)
    bvh = tmp_path / "walk.bvh"
    write_bvh_clip(generate(spec), bvh)
    out = tmp_path / "walk.fbx"
    _run_blender([{"kind": "fbx", "source": str(bvh), "out": str(out)}])
    (clip,) = read_clips(out)
    assert clip.meters_per_unit is not None and clip.up_axis == "y"
    features = measure(clip, RigSettings()).features
    assert features["speed"] == pytest.approx(1.4, abs=0.02)
    assert features["turn_rate"] == pytest.approx(0.0, abs=1.0)
    source = read_clips(bvh)[0]
    assert clip.frame_count == source.frame_count and clip.fps == pytest.approx(source.fps, rel=1e-4)
    # And through the command: an FBX is a clip like any other in a manifest.
    manifest = tmp_path / "m.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: walk.fbx\n", encoding="utf-8")
    assert main(["check", str(manifest), "--format", "json"]) in (0, 1)


def test_blender_fbx_of_a_scene_longer_than_the_walk_measures_the_walk(
    tmp_path: Path, blender: None, fbx: None
) -> None:
    """A 2 s walk exported from a 250-frame scene: Blender bakes the last pose for the 6 s after
    it. The held keys are left out (the walk read 0.27 m/s, and `range: auto` 1.34 m/s on its
    last second), and the measured range is the walk's."""
    spec = GaitSpec("walk", speed=1.4, duration=2.0, fps=24.0)
    bvh = tmp_path / "walk.bvh"
    write_bvh_clip(generate(spec), bvh)
    out = tmp_path / "walk.fbx"
    # Blender's default curve simplification too, and a scene that starts 19 frames before the
    # action: the simplified holds drift (a straight ramp), no exact repeat.
    _run_blender([{"kind": "fbx", "source": str(bvh), "out": str(out), "frame_start": 20, "scene_start": 1,
                   "scene_end": 250, "simplify": 1.0}])  # fmt: skip
    (clip,) = read_clips(out)
    assert clip.frame_count >= 240  # the scene's frames, the holds included
    for time_range in (None, "auto"):
        measured = measure(clip, RigSettings(), time_range)
        assert measured.features["speed"] == pytest.approx(1.4, abs=0.02), time_range
        assert measured.range_used is not None
        assert measured.range_used[0] >= 19 / 24 - 1.5 / 24 and measured.range_used[1] <= 21 / 24 + 2.0
    assert any(note.startswith(HELD_MARK) for note in measure(clip, RigSettings()).notes)


def test_blender_usd_of_a_still_idle_is_a_still_pose_over_the_scene(tmp_path: Path, blender: None) -> None:
    """Blender writes a pose that never moves with no time samples at all: it was read as one
    frame and the build stopped (exit 2), where the GLB and FBX of the same idle build. It is
    held over the stage's time codes now, as an engine imports it, and measured as a still pose."""
    bvh = tmp_path / "idle.bvh"
    write_bvh_clip(generate(GaitSpec("idle", duration=2.0, fps=30.0)), bvh)
    out = tmp_path / "idle.usdc"
    _run_blender([{"kind": "usd", "source": str(bvh), "out": str(out), "fps": 30}])
    (clip,) = read_clips(out)
    assert clip.frame_count >= 60 and clip.fps == pytest.approx(30.0)
    assert any("no time samples: its pose held over the stage's time codes" in n for n in clip.notes), (
        clip.notes
    )
    measured = measure(clip, RigSettings())
    assert measured.features["speed"] == pytest.approx(0.0, abs=1e-6)
    assert measured.features["turn_rate"] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    "spec",
    [
        GaitSpec("walk_left", speed=1.4, turn_rate=30.0, duration=2.0),
        GaitSpec("strafe_right", speed=1.2, direction=-90.0, duration=2.0, stride_length=1.0),
    ],
    ids=lambda s: s.name,
)
@pytest.mark.parametrize("kind", ["glb", "fbx"])
def test_blender_exports_with_generic_bone_names_measure_their_known_motion(
    tmp_path: Path, blender: None, spec: GaitSpec, kind: str, request: pytest.FixtureRequest
) -> None:
    """A hand-built Blender rig's names (`Bone`, `Bone.001`...) say nothing of left and right: the
    legs are found by the skeleton's shape. Before, the facing came from the root bone's axis,
    with `root` and `facing` guesses (and 90 deg off where the root bone points forward). The FBX
    keeps no rest pose but the exported frame's (a stride, no mirror image of itself): its legs
    are the chains the take moves, found without asking for a mirror image."""
    if kind == "fbx":
        request.getfixturevalue("fbx")
    bvh = tmp_path / "walk.bvh"
    write_bvh_clip(generate(spec), bvh)
    out = tmp_path / f"walk.{kind}"
    # The FBX exported mid-stride (the frame the scene shows is its rest pose).
    _run_blender([{"kind": kind, "source": str(bvh), "out": str(out), "rename": True, "current": 8}])
    (clip,) = read_clips(out)
    assert "Bone.001" in clip.skeleton.names
    measured = measure(clip, RigSettings())
    assert measured.facing == "hip line (hips by the skeleton's shape)"
    assert not measured.guesses, measured.guesses
    assert measured.features["speed"] == pytest.approx(spec.signed_speed, abs=0.02)
    assert measured.features["turn_rate"] == pytest.approx(spec.turn_rate, abs=1.0)
    assert measured.features["direction"] == pytest.approx(spec.direction, abs=1.0)


@pytest.mark.parametrize("take", ["131_01", "131_02"])
def test_blender_fbx_of_shared_bvh_measures_like_the_bvh(
    tmp_path: Path, blender: None, fbx: None, take: str
) -> None:
    bvh = shared_data("cmu", f"{take}.bvh")
    source = read_clips(bvh)[0]
    ours = measure(source, RigSettings())
    # BVH has no unit: Blender is told ours, so its metres are the metres we measured in.
    out = tmp_path / f"{take}.fbx"
    _run_blender([{"kind": "fbx", "source": str(bvh), "out": str(out), "scale": ours.meters_per_unit}])
    (clip,) = read_clips(out)
    theirs = measure(clip, RigSettings())
    for feature in ("speed", "forward_speed", "lateral_speed", "turn_rate", "direction", "duration"):
        assert theirs.features[feature] == pytest.approx(ours.features[feature], abs=0.01), feature
    a, b = _common(source, clip)
    difference = np.abs(_world_m(source)[:, a] * ours.meters_per_unit / (source.meters_per_unit or 1.0)
                        - _world_m(clip)[:, b])  # fmt: skip
    assert difference.max() < MM


def test_blender_fbx_of_the_shared_gltf_keeps_one_clip_per_take(
    tmp_path: Path, blender: None, fbx: None
) -> None:
    glb = shared_data("khronos-fox", "Fox.glb")
    sources = {c.name.split("/")[-1]: c for c in read_clips(glb)}
    out = tmp_path / "fox.fbx"
    _run_blender([{"kind": "fbx", "source": str(glb), "out": str(out), "fps": 24, "all_actions": True}])
    clips = {c.name.split("/")[-1]: c for c in read_clips(out)}
    assert {name.split("|")[-1] for name in clips} >= set(sources)  # Survey, Walk, Run
    for name, source in sources.items():
        (clip,) = [c for key, c in clips.items() if key.split("|")[-1] == name]
        assert clip.name == f"fox/{name}"
        a, b = _common(source, clip)
        assert len(a) >= 20  # the fox's bones, by name
        assert source.frame_count == clip.frame_count
        # Where the take has keys off the 24 fps grid (Run: 25 keys over 1.158 s), Blender
        # interpolates quaternion components linearly between them and we slerp: frames are
        # compared where a glTF key falls on them, which is every frame of Survey and Walk.
        frames = _keyed_frames(glb, name, source.fps, source.frame_count)
        assert len(frames) >= 0.5 * source.frame_count
        ours, theirs = _world_m(source)[frames][:, a], _world_m(clip)[frames][:, b]
        assert np.abs(ours - theirs).max() < MM, name


def _keyed_frames(glb: Path, animation: str, fps: float, count: int) -> list[int]:
    """Frames of ``animation`` on which every one of its channels has a key."""
    import pygltflib

    document = pygltflib.GLTF2().load(str(glb))
    (found,) = [a for a in document.animations if a.name == animation]
    keyed = set(range(count))
    for input_index in {sampler.input for sampler in found.samplers}:
        accessor = document.accessors[input_index]
        view = document.bufferViews[accessor.bufferView]
        blob = document.binary_blob()
        start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
        times = np.frombuffer(blob, dtype="<f4", count=accessor.count, offset=start)
        keyed &= {i for i in range(count) if np.min(np.abs(times - i / fps)) < 1e-4}
    return sorted(keyed)


# --- generated clips opened in Blender ----------------------------------------------------------


def test_blender_opens_every_generated_clip_where_we_put_the_joints(tmp_path: Path, blender: None) -> None:
    doc = _build(_project(tmp_path), tmp_path / "out")
    made = [s["name"] for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made
    files = [tmp_path / "out" / "clips" / f"{name}{suffix}" for name in made for suffix in (".glb", ".usda")]
    jobs: list[dict[str, object]] = [
        {
            "kind": "positions",
            "source": str(path),
            "out": str(path.with_suffix(path.suffix + ".json")),
            "fps": 30,
        }
        for path in files
    ]
    _run_blender(jobs)
    for path in files:
        clip = read_clips(path)[0]
        assert clip.fps == 30.0
        seen = json.loads(path.with_suffix(path.suffix + ".json").read_text())
        positions = np.asarray(seen["positions"])  # (F, J, 3) Blender world: Z up, metres
        as_y_up = np.stack([positions[..., 0], positions[..., 2], -positions[..., 1]], axis=-1)
        ours = _world_m(clip)
        if clip.up_axis == "z":
            ours = np.stack([ours[..., 0], ours[..., 2], -ours[..., 1]], axis=-1)
        index = [clip.skeleton.index(name) for name in seen["names"]]
        assert len(index) == clip.skeleton.joint_count, path.name
        assert positions.shape[0] == clip.frame_count, path.name  # every frame
        assert np.abs(as_y_up - ours[:, index]).max() < MM, path.name
