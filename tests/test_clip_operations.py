"""Blend, mirror and straighten against ground truth: procedural clips whose features are known,
world-space mirror images checked joint by joint, and real rigs from ../shared/data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, forward_kinematics
from blendspace_pipeline.motion.clip_ops import (
    IncompatibleClips,
    blend_clips,
    detect_cycle,
    mirror_clip,
    mirror_pairs,
    straighten_clip,
)
from blendspace_pipeline.motion.clip_ops.root_motion import (
    compose,
    decompose,
    ground_basis,
    integrate,
    step_velocities,
)
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips

SETTINGS = RigSettings()
SPAN = {"turn_rate": 360.0, "speed": 9.0}  # the default axis ranges: 2% of each is the tolerance


def features(clip: Clip) -> dict[str, float]:
    return measure(clip, SETTINGS).features


def test_decompose_then_compose_is_the_identity() -> None:
    clip = generate(GaitSpec("w", speed=1.4, turn_rate=60.0, direction=30.0, duration=1.5))
    motion = decompose(clip, SETTINGS)
    velocity, yaw_rate = step_velocities(motion.heading, motion.ground, clip.fps)
    heading, ground = integrate(velocity, yaw_rate, clip.fps, float(motion.heading[0]), motion.ground[0])
    again = compose(
        clip, motion, heading, ground, clip.rotations, clip.translations, name="r", fps=clip.fps, note=""
    )
    assert np.abs(forward_kinematics(again)[1] - forward_kinematics(clip)[1]).max() < 1e-9


@pytest.mark.parametrize(
    ("a", "b", "weights"),
    [
        (
            GaitSpec("slow", speed=1.0),
            GaitSpec("fast", speed=3.0, duration=0.8, stride_length=2.4),
            (0.5, 0.5),
        ),
        (GaitSpec("tip", turn_rate=90.0, duration=2.0), GaitSpec("idle", duration=2.0), (0.5, 0.5)),
        (
            GaitSpec("walk", speed=1.4, turn_rate=60.0, duration=1.5),
            GaitSpec("tip", turn_rate=90.0, duration=2.0),
            (0.3, 0.7),
        ),
        (
            GaitSpec("back", speed=1.1, direction=180.0),
            GaitSpec("idle", duration=2.0, fps=60.0),
            (0.25, 0.75),
        ),
        (
            GaitSpec("left", speed=4.0, turn_rate=90.0),
            GaitSpec("right", speed=4.0, turn_rate=-90.0),
            (0.6, 0.4),
        ),
    ],
)
def test_blend_measures_the_weighted_features(a: GaitSpec, b: GaitSpec, weights: tuple[float, float]) -> None:
    blended = blend_clips([generate(a), generate(b)], weights, name="mix", settings=SETTINGS)
    got = features(blended)
    for feature, span in SPAN.items():
        if feature == "speed":
            want = weights[0] * a.signed_speed + weights[1] * b.signed_speed
        else:
            want = weights[0] * a.turn_rate + weights[1] * b.turn_rate
        assert abs(got[feature] - want) <= 0.02 * span, (feature, got[feature], want)
    assert_blend_duration(blended, [generate(a), generate(b)], weights)
    assert blended.notes and "blend of" in blended.notes[0]


def assert_blend_duration(blended: Clip, clips: list[Clip], weights: tuple[float, float]) -> None:
    """Clips without a gait blend over the weighted duration; walking clips over a whole number of
    the weighted stride period, the number nearest the weighted duration (so the result loops)."""
    weighted = sum(w * clip.duration for w, clip in zip(weights, clips, strict=True))
    cycles = [(w, detect_cycle(clip, SETTINGS)) for w, clip in zip(weights, clips, strict=True)]
    walking = [(w, cycle.period) for w, cycle in cycles if cycle is not None and w > 0.0]
    frame = 1.0 / blended.fps
    if not walking:
        assert blended.duration == pytest.approx(weighted, abs=frame)
        return
    period = sum(w * p for w, p in walking) / sum(w for w, _ in walking)
    strides = blended.duration / period
    assert strides >= 1.0 - frame / period
    assert abs(strides - round(strides)) * period <= frame, (blended.duration, period)
    assert abs(blended.duration - weighted) <= period / 2 + frame, (blended.duration, weighted)


def test_blend_refuses_different_skeletons() -> None:
    plain = generate(GaitSpec("a", speed=1.0))
    rooted = generate(GaitSpec("b", speed=1.0), with_root_joint=True)
    with pytest.raises(IncompatibleClips, match="different skeletons"):
        blend_clips([plain, rooted], [0.5, 0.5], name="x", settings=SETTINGS)


def test_blend_is_deterministic() -> None:
    clips = [generate(GaitSpec("a", speed=1.0)), generate(GaitSpec("b", speed=2.0, turn_rate=30.0))]
    one = blend_clips(clips, [0.4, 0.6], name="x", settings=SETTINGS)
    two = blend_clips(clips, [0.4, 0.6], name="x", settings=SETTINGS)
    assert np.array_equal(one.rotations, two.rotations) and np.array_equal(one.translations, two.translations)


def facing_frame_positions(clip: Clip, settings: RigSettings = SETTINGS) -> np.ndarray:
    """Joint positions on every frame in the clip's initial facing frame: (forward, left, up)."""
    motion = decompose(clip, settings)
    _, world = forward_kinematics(clip)
    e1, e2 = ground_basis(motion.up_axis)
    h0 = float(motion.heading[0])
    forward, left = np.cos(h0) * e1 + np.sin(h0) * e2, -np.sin(h0) * e1 + np.cos(h0) * e2
    relative = world - motion.trajectory_points()[0]
    return np.stack([relative @ forward, relative @ left, relative @ motion.up], axis=-1)


