"""USD clip writer and UsdSkel reader: round trips, UsdSkel itself as the oracle, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, UsdUtils, UsdValidation, Vt
from scipy.spatial.transform import Rotation

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, forward_kinematics
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.usd import read
from blendspace_pipeline.writers.usd_clip import write_usd_clip

FRAMES = 5
# `walk_clip`'s joints as USD joint paths.
JOINT_PATHS = (
    "Hips",
    "Hips/LeftUpLeg",
    "Hips/LeftUpLeg/LeftLeg",
    "Hips/RightUpLeg",
    "Hips/RightUpLeg/RightLeg",
    "Hips/Spine",
)


def walk_clip(name: str = "walk") -> Clip:
    """Hips with two two-bone legs and a spine; every joint turns, the hips move forward."""
    skeleton = Skeleton(
        names=("Hips", "LeftUpLeg", "LeftLeg", "RightUpLeg", "RightLeg", "Spine"),
        parents=(-1, 0, 1, 0, 3, 0),
        rest_translations=np.array(
            [
                [0.0, 0.95, 0.0],
                [0.1, -0.05, 0.0],
                [0.0, -0.45, 0.0],
                [-0.1, -0.05, 0.0],
                [0.0, -0.45, 0.0],
                [0.0, 0.2, 0.0],
            ]
        ),
        rest_rotations=quat.from_euler(
            np.array([[0, 0, 0], [0, 0, 5], [10, 0, 0], [0, 0, -5], [10, 0, 0], [0, 0, 0]]), "XYZ"
        ),
    )
    phase = np.linspace(0.0, 2.0 * np.pi, FRAMES)[:, None]
    amplitude = np.array(
        [
            [5.0, 20.0, 3.0],
            [30.0, 4.0, 2.0],
            [45.0, 0.0, 0.0],
            [-30.0, -4.0, 2.0],
            [40.0, 1.0, 0.0],
            [4.0, -10.0, 2.0],
        ]
    )
    angles = np.sin(phase[:, :, None] + np.arange(6)[None, :, None]) * amplitude[None]
    translations = np.broadcast_to(skeleton.rest_translations, (FRAMES, 6, 3)).copy()
    translations[:, 0, 2] = np.arange(FRAMES) * 0.047
    translations[:, 0, 1] += 0.02 * np.cos(2 * phase[:, 0])
    return Clip(
        name=name,
        source=Path("walk.bvh"),
        skeleton=skeleton,
        rotations=quat.from_euler(angles, "ZXY"),
        translations=translations,
        fps=30.0,
        meters_per_unit=1.0,
        up_axis="y",
    )


def assert_same_rotations(a: np.ndarray, b: np.ndarray) -> None:
    """q and -q are the same rotation."""
    np.testing.assert_allclose(np.abs(np.sum(a * b, axis=-1)), 1.0, atol=1e-6)


def usdskel_world(path: Path, skeleton_path: str, frame: float) -> np.ndarray:
    """UsdSkel's own joint world matrices (row-vector Gf convention), (J, 4, 4)."""
    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    skel_root = UsdSkel.Root.Find(stage.GetPrimAtPath(skeleton_path))
    assert cache.Populate(skel_root, Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(skeleton_path)))
    assert query and query.GetAnimQuery()
    return np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(Usd.TimeCode(frame))))


def assert_fk_matches_usdskel(clip: Clip, path: Path, skeleton_path: str, frames: list[float]) -> None:
    world_rot, world_pos = forward_kinematics(clip)
    for frame, time in enumerate(frames):
        matrices = usdskel_world(path, skeleton_path, time)
        np.testing.assert_allclose(matrices[:, 3, :3], world_pos[frame], atol=1e-5)
        ours = Rotation.from_quat(world_rot[frame]).as_matrix()
        # Gf rows are the scaled images of the axes; a Clip carries no scale.
        theirs = matrices[:, :3, :3] / np.linalg.norm(matrices[:, :3, :3], axis=2, keepdims=True)
        np.testing.assert_allclose(np.transpose(theirs, (0, 2, 1)), ours, atol=1e-5)


