"""Takes in the conventions of public mocap sources that nobody here wrote, truth by construction.

`motion.hostile` re-expresses known-truth motion in other joint naming schemes (DAZ, CMU ASF,
OptiTrack's asset prefix, MikuMikuDance's Japanese names, names that say nothing), with the side
labels swapped, and through a mirrored (left-handed) export; and the manifest states units,
forward axes and roots that the body contradicts. Each either measures right or says, as a
`detection-guess`, what it could not settle; none reads a wrong number without a word.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.exporters import to_engine
from blendspace_pipeline.exporters.unreal import CONVENTION as UNREAL
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops.mirror import mirror_pairs
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.hostile import (
    NAME_SCHEMES,
    NAMELESS,
    HostileSpec,
    mirrored_export,
    renamed,
    sides_swapped,
    take,
)
from blendspace_pipeline.motion.measure import Measurement, measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.writers.bvh import write_bvh_clip

GAITS = (
    GaitSpec("walk_left", speed=1.4, turn_rate=45.0, duration=2.0),
    GaitSpec("strafe_right", speed=1.2, direction=-90.0, duration=2.0, stride_length=1.0),
    GaitSpec("walk_back_right", speed=1.1, direction=180.0, turn_rate=-30.0, duration=2.0, stride_length=1.1),
    GaitSpec("run_diagonal", speed=3.5, direction=45.0, turn_rate=20.0, duration=1.5, stride_length=2.4),
)
KEYS = ("speed", "turn_rate", "direction", "forward_speed", "lateral_speed")


def _truth(spec: GaitSpec) -> dict[str, float]:
    return {
        "speed": spec.signed_speed,
        "turn_rate": spec.turn_rate,
        "direction": spec.direction,
        "forward_speed": spec.forward_speed,
        "lateral_speed": spec.lateral_speed,
    }


def _close(measured: Measurement, truth: dict[str, float], keys: tuple[str, ...] = KEYS) -> None:
    for key in keys:
        tolerance = 0.6 if key in ("turn_rate", "direction") else 0.03
        assert measured.features[key] == pytest.approx(truth[key], abs=tolerance), key


@pytest.mark.parametrize("scheme", [s for s in NAME_SCHEMES if s not in NAMELESS])
@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_naming_schemes_find_the_hips_and_measure_as_the_original(scheme: str, spec: GaitSpec) -> None:
    """DAZ's `lThigh`, CMU ASF's `lfemur` (a side letter only a pair in one skeleton proves),
    OptiTrack's `Skeleton1_LThigh` and MikuMikuDance's `左足` were not recognised as hips: facing
    then came from an assumed joint axis (a walk read 90 deg sideways on a rig facing +X)."""
    clip = generate(spec)
    original = measure(clip, RigSettings())
    other = measure(renamed(clip, scheme), RigSettings())
    assert other.root.startswith("hip midpoint"), other.root
    assert other.facing == "hip line"
    assert not other.guesses
    for key in KEYS:
        assert other.features[key] == pytest.approx(original.features[key], abs=1e-9)
    _close(other, _truth(spec))


@pytest.mark.parametrize("scheme", [s for s in NAME_SCHEMES if s not in NAMELESS])
def test_naming_schemes_pair_every_sided_joint_for_mirroring(scheme: str) -> None:
    clip = renamed(generate(GAITS[0]), scheme)
    names = clip.skeleton.names
    partners = mirror_pairs(clip.skeleton)
    original = generate(GAITS[0]).skeleton.names
    expected = [
        original.index(
            ("Right" + n[4:]) if n.startswith("Left") else ("Left" + n[5:]) if n.startswith("Right") else n
        )
        for n in original
    ]
    assert partners == expected, [(names[i], names[j]) for i, j in enumerate(partners)]


@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_swapped_side_labels_are_read_by_the_feet_and_said(spec: GaitSpec) -> None:
    """Left and right swapped in the joint names made the hip line face backwards: a walk read
    -1.4 m/s at 180 deg and a strafe the other way, without a word. Knees bend forward on every
    human rig: the facing is turned round, the numbers are true, and a guess says why; the swapped
    pair in the manifest confirms it, the names' pair is doubted."""
    clip = sides_swapped(generate(spec))
    measured = measure(clip, RigSettings())
    _close(measured, _truth(spec))
    [guess] = measured.guesses
    assert guess.what == "facing" and not guess.stated
    assert "LeftUpLeg is on the character's right" in guess.evidence
    assert guess.override == "skeleton: {left_hip: RightUpLeg, right_hip: LeftUpLeg}"
    confirmed = measure(clip, RigSettings(left_hip="RightUpLeg", right_hip="LeftUpLeg"))
    assert not confirmed.guesses
    _close(confirmed, _truth(spec))
    by_names = measure(clip, RigSettings(left_hip="LeftUpLeg", right_hip="RightUpLeg"))
    [doubt] = by_names.guesses
    assert doubt.what == "facing" and doubt.stated and "knees point 180 deg away" in doubt.evidence