def assert_mirror_image(
    source: Clip, mirrored: Clip, metres_per_unit: float, tolerance_m: float = 0.01
) -> None:
    partner = mirror_pairs(source.skeleton)
    ours = facing_frame_positions(mirrored)
    expected = facing_frame_positions(source)[:, partner] * np.array([1.0, -1.0, 1.0])
    error = np.abs(ours - expected).max() * metres_per_unit
    assert error < tolerance_m, f"largest joint error {error * 100:.2f} cm"


@pytest.mark.parametrize(
    "options",
    [{}, {"with_root_joint": True, "root_yaw_offset": 90.0}, {"up": "z", "meters_per_unit": 0.01}],
    ids=["plain", "turned-root-joint", "z-up-cm"],
)
def test_mirror_is_the_world_space_mirror_image(options: dict[str, object]) -> None:
    source = generate(
        GaitSpec("walk_turn_left", speed=1.4, turn_rate=30.0, direction=20.0, start_heading=70.0), **options
    )  # type: ignore[arg-type]
    mirrored = mirror_clip(source, settings=SETTINGS, name="walk_turn_right")
    assert_mirror_image(source, mirrored, float(options.get("meters_per_unit", 1.0)))  # type: ignore[arg-type]
    before, after = features(source), features(mirrored)
    assert after["turn"] == pytest.approx(-before["turn"], abs=0.1)
    assert after["direction"] == pytest.approx(-before["direction"], abs=0.1)
    assert after["speed"] == pytest.approx(before["speed"], abs=0.01)


def test_mirror_of_a_z_up_take_that_states_no_up_axis() -> None:
    """A Z-up BVH whose hierarchy stands along Y (the root's rotation lays it into Z, as this
    project's generator and many exporters write it), with nothing in the file saying Z-up: the
    rest pose alone reads Y-up. The mirror came out upside down (read `-z` up) and unmirrored
    (turn_rate +45), and the build rejected the fix as not making the space better."""
    source = generate(
        GaitSpec("walk_turn_left", speed=1.3, turn_rate=45.0, direction=20.0), up="z", meters_per_unit=0.01
    )
    source.up_axis = None
    source.meters_per_unit = None  # as read from a BVH file
    mirrored = mirror_clip(source, settings=SETTINGS, name="walk_turn_right")
    assert_mirror_image(source, mirrored, 0.01)
    after = measure(mirrored, SETTINGS)
    assert after.up_axis == "z"
    assert after.features["turn_rate"] == pytest.approx(-45.0, abs=0.5)
    assert after.features["direction"] == pytest.approx(-20.0, abs=0.5)