def test_round_trip_keeps_layout_rate_units_and_pose(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    [clip] = read_clips(path)
    assert clip.name == "walk"
    assert clip.skeleton.names == original.skeleton.names
    assert clip.skeleton.parents == original.skeleton.parents
    assert (clip.fps, clip.frame_count) == (30.0, FRAMES)
    assert (clip.meters_per_unit, clip.up_axis) == (1.0, "y")
    assert clip.notes == []
    assert_same_rotations(clip.rotations, original.rotations)
    np.testing.assert_allclose(clip.translations, original.translations, atol=1e-5)
    assert_same_rotations(clip.skeleton.rest_rotations, original.skeleton.rest_rotations)
    np.testing.assert_allclose(
        clip.skeleton.rest_translations, original.skeleton.rest_translations, atol=1e-6
    )
    for ours, theirs in zip(forward_kinematics(clip), forward_kinematics(original), strict=True):
        np.testing.assert_allclose(np.abs(ours), np.abs(theirs), atol=1e-5)


def test_usdskel_poses_the_written_clip_like_our_forward_kinematics(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    assert_fk_matches_usdskel(original, path, "/walk/Skeleton", [float(f) for f in range(FRAMES)])
    # The bind pose is the world rest pose: UsdSkel's bind transforms equal FK of the rest pose.
    rest = Clip(
        "rest",
        path,
        original.skeleton,
        original.skeleton.rest_rotations[None],
        original.skeleton.rest_translations[None],
        30.0,
    )
    stage = Usd.Stage.Open(str(path))
    bind = np.array(UsdSkel.Skeleton(stage.GetPrimAtPath("/walk/Skeleton")).GetBindTransformsAttr().Get())
    np.testing.assert_allclose(bind[:, 3, :3], forward_kinematics(rest)[1][0], atol=1e-9)


def test_written_clip_passes_every_usd_validator(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(Usd.Stage.Open(str(path)))
    assert [error.GetMessage() for error in errors] == []


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_writing_twice_gives_identical_bytes(tmp_path: Path, suffix: str) -> None:
    first, second = tmp_path / f"a{suffix}", tmp_path / "b" / f"a{suffix}"
    write_usd_clip(walk_clip(), first)
    write_usd_clip(walk_clip(), second)
    assert first.read_bytes() == second.read_bytes()
    leftovers = sorted(p.name for p in tmp_path.rglob("*"))
    assert leftovers == ["a" + suffix, "a" + suffix, "b"]  # no temporary files


def test_units_and_up_axis_override_and_read_back(tmp_path: Path) -> None:
    path = tmp_path / "walk_cm.usda"
    write_usd_clip(walk_clip(), path, meters_per_unit=0.01, up_axis="z")
    stage = Usd.Stage.Open(str(path))
    assert (UsdGeom.GetStageMetersPerUnit(stage), UsdGeom.GetStageUpAxis(stage)) == (0.01, "Z")
    [clip] = read(path)
    assert (clip.meters_per_unit, clip.up_axis) == (0.01, "z")


def test_writer_refuses_to_guess_units(tmp_path: Path) -> None:
    clip = walk_clip()
    clip.meters_per_unit = None
    with pytest.raises(ValueError, match="meters_per_unit"):
        write_usd_clip(clip, tmp_path / "walk.usda")


def test_unauthored_units_are_left_to_detection(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    layer.pseudoRoot.ClearInfo("metersPerUnit")
    layer.pseudoRoot.ClearInfo("upAxis")
    layer.Save()
    [clip] = read(path)
    assert (clip.meters_per_unit, clip.up_axis) == (None, None)
    assert any("metersPerUnit" in note for note in clip.notes)


def _add_animation(
    path: Path,
    name: str,
    joints: list[str],
    rotations: np.ndarray,
    translations: np.ndarray,
    *,
    bind: bool = False,
) -> None:
    """Author another SkelAnimation under the SkelRoot of a written clip, keyed at frames 0, 1, ..."""
    stage = Usd.Stage.Open(str(path))
    animation = UsdSkel.Animation.Define(stage, f"/walk/{name}")
    animation.CreateJointsAttr(Vt.TokenArray(joints))
    animation.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1.0, 1.0, 1.0)] * len(joints)))
    for frame in range(len(rotations)):
        animation.CreateRotationsAttr().Set(
            Vt.QuatfArray.FromNumpy(rotations[frame].astype(np.float32)), frame
        )
        animation.CreateTranslationsAttr().Set(
            Vt.Vec3fArray.FromNumpy(translations[frame].astype(np.float32)), frame
        )
    if bind:
        UsdSkel.BindingAPI(stage.GetPrimAtPath("/walk/Skeleton")).GetAnimationSourceRel().SetTargets(
            [animation.GetPath()]
        )
    stage.Save()