@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_a_mirrored_export_reads_forward_and_says_its_turns_may_be_mirrored(spec: GaitSpec) -> None:
    """A left-handed (mirrored) export read forward as backward. Its body is its own mirror image:
    speed and forward speed are true once the feet turn the facing round; the turn and sidestep
    signs are the mirror's (indistinguishable from swapped labels), and the guess says so."""
    measured = measure(mirrored_export(generate(spec)), RigSettings())
    truth = _truth(spec)
    mirrored = {**truth, "turn_rate": -truth["turn_rate"], "direction": -truth["direction"]}
    if abs(truth["direction"]) == 180.0:
        mirrored["direction"] = 180.0
    mirrored["lateral_speed"] = -truth["lateral_speed"]
    _close(measured, mirrored)
    [guess] = measured.guesses
    assert guess.what == "facing" and "mirrored" in guess.evidence and "wrong sign" in guess.evidence


def test_a_stated_forward_the_body_contradicts_is_doubted_with_the_right_axis() -> None:
    """`forward: +z` on a rig whose Hips +Z is the character's left (LAFAN1's) read a walk as a
    sidestep without a word. Still used, now doubted, with the axis the body faces along."""
    spec = GAITS[0]
    clip = generate(spec)
    wrong = measure(clip, RigSettings(forward="+x"))
    assert wrong.features["direction"] == pytest.approx(-90.0, abs=1.0)  # used as stated: +X is its left
    [guess] = wrong.guesses
    assert (
        guess.what == "facing"
        and guess.stated
        and "faces 90 deg away from the +x axis of Hips" in guess.evidence
    )
    assert guess.override == "skeleton: {forward: +z}"
    right = measure(clip, RigSettings(forward="+z"))
    assert not right.guesses
    _close(right, _truth(spec))


def test_a_stated_unit_that_makes_a_toddler_of_an_adult_is_doubted() -> None:
    """`units: cm` on a CMU take made the legs 0.145 m and walks 0.25 m/s, without a word (legs
    within 0.1-5 m were never doubted). Doubted now, naming the unit the body reads."""
    clip = take(HostileSpec("walk", unit="cmu", tpose_first_frame=False)).clip
    measured = measure(clip, RigSettings(units="cm"))
    [guess] = [g for g in measured.guesses if g.what == "units"]
    assert guess.stated and "legs 0.145 m long; the body reads 0.05644 m per unit" in guess.evidence
    assert guess.override == "skeleton: {units: 0.0564444}"
    assert not [g for g in measure(clip, RigSettings(units=0.0254 / 0.45)).guesses if g.what == "units"]