def asymmetric_rig(clip: Clip, seed: int = 3) -> Clip:
    """The same motion on a rig whose left joints have arbitrary local axes (as Mixamo-style rigs
    do): every left joint gets a random rest/local frame, compensated so the world pose is equal."""
    rng = np.random.default_rng(seed)
    skeleton = clip.skeleton
    extra = np.tile(quat.IDENTITY, (skeleton.joint_count, 1))
    for joint, name in enumerate(skeleton.names):
        if name.startswith("Left"):
            axis = rng.normal(size=3)
            extra[joint] = quat.from_axis_angle(axis / np.linalg.norm(axis), rng.uniform(0.5, 2.5))
    # A joint's local frame turns by extra[j]: local rotation R_j -> R_j * extra[j]; its children
    # see a parent frame turned by extra[j], so their local rotation and offset are re-expressed.
    rotations = clip.rotations.copy()
    translations = clip.translations.copy()
    rest_rot = skeleton.rest_rotations.copy()
    rest_t = skeleton.rest_translations.copy()
    for joint, parent in enumerate(skeleton.parents):
        rotations[:, joint] = quat.multiply(rotations[:, joint], extra[joint][None])
        rest_rot[joint] = quat.multiply(rest_rot[joint], extra[joint])
        if parent >= 0:
            undo = quat.conjugate(extra[parent])
            rotations[:, joint] = quat.multiply(undo[None], rotations[:, joint])
            rest_rot[joint] = quat.multiply(undo, rest_rot[joint])
            translations[:, joint] = quat.rotate(
                np.broadcast_to(undo, (len(rotations), 4)), translations[:, joint]
            )
            rest_t[joint] = quat.rotate(undo, rest_t[joint])
    rig = Skeleton(skeleton.names, skeleton.parents, rest_t, rest_rot)
    return Clip(
        clip.name, clip.source, rig, rotations, translations, clip.fps, clip.meters_per_unit, clip.up_axis
    )


def test_mirror_on_a_rig_with_asymmetric_joint_axes() -> None:
    plain = generate(GaitSpec("walk_turn_left", speed=1.4, turn_rate=45.0))
    rig = asymmetric_rig(plain)
    assert np.abs(forward_kinematics(rig)[1] - forward_kinematics(plain)[1]).max() < 1e-9  # same motion
    mirrored = mirror_clip(rig, settings=SETTINGS, name="m")
    assert_mirror_image(rig, mirrored, 1.0)
    # Naively swapping left and right local rotations would put the legs in the wrong place.
    assert features(mirrored)["turn_rate"] == pytest.approx(-45.0, abs=0.5)


def test_mirror_on_the_real_fox_rig() -> None:
    clips = read_clips(shared_data("khronos-fox", "Fox.glb"))
    walk = next(c for c in clips if c.name.endswith("Walk"))
    # Fox's joint axes come from Blender: the left and right legs have the *same* local rest
    # rotation, not mirror images, so swapping local rotations cannot mirror this rig.
    rest = walk.skeleton.rest_rotations
    names = walk.skeleton.names
    left, right = names.index("b_LeftLeg01_015"), names.index("b_RightLeg01_019")
    assert np.allclose(rest[left], rest[right], atol=1e-3) and not np.allclose(rest[left], quat.IDENTITY)
    mirrored = mirror_clip(walk, settings=SETTINGS, name="Walk_mirror")
    # Fox.glb is modelled in centimetres despite glTF's metres (115 units from nose to tail).
    _, world = forward_kinematics(walk)
    assert 100 < np.ptp(world[0], axis=0).max() < 130
    assert_mirror_image(walk, mirrored, 0.01)


