"""A clip as a UsdSkel asset: `SkelRoot` > `Skeleton` > `SkelAnimation`, written with usd-core.

Frame ``i`` is time code ``i`` and ``timeCodesPerSecond`` is the clip's rate, so any USD player
shows the clip at its own speed. The skeleton carries ``restTransforms`` (local) and
``bindTransforms`` (the world rest pose) so UsdSkel can pose joints the animation leaves out, and
``jointNames`` keeps the original names when they are not valid USD path elements (``a:b``).
A skeleton without hierarchy (a Godot Animation resource's bare tracks) is written flat and marked
so in the Skeleton prim's ``customData`` (`FLAT_SKELETON_KEY`): a flat joint list alone does not
say whether the source had no hierarchy, and measurement takes root motion and facing from a
single joint's track only for such clips, so without the mark a re-read clip would measure
differently.
The file is deterministic: no timestamps, one float32 per value, so a rebuild is byte-identical.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdSkel, Vt
from scipy.spatial.transform import Rotation

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.provenance import USD_KEY, Provenance

SUFFIXES = (".usd", ".usda", ".usdc")
# customData key path (nested dictionary ``blendspace_pipeline = {hasHierarchy = false}``) on the
# Skeleton prim; `readers.usd` restores `Skeleton.has_hierarchy` from it.
FLAT_SKELETON_KEY = "blendspace_pipeline:hasHierarchy"


def write_usd_clip(
    clip: Clip,
    path: Path,
    *,
    meters_per_unit: float | None = None,
    up_axis: str | None = None,
    provenance: Provenance | None = None,
) -> None:
    """Write ``clip`` to ``path`` atomically; ``meters_per_unit``/``up_axis`` override the clip's.

    ``provenance`` (a generated clip's record) goes into the default prim's ``customData``.

    Raises `ValueError` when the units or up axis are unknown: USD's fallbacks (centimetres,
    Y up) would silently mislabel a metre-scale or Z-up clip, so the caller must decide.
    """
    units = meters_per_unit if meters_per_unit is not None else clip.meters_per_unit
    up = (up_axis or clip.up_axis or "").lower()
    if units is None or not units > 0:
        raise ValueError(f"clip {clip.name!r}: metres per unit unknown; pass meters_per_unit")
    if up not in ("y", "z"):
        raise ValueError(f"clip {clip.name!r}: up axis unknown; pass up_axis='y' or 'z'")
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"{path}: a USD clip is written as one of {', '.join(SUFFIXES)}")
    layer = Sdf.Layer.CreateAnonymous(".usda")
    stage = Usd.Stage.Open(layer)
    _write_metadata(stage, clip, units, up)
    root = UsdSkel.Root.Define(stage, Sdf.Path.absoluteRootPath.AppendChild(_identifier(clip.name)))
    stage.SetDefaultPrim(root.GetPrim())
    if provenance is not None:
        record = provenance.as_dict()
        record["sources"] = Vt.StringArray(record["sources"])
        record["weights"] = Vt.DoubleArray(record["weights"])
        root.GetPrim().SetCustomDataByKey(USD_KEY, record)
    joints = joint_paths(clip.skeleton)
    skeleton = _write_skeleton(stage, root.GetPath().AppendChild("Skeleton"), clip.skeleton, joints)
    animation = _write_animation(stage, skeleton.GetPath().AppendChild(_identifier(clip.name)), clip, joints)
    binding = UsdSkel.BindingAPI.Apply(skeleton.GetPrim())
    binding.CreateAnimationSourceRel().SetTargets([animation.GetPath()])
    _export_atomically(layer, path)


def joint_paths(skeleton: Skeleton) -> list[str]:
    """UsdSkel joint paths (``Hips/Spine/Chest``) built from the hierarchy.

    A skeleton without hierarchy (tracks only) is written flat, so UsdSkel poses each joint on
    its own exactly as `forward_kinematics` does.
    """
    paths: list[str] = []
    taken: set[str] = set()
    for joint, parent in enumerate(skeleton.parents):
        prefix = paths[parent] + "/" if parent >= 0 and skeleton.has_hierarchy else ""
        candidate = prefix + _identifier(skeleton.names[joint])
        unique, counter = candidate, 1
        while unique in taken:
            counter += 1
            unique = f"{candidate}_{counter}"
        taken.add(unique)
        paths.append(unique)
    return paths


def _identifier(name: str) -> str:
    return str(Tf.MakeValidIdentifier(name))


def _write_metadata(stage: Usd.Stage, clip: Clip, meters_per_unit: float, up: str) -> None:
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "z" else UsdGeom.Tokens.y)
    stage.SetTimeCodesPerSecond(float(clip.fps))
    stage.SetFramesPerSecond(float(clip.fps))
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(float(max(clip.frame_count - 1, 0)))


def _write_skeleton(
    stage: Usd.Stage, where: Sdf.Path, skeleton: Skeleton, joints: list[str]
) -> UsdSkel.Skeleton:
    skel = UsdSkel.Skeleton.Define(stage, where)
    skel.CreateJointsAttr(Vt.TokenArray(joints))
    skel.CreateJointNamesAttr(Vt.TokenArray(list(skeleton.names)))
    rest_t, rest_r = skeleton.rest_translations, skeleton.rest_rotations
    skel.CreateRestTransformsAttr(_matrices(rest_t, rest_r))
    # bindTransforms are world-space: the rest pose run through the same FK as the clip.
    world_r, world_t = _rest_world(skeleton)
    skel.CreateBindTransformsAttr(_matrices(world_t, world_r))
    if not skeleton.has_hierarchy:
        # Authored only for flat skeletons, so files of ordinary rigs stay byte-identical to
        # earlier builds; an absent key means the joint paths are the hierarchy, as in any USD.
        skel.GetPrim().SetCustomDataByKey(FLAT_SKELETON_KEY, False)
    return skel


def _rest_world(skeleton: Skeleton) -> tuple[FloatArray, FloatArray]:
    world_r = np.empty_like(skeleton.rest_rotations)
    world_t = np.empty_like(skeleton.rest_translations)
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0 or not skeleton.has_hierarchy:
            world_r[joint], world_t[joint] = skeleton.rest_rotations[joint], skeleton.rest_translations[joint]
            continue
        world_r[joint] = quat.multiply(world_r[parent], skeleton.rest_rotations[joint])
        world_t[joint] = world_t[parent] + quat.rotate(world_r[parent], skeleton.rest_translations[joint])
    return world_r, world_t


def _matrices(translations: FloatArray, rotations: FloatArray) -> Vt.Matrix4dArray:
    """Gf matrices use row vectors (``p' = p M``): the rotation block is R transposed."""
    rotation = Rotation.from_quat(quat.normalize(rotations)).as_matrix()
    out = np.zeros((len(translations), 4, 4))
    out[:, :3, :3] = np.transpose(rotation, (0, 2, 1))
    out[:, 3, :3] = translations
    out[:, 3, 3] = 1.0
    return Vt.Matrix4dArray([Gf.Matrix4d(*m.ravel().tolist()) for m in out])


def _write_animation(stage: Usd.Stage, where: Sdf.Path, clip: Clip, joints: list[str]) -> UsdSkel.Animation:
    animation = UsdSkel.Animation.Define(stage, where)
    animation.CreateJointsAttr(Vt.TokenArray(joints))
    translations = animation.CreateTranslationsAttr()
    rotations = animation.CreateRotationsAttr()
    # Scales never change in a Clip: one default value instead of a copy per frame.
    animation.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1.0, 1.0, 1.0)] * len(joints)))
    # Our quaternions are xyzw like GfQuatf's memory layout (imaginary, then real).
    quats = quat.normalize(clip.rotations).astype(np.float32)
    offsets = clip.translations.astype(np.float32)
    for frame in range(clip.frame_count):
        time = Usd.TimeCode(float(frame))
        translations.Set(Vt.Vec3fArray.FromNumpy(offsets[frame]), time)
        rotations.Set(Vt.QuatfArray.FromNumpy(quats[frame]), time)
    return animation


def _export_atomically(layer: Sdf.Layer, path: Path) -> None:
    """Export beside ``path`` under the same suffix (it picks the file format), then rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # A fresh name that USD creates itself (mkstemp's file would keep mode 0600).
    temporary = path.with_name(f".{path.stem}.{os.getpid()}.{uuid.uuid4().hex}{path.suffix}")
    try:
        if not layer.Export(str(temporary)):
            raise OSError(f"USD could not write {temporary}")
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
