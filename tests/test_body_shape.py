"""Rigs whose joint names say nothing (an exporter's `joint_07`, Blender's `Bone.007`): the legs are
found by the skeleton's shape, left told from right by the rest pose's toes or the knees over the
take. Truth by construction (procedural gaits renamed, on other joint orders, without toes) and
on the real CMU takes renamed.

Before, no hip was found: the facing came from an assumed root axis (a `facing` guess, and a walk
read 90 deg sideways on a rig facing +X) and the root from the highest moving joint.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.body_shape import hips_by_shape
from blendspace_pipeline.motion.clip import Clip, forward_kinematics, rest_positions
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.mirror import mirror_clip, mirror_pairs
from blendspace_pipeline.motion.detect import RigSettings, still_joints
from blendspace_pipeline.motion.hostile import (
    NAMELESS,
    big_feet,
    heel_bones,
    keyed_everywhere,
    long_coat,
    on_other_skeleton,
    posed_rest,
    renamed,
    static_leg_copies,
    thigh_twist,
    with_joints,
    without_toes,
)
from blendspace_pipeline.motion.measure import measure, trim
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip

SETTINGS = RigSettings()
GAITS = (
    GaitSpec("walk_left", speed=1.4, turn_rate=45.0, duration=2.0),
    GaitSpec("strafe_right", speed=1.2, direction=-90.0, duration=2.0, stride_length=1.0),
    GaitSpec("run_back", speed=3.0, direction=180.0, turn_rate=-20.0, duration=1.5, stride_length=2.2),
)
FEATURES = ("speed", "turn_rate", "direction", "forward_speed", "lateral_speed")
SHAPE = "hip line (hips by the skeleton's shape)"


def _same(measured: dict[str, float], original: dict[str, float], tolerance: float = 1e-6) -> None:
    for key in FEATURES:
        assert measured[key] == pytest.approx(original[key], abs=tolerance), key


@pytest.mark.parametrize("up", ["y", "z"])
@pytest.mark.parametrize("scheme", NAMELESS)
@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_nameless_rigs_measure_as_the_named_one(spec: GaitSpec, scheme: str, up: str) -> None:
    clip = generate(spec, up=up)
    original = measure(clip, SETTINGS)
    nameless = measure(renamed(clip, scheme), SETTINGS)
    assert nameless.facing == SHAPE
    assert nameless.root.startswith("hip midpoint")
    assert not nameless.guesses, nameless.guesses
    assert any("told apart by the toes of the rest pose" in note for note in nameless.notes)
    assert nameless.meters_per_unit == original.meters_per_unit
    _same(nameless.features, original.features)


@pytest.mark.parametrize("change", ["reordered", "extra_joint"])
def test_the_right_leg_first_or_an_extra_joint_changes_nothing(change: str) -> None:
    """Another exporter's order (the right leg's branch written first) must not swap the sides."""
    clip = generate(GAITS[0])
    nameless = measure(renamed(on_other_skeleton(clip, change), "anonymous"), SETTINGS)
    assert nameless.facing == SHAPE and not nameless.guesses
    _same(nameless.features, measure(clip, SETTINGS).features)


@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_without_toes_the_knees_tell_the_sides(spec: GaitSpec) -> None:
    """Legs of hip, knee and ankle: the rest pose cannot tell left from right, the bent knees of
    every stride can."""
    clip = without_toes(generate(spec))
    nameless = measure(renamed(clip, "blender"), SETTINGS)
    assert nameless.facing == SHAPE and not nameless.guesses, nameless.guesses
    assert any("told apart by the knees over the take" in note for note in nameless.notes)
    _same(nameless.features, measure(clip, SETTINGS).features)


def test_when_nothing_tells_the_sides_it_is_a_guess() -> None:
    """No toes, and legs that never bend (a rest pose held): the sides are guessed, and said."""
    clip = renamed(without_toes(generate(GAITS[0])), "anonymous")
    skeleton = clip.skeleton
    frames = 30
    still = replace(
        clip,
        rotations=np.repeat(skeleton.rest_rotations[None], frames, axis=0),
        translations=np.repeat(skeleton.rest_translations[None], frames, axis=0),
    )
    [guess] = measure(still, SETTINGS).guesses
    assert guess.what == "facing"
    assert "neither the rest pose's toes nor the legs' motion" in guess.evidence
    assert guess.override.startswith("skeleton: {left_hip: joint_")


def test_arms_are_not_taken_for_legs() -> None:
    """Arms mirror each other too, but hang from the chest, further from the root."""
    clip = renamed(generate(GAITS[0]), "anonymous")
    found = hips_by_shape(clip.skeleton, rest_positions(clip.skeleton))
    assert found is not None and found.sided
    named = generate(GAITS[0]).skeleton.names
    assert (named[found.left], named[found.right]) == ("LeftUpLeg", "RightUpLeg")


@pytest.mark.parametrize("take", ["131_01", "131_02"])
@pytest.mark.parametrize("scheme", NAMELESS)
def test_real_cmu_takes_renamed_measure_as_named(take: str, scheme: str) -> None:
    """The real takes (CMU's `LHipJoint` sits on the pelvis: the legs part one joint lower)."""
    [clip] = read_clips(shared_data("cmu", f"{take}.bvh"))
    clip = trim(clip, (4.3, 5.5))
    original = measure(clip, SETTINGS)
    nameless = measure(renamed(clip, scheme), SETTINGS)
    assert nameless.facing == SHAPE and not nameless.guesses, nameless.guesses
    assert nameless.meters_per_unit == pytest.approx(original.meters_per_unit)
    _same(nameless.features, original.features)


def test_a_nameless_bvh_builds_with_its_hips_said(tmp_path: Path) -> None:
    """Through a file and the command: the document says how the hips were found."""
    (tmp_path / "clips").mkdir()
    for spec in GAITS:
        write_bvh_clip(renamed(generate(spec), "blender"), tmp_path / "clips" / f"{spec.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    assert main(["build", str(manifest), "--no-fix", "--out", str(tmp_path / "out")]) in (0, 1)
    doc = json.loads((tmp_path / "out" / "t.blendspace.json").read_text(encoding="utf-8"))
    by_name = {s["name"]: s for s in doc["samples"]}
    for spec in GAITS:
        sample = by_name[spec.name]
        assert sample["clip"]["facing"] == SHAPE
        assert not sample["clip"]["guesses"]
        assert sample["features"]["speed"] == pytest.approx(spec.signed_speed, abs=0.03)
        assert sample["features"]["direction"] == pytest.approx(spec.direction, abs=0.6)
    assert not [d for d in doc["diagnostics"] if d["rule"] == "detection-guess"]


def _cmu() -> Clip:
    return read_clips(shared_data("cmu", "131_01.bvh"))[0]


def _fox() -> Clip:
    return read_clips(shared_data("khronos-fox", "Fox.glb"))[0]


@pytest.mark.parametrize(
    "make",
    [
        lambda: generate(GAITS[0]),
        lambda: on_other_skeleton(generate(GAITS[0]), "reordered"),
        lambda: without_toes(generate(GAITS[0])),
        _cmu,
        _fox,
    ],
    ids=["procedural", "right-leg-first", "no-toes", "cmu", "fox"],
)
@pytest.mark.parametrize("scheme", NAMELESS)
def test_nameless_rigs_mirror_as_the_named_one(make: Callable[[], Clip], scheme: str) -> None:
    """Mirroring pairs each joint with its partner by name. With names that say nothing every joint
    kept its own motion: the mirrored walk's legs crossed, while its root motion (and so every
    feature) read right. The rest pose's symmetry pairs them, as the names do (CMU's calibrated
    skeleton is 3 cm off symmetric; the Fox is a quadruped)."""
    clip = make()
    nameless = renamed(clip, scheme)
    assert mirror_pairs(nameless.skeleton) == mirror_pairs(clip.skeleton)
    named = mirror_clip(clip, settings=SETTINGS, name="m")
    other = mirror_clip(nameless, settings=SETTINGS, name="m")
    assert np.allclose(forward_kinematics(other)[1], forward_kinematics(named)[1], atol=1e-6)


def test_an_asymmetric_nameless_rig_is_not_mirrored_blindly() -> None:
    """No side in the names and no mirror symmetry (one toe missing): no partner can be known, so
    the mirror fix is refused (it falls back to a placeholder) instead of baking crossed legs."""
    clip = generate(GAITS[0])
    keep = [i for i, name in enumerate(clip.skeleton.names) if name != "RightToe"]
    skeleton = clip.skeleton
    remap = {old: new for new, old in enumerate(keep)}
    lopsided = replace(
        clip,
        skeleton=replace(
            skeleton,
            names=tuple(f"joint_{i:02d}" for i in range(len(keep))),
            parents=tuple(-1 if skeleton.parents[i] < 0 else remap[skeleton.parents[i]] for i in keep),
            rest_translations=skeleton.rest_translations[keep],
            rest_rotations=skeleton.rest_rotations[keep],
        ),
        rotations=clip.rotations[:, keep],
        translations=clip.translations[:, keep],
    )
    assert hips_by_shape(lopsided.skeleton, rest_positions(lopsided.skeleton)) is None
    with pytest.raises(IncompatibleClips, match="no joint name says left or right"):
        mirror_pairs(lopsided.skeleton)


@pytest.mark.parametrize(
    "change",
    [heel_bones, long_coat, thigh_twist, lambda c: big_feet(c, 0.25), lambda c: big_feet(c, 0.32)],
    ids=["heel-before-toe", "floor-length-coat", "thigh-twist", "25cm-feet", "32cm-feet"],
)
@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_rigs_that_look_like_other_legs_measure_as_named(
    change: Callable[[Clip], Clip], spec: GaitSpec
) -> None:
    """From the hostile pass: a heel bone listed before the toe was taken for the toe (the walk read
    backwards, -1.4 m/s, and the false toes vetoed the knees); a floor-length coat's front and
    back chains (longer than the legs, mirror images across the body's side) were taken for the
    legs (a walk read as a strafe); a twist joint inside the thigh made the knee the ankle (no legs
    found)."""
    clip = change(generate(spec))
    nameless = measure(renamed(clip, "blender"), SETTINGS)
    assert nameless.facing == SHAPE and not nameless.guesses, nameless.guesses
    _same(nameless.features, measure(clip, SETTINGS).features)
    hips = hips_by_shape(renamed(clip, "blender").skeleton, rest_positions(clip.skeleton))
    assert hips is not None
    assert (clip.skeleton.names[hips.left], clip.skeleton.names[hips.right]) == ("LeftUpLeg", "RightUpLeg")


RIG_VARIANTS: dict[str, Callable[[Clip], Clip]] = {
    "plain": lambda clip: clip,
    "static-leg-copies": static_leg_copies,
    "static-copies-first": lambda clip: static_leg_copies(clip, parent="Hips", first=True),
    "keyed-everywhere": keyed_everywhere,
    "moving-coat": lambda clip: long_coat(clip, hem=0.015, sway=1.0),
}


@pytest.mark.parametrize("variant", list(RIG_VARIANTS))
@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_a_posed_frame_for_the_rest_pose_still_finds_the_legs(spec: GaitSpec, variant: str) -> None:
    """An armature-only FBX (and Blender's USD) keeps no rest pose but the exported frame's: a
    stride, a heel lifted, the toes' end off the floor. The legs reach the floor at their lowest
    joint, not only at their end (an A-pose nameless FBX found no hips: `root` and `facing`
    guesses, a turn on the spot read 0.14 m/s). Static copies of the legs (a Rigify-like rig's
    ORG helpers, never animated) are as near the root: the legs that move win (they had read a
    walk backwards), also in a true rest pose where the copies tie with the legs and come first.
    A take that keys every bone (nothing holds exactly still) finds them too, and a baked cloth
    coat swinging 1.5 cm above the floor (mirror images, moving, but no feet) is no pair of legs."""
    clip = RIG_VARIANTS[variant](generate(spec))
    truth = measure(clip, SETTINGS).features
    rested = measure(renamed(clip, "blender"), SETTINGS)
    assert rested.facing == SHAPE and not rested.guesses, rested.guesses
    _same(rested.features, truth)
    for frame in range(0, clip.frame_count, max(1, clip.frame_count // 8)):
        nameless = renamed(posed_rest(clip, frame), "blender")
        measured = measure(nameless, SETTINGS)
        assert measured.facing == SHAPE and not measured.guesses, (frame, measured.guesses)
        _same(measured.features, truth)


def test_a_moving_leg_and_its_static_copy_are_no_pair() -> None:
    """Without a mirror image to ask for, a leg and the static copy of the other leg (same bones,
    both hanging from the hips) could pair: both legs of a pair must move."""
    clip = static_leg_copies(generate(GAITS[0]), parent="Hips")
    for frame in range(0, clip.frame_count, 7):
        posed = posed_rest(clip, frame)
        hips = hips_by_shape(posed.skeleton, rest_positions(posed.skeleton), still=still_joints(posed))
        assert hips is not None
        names = {clip.skeleton.names[hips.left], clip.skeleton.names[hips.right]}
        assert names == {"LeftUpLeg", "RightUpLeg"}, (frame, names)


def test_a_few_sided_helper_names_do_not_stop_the_shape_pairing() -> None:
    """Only two IK helpers named `ik_target_L` / `_R` on a `Bone.NNN` rig: mirroring paired them by
    name and every other joint with itself (a mirrored walk's feet 0.69 m off, silently)."""
    clip = with_joints(
        generate(GAITS[0]),
        [("ik_target_L", "Hips", (0.3, -0.9, 0.2), None), ("ik_target_R", "Hips", (-0.3, -0.9, 0.2), None)],
    )
    named = mirror_clip(clip, settings=SETTINGS, name="m")
    names = [n if n.startswith("ik_target") else f"Bone.{i:03d}" for i, n in enumerate(clip.skeleton.names)]
    partial = replace(clip, skeleton=replace(clip.skeleton, names=tuple(names)))
    assert mirror_pairs(partial.skeleton) == mirror_pairs(clip.skeleton)
    other = mirror_clip(partial, settings=SETTINGS, name="m")
    assert np.allclose(forward_kinematics(other)[1], forward_kinematics(named)[1], atol=1e-6)


@pytest.mark.parametrize("take", ["131_01", "131_02"])
def test_real_cmu_takes_renamed_pick_the_same_auto_range(take: str) -> None:
    """The stride detector used the toes of a nameless rig and the ankles of a named one: 131_02's
    `range: auto` differed (turn 4.30 deg/s named, 5.08 nameless, and a partial-stride warning)."""
    [clip] = read_clips(shared_data("cmu", f"{take}.bvh"))
    named = measure(clip, SETTINGS, "auto")
    nameless = measure(renamed(clip, "anonymous"), SETTINGS, "auto")
    assert nameless.range_used == named.range_used
    assert nameless.partial_stride == named.partial_stride
    _same(nameless.features, named.features)


def test_without_toes_the_file_order_names_the_feet_and_says_so() -> None:
    """No toes and the right leg listed first: each clip's knees decide its facing, but the rig's
    feet keep the file's order for every clip (contacts and markers stay consistent across the
    set), and the note says which foot is called left."""
    clip = renamed(without_toes(on_other_skeleton(generate(GAITS[0]), "reordered")), "anonymous")
    measured = measure(clip, SETTINGS)
    [note] = [n for n in measured.notes if n.startswith("hips found by the skeleton's shape")]
    assert "told apart by the knees over the take" in note
    assert "foot contacts and markers name" in note and "as the file lists it first" in note
    _same(measured.features, measure(generate(GAITS[0]), SETTINGS).features)


def test_a_few_sided_names_on_an_asymmetric_nameless_rig_are_not_mirrored() -> None:
    """IK helpers named by side, every other joint nameless, and a prop on one hand: the shape
    cannot pair the legs and the names pair two joints. Mirroring is refused, not baked with
    every leg joint keeping its own motion."""
    clip = with_joints(
        generate(GAITS[0]),
        [
            ("ik_target_L", "Hips", (0.3, -0.9, 0.2), None),
            ("ik_target_R", "Hips", (-0.3, -0.9, 0.2), None),
            ("prop", "LeftHand", (0.1, 0.0, 0.0), None),
            ("prop_tip", "prop", (0.3, 0.0, 0.0), None),
        ],
    )
    names = [n if n.startswith("ik_target") else f"Bone.{i:03d}" for i, n in enumerate(clip.skeleton.names)]
    lopsided = replace(clip.skeleton, names=tuple(names))
    with pytest.raises(IncompatibleClips, match="no joint name says left or right"):
        mirror_pairs(lopsided)


def test_an_armature_named_after_its_file_and_control_bones_on_one_spot_still_mirror() -> None:
    """Blender names an armature imported from `walk_turn_left.bvh` after the file: the root joint's
    name said "left" and the mirror was refused. Two control bones on the centre line at one spot
    (Rigify's `torso` and `MCH-WGT-hips`) made the shape pairing refuse a symmetric rig."""
    clip = generate(GAITS[0])
    named = replace(clip, skeleton=replace(clip.skeleton, names=("walk_turn_left", *clip.skeleton.names[1:])))
    assert mirror_pairs(named.skeleton) == mirror_pairs(clip.skeleton)
    controls = with_joints(
        clip, [("torso", "Hips", (0.0, 0.1, 0.0), None), ("MCH-WGT-hips", "Hips", (0.0, 0.1, 0.0), None)]
    )
    nameless = renamed(controls, "blender")
    assert mirror_pairs(nameless.skeleton) == mirror_pairs(controls.skeleton)