@pytest.mark.parametrize(
    ("unit", "stated", "legs"), [("cmu", "in", "0.37"), ("in", "cm", "0.32"), ("cm", "in", "2.08")]
)
def test_a_stated_unit_that_makes_a_child_or_a_giant_is_noted_not_doubted(
    unit: str, stated: str, legs: str
) -> None:
    """`units: in` on a CMU take (legs 0.37 m), inches read as centimetres (0.32 m), centimetres
    as inches (2.08 m): a child or a giant in its true unit reads the same, so the clip gets a
    note with the numbers, not a warning that nothing could settle."""
    clip = take(HostileSpec("walk", unit=unit, tpose_first_frame=False)).clip
    measured = measure(clip, RigSettings(units=stated))
    assert not [g for g in measured.guesses if g.what == "units"]
    [note] = [n for n in measured.notes if "`skeleton.units` makes the legs" in n]
    assert f"legs {legs} m long" in note and "(an adult's)" in note


def test_a_small_character_in_its_own_unit_is_neither_doubted_nor_noted_in_the_adult_range() -> None:
    """Legs of 0.45 m stated in centimetres: within the adult range's reach, nothing is said."""
    clip = generate(GaitSpec("walk", speed=1.0, duration=1.0), meters_per_unit=0.01)
    child = measure(clip, RigSettings(units=0.0055))  # legs 0.82 m * 0.55 = 0.45 m
    assert not [g for g in child.guesses if g.what == "units"]
    assert not [n for n in child.notes if "`skeleton.units`" in n]


def test_a_stated_root_that_stays_put_is_doubted_but_not_on_an_in_place_take() -> None:
    """`root: Root` on a take whose top joint sits at the origin while the hips walk read the
    walk as standing still, without a word: doubted now. An in-place export (the root held
    still, the hips only swaying and bobbing) with `root: Root` is what it says, and not doubted."""
    clip = take(HostileSpec("walk", unit="cm")).clip
    still = measure(clip, RigSettings(root="Root"))
    assert abs(still.features["speed"]) < 0.01  # used as stated
    [guess] = [g for g in still.guesses if g.what == "root"]
    assert guess.stated and "Root gets 0 % as far from where it starts as the hips" in guess.evidence
    assert not [g for g in measure(clip, RigSettings(root="Hips")).guesses if g.what == "root"]
    walk = generate(GAITS[0], with_root_joint=True)
    translations, rotations = walk.translations.copy(), walk.rotations.copy()
    translations[:, 0], rotations[:, 0] = 0.0, quat.IDENTITY  # the root held at the origin: in place
    in_place = replace(walk, translations=translations, rotations=rotations)
    assert not [g for g in measure(in_place, RigSettings(root="Root")).guesses if g.what == "root"]


def _only_joints(clip: Clip, joints: list[int]) -> Clip:
    """``clip`` with only ``joints`` (parents before children), in that order."""
    parents = clip.skeleton.parents
    remap = {old: new for new, old in enumerate(joints)}
    skeleton = replace(
        clip.skeleton,
        names=tuple(clip.skeleton.names[i] for i in joints),
        parents=tuple(-1 if parents[i] < 0 else remap[parents[i]] for i in joints),
        rest_translations=clip.skeleton.rest_translations[joints],
        rest_rotations=clip.skeleton.rest_rotations[joints],
    )
    return replace(
        clip,
        skeleton=skeleton,
        rotations=clip.rotations[:, joints],
        translations=clip.translations[:, joints],
    )


def _posed_legs(clip: Clip, knee: float, ankle: float, hip: float = 0.0) -> Clip:
    """``clip`` with both legs held in one pose (degrees: hip flexion, knee bend, ankle plantar
    flexion; a kneeling pose is 0, 90, 90: thighs down, shins back along the floor, insteps down,
    toes pointing backwards)."""
    rotations = clip.rotations.copy()
    names = clip.skeleton.names
    for side in ("Left", "Right"):
        for joint, angle in ((f"{side}UpLeg", -hip), (f"{side}Leg", knee), (f"{side}Foot", ankle)):
            rotations[:, names.index(joint)] = quat.from_axis_angle(
                np.array([1.0, 0.0, 0.0]), np.deg2rad(angle)
            )
    return replace(clip, rotations=rotations)