def test_two_animations_give_two_clips_named_after_their_prims(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    joints = list(JOINT_PATHS)
    turned = quat.multiply(quat.from_euler(np.array([0.0, 90.0, 0.0]), "XYZ"), original.rotations)
    _add_animation(path, "turn", joints, turned, original.translations)
    first, second = read(path)
    assert (first.name, second.name) == ("walk/walk", "walk/turn")
    assert_same_rotations(first.rotations, original.rotations)
    assert_same_rotations(second.rotations, turned)


def test_sparse_reordered_animation_keeps_rest_for_undriven_joints(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    # Drives only the left knee then the hips (skeleton order is hips first): the rest stays at rest.
    joints = ["Hips/LeftUpLeg/LeftLeg", "Hips"]
    picked = [2, 0]
    _add_animation(
        path, "sparse", joints, original.rotations[:, picked], original.translations[:, picked], bind=True
    )
    clips = {clip.name: clip for clip in read(path)}
    sparse = clips["walk/sparse"]
    rest = original.skeleton.rest_rotations
    assert_same_rotations(sparse.rotations[:, picked], original.rotations[:, picked])
    assert_same_rotations(
        sparse.rotations[:, [1, 3, 4, 5]], np.broadcast_to(rest[[1, 3, 4, 5]], (FRAMES, 4, 4))
    )
    # UsdSkel fills the undriven joints from restTransforms too: it is the oracle for the mapping.
    assert_fk_matches_usdskel(sparse, path, "/walk/Skeleton", [float(f) for f in range(FRAMES)])


def test_skelroot_transform_is_applied_to_the_root_joints(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    stage = Usd.Stage.Open(str(path))
    xform = UsdGeom.Xformable(stage.GetPrimAtPath("/walk"))
    xform.AddTranslateOp().Set(Gf.Vec3d(1.0, 0.0, -2.0))
    xform.AddRotateXOp().Set(-90.0)
    xform.AddScaleOp().Set(Gf.Vec3f(2.0, 2.0, 2.0))
    stage.Save()
    [clip] = read(path)
    assert any("transform of </walk/Skeleton>" in note for note in clip.notes)
    assert_fk_matches_usdskel(clip, path, "/walk/Skeleton", [float(f) for f in range(FRAMES)])


def test_rest_pose_falls_back_to_bind_transforms(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/walk/Skeleton").RemoveProperty("restTransforms")
    stage.Save()
    [clip] = read(path)
    assert_same_rotations(clip.skeleton.rest_rotations, original.skeleton.rest_rotations)
    np.testing.assert_allclose(
        clip.skeleton.rest_translations, original.skeleton.rest_translations, atol=1e-9
    )


def test_keys_on_a_regular_half_step_set_the_frame_rate(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    stage = Usd.Stage.Open(str(path))
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/walk/Skeleton/walk"))
    for attribute in (animation.GetRotationsAttr(), animation.GetTranslationsAttr()):
        keys = {time: attribute.Get(time) for time in attribute.GetTimeSamples()}
        attribute.Clear()
        for time, value in keys.items():
            attribute.Set(value, time / 2.0)
    stage.SetEndTimeCode((FRAMES - 1) / 2.0)
    stage.Save()
    [clip] = read(path)
    assert (clip.fps, clip.frame_count) == (60.0, FRAMES)
    assert_same_rotations(clip.rotations, original.rotations)


def _hold_first_pose(path: Path, start: float, end: float) -> None:
    """Make the file's animation a pose with no time samples (its values as defaults) over the
    stage's time codes ``start``..``end``, as Blender writes a still idle."""
    stage = Usd.Stage.Open(str(path))
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/walk/Skeleton/walk"))
    for attribute in (animation.GetRotationsAttr(), animation.GetTranslationsAttr()):
        keys = attribute.GetTimeSamples()
        first = attribute.Get(keys[0]) if keys else attribute.Get()
        attribute.Clear()
        attribute.Set(first)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    stage.Save()


def test_a_pose_without_time_samples_is_held_over_the_stage_range(tmp_path: Path) -> None:
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path, meters_per_unit=1.0, up_axis="y")
    _hold_first_pose(path, 1.0, 250.0)
    [clip] = read(path)
    assert (clip.frame_count, clip.fps) == (250, 30.0)
    assert any("no time samples: its pose held over the stage's time codes 1-250" in n for n in clip.notes)
    for frame in (0, 124, 249):
        assert_same_rotations(clip.rotations[frame], original.rotations[0])
        np.testing.assert_allclose(clip.translations[frame], original.translations[0], atol=1e-6)
    # A Skeleton prim that moves while its animation holds one pose: the motion is read.
    stage = Usd.Stage.Open(str(path))
    mover = UsdGeom.Xformable(stage.GetPrimAtPath("/walk/Skeleton")).AddTranslateOp(opSuffix="carry")
    mover.Set(Gf.Vec3d(0.0, 0.0, 0.0), 1.0)
    mover.Set(Gf.Vec3d(0.0, 0.0, 1.45), 250.0)
    stage.Save()
    [carried] = read(path)
    _, world = forward_kinematics(carried)
    assert world[-1, 0, 2] - world[0, 0, 2] == pytest.approx(1.45, abs=1e-4)
    stage.GetPrimAtPath("/walk/Skeleton").RemoveProperty("xformOp:translate:carry")
    UsdGeom.Xformable(stage.GetPrimAtPath("/walk/Skeleton")).ClearXformOpOrder()
    stage.Save()
    # A stage whose range is one time code (or none) still reads one pose, as before.
    _hold_first_pose(path, 1.0, 1.0)
    [clip] = read(path)
    assert clip.frame_count == 1
    assert any("read as a single pose" in n for n in clip.notes)


def test_a_pose_without_keys_beside_a_keyed_take_stays_one_pose(tmp_path: Path) -> None:
    """Beside a keyed take, an animation without keys is a pose (a `TPose` action): one frame,
    which the build leaves out, as before; held over the stage's frames it became a sample."""
    original = walk_clip()
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    joints = list(JOINT_PATHS[:5])
    stage = Usd.Stage.Open(str(path))
    pose = UsdSkel.Animation.Define(stage, "/walk/TPose")
    pose.CreateJointsAttr(Vt.TokenArray(joints))
    pose.CreateRotationsAttr().Set(Vt.QuatfArray.FromNumpy(original.rotations[0, :5].astype(np.float32)))
    pose.CreateTranslationsAttr().Set(
        Vt.Vec3fArray.FromNumpy(original.translations[0, :5].astype(np.float32))
    )
    stage.Save()
    walk, tpose = read(path)
    assert (walk.name, walk.frame_count) == ("walk/walk", FRAMES)
    assert (tpose.name, tpose.frame_count) == ("walk/TPose", 1)


def test_non_unit_scales_are_noted(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    stage = Usd.Stage.Open(str(path))
    scales = [Gf.Vec3h(1.0, 1.0, 1.0)] * 5 + [Gf.Vec3h(1.5, 1.5, 1.5)]
    UsdSkel.Animation(stage.GetPrimAtPath("/walk/Skeleton/walk")).GetScalesAttr().Set(Vt.Vec3hArray(scales))
    stage.Save()
    [clip] = read(path)
    assert any("scales" in note for note in clip.notes)


def _read_error(path: Path) -> ClipReadError:
    with pytest.raises(ClipReadError) as caught:
        read(path)
    error = caught.value
    assert error.path == path and error.hint
    return error


def test_stage_without_skeleton_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "props.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Xform.Define(stage, "/Hips/Spine")
    stage.Save()
    assert "no UsdSkel Skeleton" in _read_error(path).message


def test_skeleton_without_animation_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    stage = Usd.Stage.Open(str(path))
    stage.RemovePrim("/walk/Skeleton/walk")
    stage.Save()
    error = _read_error(path)
    assert "</walk/Skeleton>" in error.message and "skel:animationSource" in (error.hint or "")


def test_garbage_bytes_are_rejected(tmp_path: Path) -> None:
    path = tmp_path / "broken.usda"
    path.write_bytes(b"\x00\x9f\x12 this is not usd {{{")
    assert "USD" in _read_error(path).message


def test_syntax_error_reports_its_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.usda"
    path.write_text('#usda 1.0\n\ndef SkelRoot "A"\n{\n    float x = \n}\n', encoding="utf-8")
    error = _read_error(path)
    assert error.line == 5 and str(path) not in error.message


def test_usdz_package_reads_like_its_layer(tmp_path: Path) -> None:
    original = walk_clip()
    layer, package = tmp_path / "walk.usdc", tmp_path / "walk.usdz"
    write_usd_clip(original, layer)
    assert UsdUtils.CreateNewUsdzPackage(str(layer), str(package))
    [clip] = read_clips(package)
    assert clip.skeleton.names == original.skeleton.names
    np.testing.assert_allclose(clip.translations, original.translations, atol=1e-5)


def test_names_that_are_not_usd_identifiers_survive_through_joint_names(tmp_path: Path) -> None:
    original = walk_clip()
    names = tuple(f"mixamorig:{name}" for name in original.skeleton.names)
    original.skeleton = Skeleton(
        names,
        original.skeleton.parents,
        original.skeleton.rest_translations,
        original.skeleton.rest_rotations,
    )
    path = tmp_path / "walk.usda"
    write_usd_clip(original, path)
    stage = Usd.Stage.Open(str(path))
    joints = UsdSkel.Skeleton(stage.GetPrimAtPath("/walk/Skeleton")).GetJointsAttr().Get()
    assert joints[2] == "mixamorig_Hips/mixamorig_LeftUpLeg/mixamorig_LeftLeg"
    [clip] = read(path)
    assert clip.skeleton.names == names


def test_shared_leaf_names_fall_back_to_full_joint_paths(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    stage = Usd.Stage.Open(str(path))
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/walk/Skeleton"))
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/walk/Skeleton/walk"))
    renamed = [
        str(j).replace("RightUpLeg/RightLeg", "RightUpLeg/LeftLeg") for j in skeleton.GetJointsAttr().Get()
    ]
    skeleton.GetJointsAttr().Set(Vt.TokenArray(renamed))
    animation.GetJointsAttr().Set(Vt.TokenArray(renamed))
    skeleton.GetJointNamesAttr().Clear()
    stage.Save()
    [clip] = read(path)
    assert clip.skeleton.names == (
        "Hips",
        "LeftUpLeg",
        "Hips/LeftUpLeg/LeftLeg",
        "RightUpLeg",
        "Hips/RightUpLeg/LeftLeg",
        "Spine",
    )


def _flat(clip: Clip) -> Clip:
    """``clip`` as a Godot Animation resource gives it: every joint its own track, no hierarchy."""
    skeleton = clip.skeleton
    clip.skeleton = Skeleton(
        skeleton.names,
        tuple(-1 for _ in skeleton.names),
        skeleton.rest_translations,
        skeleton.rest_rotations,
        has_hierarchy=False,
    )
    return clip


def test_flat_skeleton_is_marked_and_read_back_flat(tmp_path: Path) -> None:
    path = tmp_path / "walk.usda"
    write_usd_clip(_flat(walk_clip()), path)
    [clip] = read(path)
    assert not clip.skeleton.has_hierarchy
    assert clip.skeleton.parents == (-1,) * 6
    # An ordinary rig authors no mark, so its files stay as they were.
    write_usd_clip(walk_clip(), tmp_path / "rig.usda")
    assert "blendspace_pipeline" not in (tmp_path / "rig.usda").read_text()
    assert read(tmp_path / "rig.usda")[0].skeleton.has_hierarchy


def test_flat_mark_is_ignored_once_joints_have_parents(tmp_path: Path) -> None:
    """An edited file whose joints gained a hierarchy must be posed through it, as UsdSkel does."""
    path = tmp_path / "walk.usda"
    write_usd_clip(walk_clip(), path)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/walk/Skeleton").SetCustomDataByKey("blendspace_pipeline:hasHierarchy", False)
    stage.Save()
    assert read(path)[0].skeleton.has_hierarchy


def test_godot_clip_measures_the_same_after_a_usd_round_trip(tmp_path: Path) -> None:
    """A .tres clip has no hierarchy, so it is measured on its root track; written to USD (as a
    generated clip is) and read back, it must still be, not switch to the hip line."""
    from conftest import shared_data

    from blendspace_pipeline.motion.detect import RigSettings
    from blendspace_pipeline.motion.measure import measure

    [source] = read_clips(shared_data("godot-tps-demo", "strafe_left-cycle.tres"))
    path = tmp_path / "strafe_left.usda"
    write_usd_clip(source, path)
    [clip] = read_clips(path)
    assert not clip.skeleton.has_hierarchy
    before, after = measure(source, RigSettings()), measure(clip, RigSettings())
    assert (after.root, after.facing) == (before.root, before.facing)
    for name, value in before.features.items():
        assert after.features[name] == pytest.approx(value, abs=1e-6), name