def test_mirror_on_cmu_mocap() -> None:
    clip = read_clips(shared_data("cmu", "131_01.bvh"))[0].trimmed(240, 480)
    mirrored = mirror_clip(clip, settings=SETTINGS, name="m")
    # CMU's left and right bones are not the same length (up to 0.5 units, 3 cm, at the fingers)
    # and BVH keeps each joint's own OFFSET, so each joint may differ from the exact mirror image
    # by the length differences along its chain, plus the 1 cm of the issue.
    skeleton = clip.skeleton
    partner = mirror_pairs(skeleton)
    reflect = np.array([-1.0, 1.0, 1.0])  # CMU rest pose: X is the character's side
    bone = np.abs(skeleton.rest_translations - skeleton.rest_translations[partner] * reflect).max(axis=1)
    chain = bone.copy()
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            chain[joint] += chain[parent]
    ours = facing_frame_positions(mirrored)
    expected = facing_frame_positions(clip)[:, partner] * np.array([1.0, -1.0, 1.0])
    error = np.linalg.norm(ours - expected, axis=-1).max(axis=0) * 0.0564
    assert (error <= 0.01 + np.sqrt(3) * chain * 0.0564).all(), error
    assert error[[skeleton.index(n) for n in ("Hips", "LeftHip", "RightHip", "Head")]].max() < 0.01


def test_unpaired_side_joints_are_refused() -> None:
    clip = generate(GaitSpec("w", speed=1.0))
    names = tuple("LeftFoo" if n == "RightHand" else n for n in clip.skeleton.names)
    broken = Skeleton(
        names, clip.skeleton.parents, clip.skeleton.rest_translations, clip.skeleton.rest_rotations
    )
    with pytest.raises(IncompatibleClips, match="no mirror partner"):
        mirror_clip(
            Clip("w", Path("w"), broken, clip.rotations, clip.translations, clip.fps),
            settings=SETTINGS,
            name="m",
        )


@pytest.mark.parametrize("turn_rate", [4.0, -7.5, 10.0])
def test_straighten_removes_the_turn_and_keeps_the_speed(turn_rate: float) -> None:
    source = generate(GaitSpec("walk", speed=1.4, turn_rate=turn_rate, direction=5.0))
    straight = features(straighten_clip(source, settings=SETTINGS, name="s"))
    assert abs(straight["turn_rate"]) < 0.01 * SPAN["turn_rate"]
    assert straight["speed"] == pytest.approx(features(source)["speed"], rel=0.02)
    assert straight["direction"] == pytest.approx(5.0, abs=0.5)


def test_stick_figure_render_of_a_mirrored_clip(tmp_path: Path) -> None:
    """Renders a few frames of a source clip and its mirror side by side (top view) with
    OpenImageIO, so a person can look at them; the test checks the image has the figures."""
    oiio = pytest.importorskip("OpenImageIO")
    source = generate(GaitSpec("walk_turn_left", speed=1.4, turn_rate=45.0, duration=2.0))
    mirrored = mirror_clip(source, settings=SETTINGS, name="walk_turn_right")
    width, height = 800, 400
    image = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.fill(image, (1.0, 1.0, 1.0))
    for panel, (clip, colour) in enumerate(((source, (0.1, 0.3, 0.9)), (mirrored, (0.6, 0.2, 0.6)))):
        _, world = forward_kinematics(clip)
        for frame in range(0, clip.frame_count, 10):
            for joint, parent in enumerate(clip.skeleton.parents):
                if parent < 0:
                    continue
                # Top view: x to the right, z (forward) up the image, 70 px per metre.
                ends = [world[frame, j] for j in (joint, parent)]
                xs = [int(width / 4 + panel * width / 2 + 70 * p[0]) for p in ends]
                ys = [int(height - 40 - 70 * p[2]) for p in ends]
                oiio.ImageBufAlgo.render_line(image, xs[0], ys[0], xs[1], ys[1], colour)
    out = Path(__file__).resolve().parents[1] / "test-artifacts" / "mirror_stick_figures.png"
    out.parent.mkdir(exist_ok=True)
    assert image.write(str(out))
    pixels = image.get_pixels(oiio.FLOAT)
    left_half, right_half = pixels[:, : width // 2], pixels[:, width // 2 :]
    assert (left_half < 0.95).any() and (right_half < 0.95).any()