@pytest.mark.parametrize(
    "spec",
    [GaitSpec("kneel", duration=2.0), GaitSpec("knee_walk", speed=0.3, duration=2.0)],
    ids=lambda s: s.name,
)
def test_kneeling_with_the_toes_pointing_back_keeps_its_facing(spec: GaitSpec) -> None:
    """Kneeling on the insteps points the toes backwards: judged by the toes, a correct hip line
    was turned round (a knee-walk read -0.3 m/s) and a correct stated pair or forward doubted.
    The knees still stick out forward: nothing is turned and nothing doubted."""
    clip = _posed_legs(generate(spec), knee=90.0, ankle=90.0)
    measured = measure(clip, RigSettings())
    assert measured.facing == "hip line" and not [g for g in measured.guesses if g.what == "facing"]
    assert measured.features["speed"] == pytest.approx(spec.signed_speed, abs=0.02)
    stated = measure(clip, RigSettings(left_hip="LeftUpLeg", right_hip="RightUpLeg"))
    assert not [g for g in stated.guesses if g.what == "facing"]
    assert not [g for g in measure(clip, RigSettings(forward="+z")).guesses if g.what == "facing"]


def test_straight_legs_are_read_by_the_toes_and_a_rig_without_toes_by_the_knees() -> None:
    """The legs' two witnesses stand in for each other: knees that never bend leave the toes to
    tell swapped labels; a rig whose toes are only BVH End Sites (no toe joint) has its knees."""
    spec = GAITS[0]
    straight = sides_swapped(_posed_legs(generate(spec), knee=0.0, ankle=0.0))
    measured = measure(straight, RigSettings())
    assert measured.facing.startswith("hip line, reversed")
    assert measured.features["turn_rate"] == pytest.approx(45.0, abs=0.5)
    assert "toes point" in measured.guesses[0].evidence
    clip = generate(spec)
    keep = [i for i, n in enumerate(clip.skeleton.names) if "Toe" not in n]
    toeless = sides_swapped(_only_joints(clip, keep))
    read = measure(toeless, RigSettings())
    assert read.facing.startswith("hip line, reversed") and "knees point" in read.guesses[0].evidence
    _close(read, _truth(spec))


def _hipless(clip: Clip) -> Clip:
    """``clip`` renamed so that no name says left or right, and without its right toe, so that
    the legs are no mirror images either: no hips are found at all (`body_shape`)."""
    keep = [i for i, name in enumerate(clip.skeleton.names) if name != "RightToe"]
    return renamed(_only_joints(clip, keep), "anonymous")


def test_without_hips_the_root_is_the_top_joint_that_travels() -> None:
    """Names that say nothing, legs that are not mirror images and a static top joint at the
    origin (a MotionBuilder reference): the fallback root was that joint, and every clip read 0 m/s
    and a unit of 7.8 m. Now the highest joint that travels with the body carries the root motion
    (a guess, said)."""
    spec = HostileSpec("walk", unit="cm", speed=1.4, tpose_first_frame=False)
    hostile = take(spec)
    clip = _hipless(hostile.clip)
    first, last = hostile.steady_seconds
    measured = measure(clip, RigSettings(), (first, last))
    assert measured.root == "joint_01"  # the hips, under the static joint_00
    assert measured.meters_per_unit == pytest.approx(0.01)
    assert measured.features["speed"] == pytest.approx(1.4, abs=0.05)
    assert {g.what for g in measured.guesses} >= {"root", "facing"}


def test_without_hips_a_vertical_forward_axis_is_passed_over() -> None:
    """A Z-up file whose root joint keeps its own Y-up axes: its local -Y, the usual forward of
    Z-up files, points down, and a walk read 38 deg/s for 45. The most horizontal axis is taken
    instead, and the guess says the usual one was vertical."""
    spec = GaitSpec("walk", speed=1.4, turn_rate=45.0, duration=2.0)
    clip = _hipless(generate(spec, up="z"))
    measured = measure(clip, RigSettings(up="z"))
    assert measured.facing == "joint_00 axis +z"
    [guess] = [g for g in measured.guesses if g.what == "facing"]
    assert "its -y axis, the usual forward, points along the up axis" in guess.evidence
    _close(measured, _truth(spec), ("turn_rate", "direction"))


def test_shift_jis_joint_names_are_read_as_written(tmp_path: Path) -> None:
    """MikuMikuDance's BVH exports are Shift-JIS: its names read as U+FFFD, matching nothing."""
    clip = renamed(generate(GAITS[0]), "mmd")
    path = tmp_path / "walk.bvh"
    write_bvh_clip(clip, path)
    path.write_bytes(path.read_text(encoding="utf-8").encode("cp932"))
    [read] = read_clips(path)
    assert read.skeleton.names == clip.skeleton.names
    assert measure(read, RigSettings()).root == "hip midpoint (左足, 右足)"
    # A clip generated from it copies its hierarchy (a mirror of a BVH set is BVH too): the
    # names survive, written as UTF-8.
    copy = tmp_path / "copy.bvh"
    write_bvh_clip(read, copy, template=path)
    [again] = read_clips(copy)
    assert again.skeleton.names == clip.skeleton.names


@pytest.mark.parametrize(
    ("raw", "text"),
    [("Épaule_G".encode("cp1252"), "Épaule_G"), ("Cuisse_àgauche".encode("cp1252"), "Cuisse_àgauche"),
     ("Muñeca_I".encode("cp1252"), "Muñeca_I"), ("全ての親".encode("cp932"), "全ての親")],
)  # fmt: skip
def test_legacy_encodings_keep_latin_and_japanese_names(tmp_path: Path, raw: bytes, text: str) -> None:
    """Accented Latin names (Windows-1252) were read as Shift-JIS when that happened to decode:
    `Épaule_G` became `ﾉpaule_G`."""
    clip = generate(GAITS[0])
    names = list(clip.skeleton.names)
    names[names.index("Head")] = "HEADNAME"
    path = tmp_path / "take.bvh"
    write_bvh_clip(replace(clip, skeleton=replace(clip.skeleton, names=tuple(names))), path)
    path.write_bytes(path.read_bytes().replace(b"HEADNAME", raw))
    [read] = read_clips(path)
    assert text in read.skeleton.names


def test_centre_joints_with_a_side_letter_after_a_prefix_stay_centre_joints() -> None:
    """Widening side prefixes to `Skeleton1_LThigh` read Maya's `C_ROOT` as a right `coot` and
    `DEF_RIBS` as a right joint: mirroring then failed for want of their partners."""
    clip = generate(GAITS[0], with_root_joint=True)
    names = ["C_ROOT" if n == "Root" else "DEF_RIBS" if n == "Chest" else n for n in clip.skeleton.names]
    skeleton = replace(clip.skeleton, names=tuple(names))
    partners = mirror_pairs(skeleton)
    for centre in ("C_ROOT", "DEF_RIBS"):
        assert partners[names.index(centre)] == names.index(centre)
    assert names[partners[names.index("LeftUpLeg")]] == "RightUpLeg"


def test_a_dropped_rest_frame_is_the_range_the_document_and_markers_count_from(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A take whose first frame is a T-pose is measured from its second: its document said no
    range, and exported sync markers counted from the file's first frame, one frame early."""
    spec = GaitSpec("walk", speed=1.4, duration=2.0)
    (tmp_path / "clips").mkdir()
    write_bvh_clip(generate(spec, tpose_first_frame=True), tmp_path / "clips" / "walk.bvh")
    for other in GAITS[1:]:
        write_bvh_clip(generate(other), tmp_path / "clips" / f"{other.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    assert main(["build", str(manifest), "--no-fix", "--out", str(tmp_path / "out")]) in (0, 1)
    doc = json.loads((tmp_path / "out" / "t.blendspace.json").read_text(encoding="utf-8"))
    [walk] = [s for s in doc["samples"] if s["name"] == "walk"]
    assert walk["clip"]["range"] == pytest.approx([1 / 30, 2.0], abs=1e-4)
    [other] = [s for s in doc["samples"] if s["name"] == "strafe_right"]
    assert other["clip"]["range"] is None
    document = BlendSpaceDocument.model_validate(doc)
    [engine] = [s for s in to_engine(document, UNREAL).samples if s.name == "walk"]
    assert walk["markers"]
    capsys.readouterr()
    assert main(["export", str(tmp_path / "out" / "t.blendspace.json"), "--engine", "unreal"]) == 0
    [note] = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note: walk ")]
    assert "walk was measured on 0.03-2.00 s of walk.bvh (its first frame, a rest pose, left out)" in note
    assert [t for _, t in engine.markers] == pytest.approx(
        [m["time"] + 1 / 30 for m in walk["markers"]], abs=1e-5
    )


def test_a_joint_name_used_twice_is_noted() -> None:
    """Two joints of one name: a `skeleton:` setting naming it can mean only one (the first)."""
    clip = generate(GAITS[0])
    names = list(clip.skeleton.names)
    names[names.index("LeftHand")] = "RightHand"
    doubled = replace(clip, skeleton=replace(clip.skeleton, names=tuple(names)))
    [note] = [n for n in measure(doubled, RigSettings()).notes if "used twice" in n]
    assert "RightHand" in note
    assert not [n for n in measure(clip, RigSettings()).notes if "used twice" in n]


def test_an_up_axis_the_file_states_and_the_body_contradicts_is_doubted(tmp_path: Path) -> None:
    """A GLB exported from Blender with "+Y Up" off, an FBX without its axis conversion: the file
    states Y while the body stands along Z, and every walk read 0 m/s without a word (a stated unit
    was already checked this way, the up axis not). Still used, now doubted; the manifest's
    `skeleton: {up: z}` settles it. A USD `upAxis` that is no USD up axis (Blender writes "X")
    is not trusted: the body decides."""
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    spec = GAITS[0]
    lying = tmp_path / "walk.usda"
    write_usd_clip(generate(spec, up="z"), lying, meters_per_unit=1.0, up_axis="y")
    [clip] = read_clips(lying)
    assert clip.up_axis == "y"
    measured = measure(clip, RigSettings())
    [guess] = [g for g in measured.guesses if g.what == "up axis"]
    assert guess.stated and guess.value == "Y (the file's)" and "the body reads Z up" in guess.evidence
    assert guess.override == "skeleton: {up: z}"
    assert not [g for g in measured.guesses if g.what == "facing"]  # the legs are not read on a wrong ground
    settled = measure(clip, RigSettings(up="z"))
    assert not settled.guesses
    _close(settled, _truth(spec))
    x_up = tmp_path / "x.usda"
    x_up.write_text(
        lying.read_text(encoding="utf-8").replace('upAxis = "Y"', 'upAxis = "X"'), encoding="utf-8"
    )
    [odd] = read_clips(x_up)
    assert odd.up_axis is None and any("upAxis 'X' is not a USD up axis" in n for n in odd.notes)
    _close(measure(odd, RigSettings()), _truth(spec))


def test_a_clip_listing_its_joints_breadth_first_writes_a_faithful_bvh(tmp_path: Path) -> None:
    """An FBX lists joints breadth first; BVH lists them depth first. The writer wrote the
    hierarchy depth first but the motion columns in the clip's order, moving joints by up to
    1.6 m when read back."""
    from blendspace_pipeline.motion.clip import forward_kinematics

    clip = generate(GAITS[0])
    parents = clip.skeleton.parents
    order, queue = [], [j for j, p in enumerate(parents) if p < 0]
    while queue:
        joint = queue.pop(0)
        order.append(joint)
        queue += [j for j, p in enumerate(parents) if p == joint]
    assert order != list(range(len(parents)))  # breadth first differs from the generator's order
    wide = _only_joints(clip, order)
    path = tmp_path / "wide.bvh"
    write_bvh_clip(wide, path)
    [back] = read_clips(path)
    original = forward_kinematics(clip)[1]
    read = forward_kinematics(back)[1]
    for name in clip.skeleton.names:
        np.testing.assert_allclose(
            read[:, back.skeleton.names.index(name)], original[:, clip.skeleton.names.index(name)], atol=1e-4
        )


def test_root_motion_faster_than_any_body_is_doubted() -> None:
    """Blender's "apply transform" on a Mixamo-style armature leaves the location keys in
    centimetres under bones in metres: a walk read 140 m/s on 0.82 m legs, and only
    `outside-axis-range` said anything. Doubted now; a real sprint is not."""
    clip = generate(GAITS[0])
    translations = clip.translations.copy()
    translations[:, 0] *= 100.0  # the hips' (root's) keys a hundred times the bones' unit
    measured = measure(replace(clip, translations=translations), RigSettings(units="m"))
    assert measured.features["speed"] == pytest.approx(140.0, rel=0.01)
    [guess] = [g for g in measured.guesses if g.what == "root"]
    assert guess.stated and "no body travels 140 m/s on legs 0.82 m long" in guess.evidence
    sprint = measure(generate(GaitSpec("sprint", speed=10.0, duration=1.0, stride_length=4.5)), RigSettings())
    assert not [g for g in sprint.guesses if g.what == "root"]


def test_a_single_frame_pose_among_a_files_animations_is_left_out_and_said(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Blender exports a one-key "TPose" action beside the takes (a GLB of several animations):
    measuring it failed the whole build (exit 2, "give the clip more frames"), and no manifest
    entry can leave one animation of a file out. It is left out now, and the file's other
    animations say so; alone in its file, its error stands."""
    from blendspace_pipeline.errors import InputError
    from blendspace_pipeline.pipeline import measure_stage

    walk = replace(generate(GAITS[0]), name="take/walk")
    pose = replace(walk.trimmed(0, 1), name="take/TPose")
    path = tmp_path / "take.glb"
    path.write_bytes(b"stands in for the file: the reader is replaced below")
    monkeypatch.setattr(measure_stage, "read_clips", lambda *_a, **_k: [pose, walk])
    measured = measure_stage.measure_file(path, RigSettings(), None)
    assert [name for name, _ in measured] == ["take/walk"]
    [(_, found)] = measured
    assert "animation 'take/TPose' of this file is a single frame (a pose): left out" in found.notes
    _close(found, _truth(GAITS[0]))
    monkeypatch.setattr(measure_stage, "read_clips", lambda *_a, **_k: [pose])
    path.write_bytes(b"another file, so not from the cache")
    with pytest.raises(InputError, match="1 frame"):
        measure_stage.measure_file(path, RigSettings(), None)


def test_a_root_that_jumps_back_in_one_frame_is_doubted() -> None:
    """An NLA strip repeated twice in Blender snaps the root back to the start: a 1.4 m/s walk
    read 0.7 m/s without a word. The jump is said, with where it is; a clean take says nothing."""
    clip = generate(GaitSpec("walk", speed=1.4, duration=2.0))
    twice = replace(
        clip,
        rotations=np.concatenate([clip.rotations, clip.rotations[1:]]),
        translations=np.concatenate([clip.translations, clip.translations[1:]]),
    )
    measured = measure(twice, RigSettings())
    [guess] = [g for g in measured.guesses if g.what == "root"]
    assert (
        guess.stated and guess.value.startswith("jumps 2.") and "between frames 60 and 61" in guess.evidence
    )
    assert not [g for g in measure(clip, RigSettings()).guesses if g.what == "root"]
    for spec in GAITS:  # walks, strafes, backward, a run: no jump
        assert not [g for g in measure(generate(spec), RigSettings()).guesses if g.what == "root"]
