"""USD (UsdSkel) clips: one clip per `SkelAnimation` that drives a `Skeleton` on the stage.

An animation belongs to a skeleton when the skeleton (or an ancestor such as the SkelRoot) binds
it with ``skel:animationSource``, or, for an unbound animation, when every joint it lists is one
of the skeleton's joints (animation libraries often ship clips without a binding). Joints the
animation does not drive keep their rest transform, as UsdSkel itself poses them. The skeleton
prim's own transform (an up-axis or unit conversion on the SkelRoot, root motion on an Xform) is
folded into the root joints, so the clip's joints sit where UsdSkel puts them in the world.
A flat skeleton marked by our writer as having no hierarchy (`usd_clip.FLAT_SKELETON_KEY`, clips
made from Godot Animation tracks) is read back with ``has_hierarchy=False``, so it measures as
its source did.

USD has no line numbers once composed, so messages name the prim path instead.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom, UsdSkel, Vt
from scipy.spatial.transform import Rotation

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, UpAxis
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.limits import (
    REFERENCE_ROOTS,
    allowed_roots,
    check_regular,
    confined,
    current_roots,
    read_regular_file,
)
from blendspace_pipeline.writers.usd_clip import FLAT_SKELETON_KEY

SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")

# A stage range this long is a broken file, not a clip (a day at 120 fps is ~10 million).
_MAX_FRAMES = 1_000_000
# UsdSkel poses nothing unless translations, rotations and scales are all authored; we read
# what is there (a forgotten constant scale should not lose the clip) but say so.
_STRICT = " (UsdSkel itself shows such an animation at rest)"
_REEXPORT = "re-export the clip from the DCC with UsdSkel animation (skeleton and SkelAnimation)"


def read(path: Path) -> list[Clip]:
    """Every SkelAnimation in ``path`` that drives a Skeleton, as clips."""
    try:
        return _read_stage(path, _open(path))
    except Tf.ErrorException as error:
        raise _usd_error(path, error) from None


def _open(path: Path) -> Usd.Stage:
    _check_text(path)
    _check_dependencies(path)
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise ClipReadError("USD could not open the file", path=path, hint=_REEXPORT)
    return stage


_MAX_LAYERS = 256  # sublayers and references of one clip, all together


def _check_text(path: Path) -> None:
    """A text USD file must be UTF-8: USD's own error for other bytes cannot even be printed."""
    check_regular(path, what="USD file")
    with open(path, "rb") as stream:
        if stream.read(5) != b"#usda":
            return  # binary crate or a package: USD reads those itself
    data = read_regular_file(path, what="USD file")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        column = error.start - (data.rfind(b"\n", 0, error.start) + 1) + 1
        raise ClipReadError(
            f"not valid USD: the text is not UTF-8 (byte 0x{data[error.start]:02x})",
            path=path,
            line=line,
            column=column,
            hint="save the file as UTF-8, or re-export it",
        ) from None


def _check_dependencies(path: Path, keep: list[object] | None = None) -> list[Path]:
    """Every sublayer, reference and payload resolves inside the project and is a regular file,
    checked layer by layer *before* USD composes (and so reads) any of them. Returns the layer
    files the clip composes besides its own (a `.usdz` package's inner layers are its bytes)."""
    roots = current_roots(path)
    seen: set[str] = set()
    found: list[Path] = []
    pending = [str(path)]
    while pending:
        current = pending.pop()
        if current in seen:
            continue
        seen.add(current)
        if len(seen) > _MAX_LAYERS:
            raise ClipReadError(
                f"the clip composes more than {_MAX_LAYERS} layers", path=path, hint=_REEXPORT
            )
        layer = Sdf.Layer.FindOrOpen(current)
        if layer is None:
            continue  # Usd.Stage.Open reports it
        if keep is not None:
            keep.append(layer)
        dependencies = (
            layer.GetCompositionAssetDependencies()
            if hasattr(layer, "GetCompositionAssetDependencies")
            else layer.externalReferences
        )
        for asset in dependencies:
            if not asset:
                continue
            resolved = layer.ComputeAbsolutePath(asset)
            outer = resolved.split("[", 1)[0]  # a file inside a .usdz package: check the package
            target = confined(path, outer, roots, what=f"USD layer reference {asset!r}")
            check_regular(target, what=f"USD layer {asset!r}")
            found.append(target)
            if "[" not in resolved:
                pending.append(str(target))
    return found


def composed_layers(path: Path, project: Path | None = None, keep: list[object] | None = None) -> list[Path]:
    """The layer files ``path`` composes (`_check_dependencies`, with the roots `read_clips`
    allows); [] when one of them is not allowed (reading the clip says why). ``keep`` receives
    the opened layers: while the caller holds them, reading the clip opens none of them again
    (USD's layer registry keeps a layer only while it is referenced; an 18 MB shared layer was
    parsed twice per clip)."""
    token = REFERENCE_ROOTS.set(allowed_roots(path, project))
    try:
        check_regular(path, what="USD file")
        return _check_dependencies(path, keep)
    except (ClipReadError, Tf.ErrorException):  # a broken layer: reading the clip says where
        return []
    finally:
        REFERENCE_ROOTS.reset(token)


def _usd_error(path: Path, error: Tf.ErrorException) -> ClipReadError:
    """The first USD error, with the text parser's ``file:line:col`` turned into our location."""
    text = _error_text(error)
    parsed = re.search(r":(\d+):(\d+): ([^\n]*)", text)
    if parsed:
        detail = parsed.group(3).rstrip("'")
        return ClipReadError(
            f"not valid USD: {detail}",
            path=path,
            line=int(parsed.group(1)),
            column=int(parsed.group(2)),
            hint="fix the syntax at that line or re-export the file",
        )
    quoted = re.search(r" : '([^\n]*)", text)
    detail = quoted.group(1).rstrip("'") if quoted else text.strip()
    return ClipReadError(
        f"not a readable USD file: {detail}",
        path=path,
        hint="the file is truncated, corrupt or not USD; " + _REEXPORT,
    )


def _error_text(error: Tf.ErrorException) -> str:
    # USD's errors quote the offending bytes; str() of a non-UTF-8 quote raises UnicodeDecodeError.
    parts = []
    for each in error.args:
        try:
            parts.append(str(each))
        except UnicodeDecodeError:
            parts.append("the file holds bytes that are not UTF-8 text")
    return "\n".join(parts)


def _read_stage(path: Path, stage: Usd.Stage) -> list[Clip]:
    prims = list(_all_prims(stage))
    skeletons = [UsdSkel.Skeleton(prim) for prim in prims if prim.IsA(UsdSkel.Skeleton)]
    if not skeletons:
        raise ClipReadError(
            "no UsdSkel Skeleton on the stage",
            path=path,
            hint="export the character as UsdSkel (a SkelRoot holding a Skeleton with joints and "
            "restTransforms, plus a SkelAnimation); plain Xform joint hierarchies are not read",
        )
    animations = [UsdSkel.Animation(prim) for prim in prims if prim.IsA(UsdSkel.Animation)]
    pairs = _match_animations(skeletons, animations)
    if not pairs:
        where = ", ".join(f"<{skel.GetPath()}>" for skel in skeletons)
        raise ClipReadError(
            f"no SkelAnimation drives Skeleton {where}",
            path=path,
            hint="bind the animation with skel:animationSource on the Skeleton or its SkelRoot "
            "(UsdSkelBindingAPI), or export with animation enabled; an unbound SkelAnimation is "
            "used only when all its joints are joints of the Skeleton",
        )
    names = _clip_names(path, [animation for _, animation in pairs])
    # A pose without keys is held over the stage's frames only where nothing in the file is keyed
    # (a still idle exported alone); beside keyed takes it is a pose (a `TPose` action), one frame.
    keyed = any(_keyed(animation) for _, animation in pairs)
    return [
        _read_clip(path, stage, name, skel, animation, hold=not keyed)
        for name, (skel, animation) in zip(names, pairs, strict=True)
    ]


def _keyed(animation: UsdSkel.Animation) -> bool:
    attributes = (animation.GetTranslationsAttr(), animation.GetRotationsAttr(), animation.GetScalesAttr())
    return any(attribute.GetNumTimeSamples() > 0 for attribute in attributes)


def _all_prims(stage: Usd.Stage) -> Iterator[Usd.Prim]:
    # Instanced characters (crowds, referenced assets) hide their prims behind instance proxies.
    yield from Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))


def _match_animations(
    skeletons: list[UsdSkel.Skeleton], animations: list[UsdSkel.Animation]
) -> list[tuple[UsdSkel.Skeleton, UsdSkel.Animation]]:
    """(skeleton, animation) per animation, in stage order; bound animations first choice."""
    bound: dict[Sdf.Path, UsdSkel.Skeleton] = {}
    for skel in skeletons:
        source = UsdSkel.BindingAPI(skel.GetPrim()).GetInheritedAnimationSource()
        if source and source.GetPath() not in bound:
            bound[source.GetPath()] = skel
    pairs = []
    for animation in animations:
        skel = bound.get(animation.GetPath()) or _skeleton_for_joints(skeletons, animation)
        if skel is not None:
            pairs.append((skel, animation))
    return pairs


def _skeleton_for_joints(
    skeletons: list[UsdSkel.Skeleton], animation: UsdSkel.Animation
) -> UsdSkel.Skeleton | None:
    driven = set(_tokens(animation.GetJointsAttr()))
    for skel in skeletons:
        if driven and driven <= set(_tokens(skel.GetJointsAttr())):
            return skel
    return None


def _tokens(attribute: Usd.Attribute) -> list[str]:
    value = attribute.Get()
    return [str(token) for token in value] if value is not None else []


def _clip_names(path: Path, animations: list[UsdSkel.Animation]) -> list[str]:
    if len(animations) == 1:
        return [path.stem]
    names = [f"{path.stem}/{animation.GetPrim().GetName()}" for animation in animations]
    # Two animations of the same name under different parents: the prim path tells them apart.
    return [
        name if names.count(name) == 1 else f"{path.stem}/{str(animation.GetPath()).lstrip('/')}"
        for name, animation in zip(names, animations, strict=True)
    ]


@dataclass(frozen=True)
class _Layout:
    """The skeleton as read: joint paths (the animation's keys) and our `Skeleton`."""

    paths: list[str]
    skeleton: Skeleton


def _read_clip(
    path: Path,
    stage: Usd.Stage,
    name: str,
    skel: UsdSkel.Skeleton,
    animation: UsdSkel.Animation,
    *,
    hold: bool,
) -> Clip:
    layout = _read_layout(path, skel)
    times, fps, notes = _frame_times(path, stage, animation, hold=hold)
    rotations, translations = _sample_animation(path, animation, layout, times, notes)
    skeleton = _fold_prim_transform(skel, layout.skeleton, times, rotations, translations, notes)
    meters_per_unit, up_axis = _stage_units(stage, notes)
    return Clip(
        name=name,
        source=path,
        skeleton=skeleton,
        rotations=rotations,
        translations=translations,
        fps=fps,
        meters_per_unit=meters_per_unit,
        up_axis=up_axis,
        notes=notes,
    )


def _read_layout(path: Path, skel: UsdSkel.Skeleton) -> _Layout:
    where = skel.GetPath()
    joints = skel.GetJointsAttr()
    if joints.HasAuthoredValue() and joints.GetTypeName() != Sdf.ValueTypeNames.TokenArray:
        raise ClipReadError(
            f"Skeleton <{where}>: `joints` is {joints.GetTypeName()}, not token[]",
            path=path,
            hint='author joints as `uniform token[] joints = ["Hips", "Hips/Spine", ...]`',
        )
    paths = _tokens(joints)
    if not paths:
        raise ClipReadError(
            f"Skeleton <{where}> has no joints", path=path, hint="author the Skeleton's joints array"
        )
    if len(set(paths)) != len(paths):
        twice = sorted({p for p in paths if paths.count(p) > 1})
        raise ClipReadError(
            f"Skeleton <{where}> lists joint {twice[0]!r} twice", path=path, hint="joint paths must be unique"
        )
    topology = UsdSkel.Topology(Vt.TokenArray(paths))
    valid, reason = topology.Validate()
    if not valid:
        raise ClipReadError(f"Skeleton <{where}>: {reason}", path=path, hint=_REEXPORT)
    parents = tuple(int(p) for p in topology.GetParentIndices())
    rest_t, rest_r = _rest_pose(path, skel, parents)
    skeleton = Skeleton(_joint_names(skel, paths), parents, rest_t, rest_r, _has_hierarchy(skel, parents))
    return _Layout(paths, skeleton)


def _has_hierarchy(skel: UsdSkel.Skeleton, parents: tuple[int, ...]) -> bool:
    """False only for a flat joint list our writer marked as having no hierarchy.

    The mark is ignored once the joints have parents (an edited file): forward kinematics must
    then follow the hierarchy, as UsdSkel does.
    """
    marked = skel.GetPrim().GetCustomDataByKey(FLAT_SKELETON_KEY)
    return not (marked is False and all(parent < 0 for parent in parents))


def _joint_names(skel: UsdSkel.Skeleton, paths: list[str]) -> tuple[str, ...]:
    """``jointNames`` when authored and usable, else the last path element (full path if shared)."""
    authored = _tokens(skel.GetJointNamesAttr())
    if len(authored) == len(paths) and all(authored) and len(set(authored)) == len(authored):
        return tuple(authored)
    leaves = [p.rsplit("/", 1)[-1] for p in paths]
    return tuple(leaf if leaves.count(leaf) == 1 else p for leaf, p in zip(leaves, paths, strict=True))


def _rest_pose(path: Path, skel: UsdSkel.Skeleton, parents: tuple[int, ...]) -> tuple[FloatArray, FloatArray]:
    """Local rest transforms, or local transforms derived from the world-space bind pose."""
    count = len(parents)
    rest = skel.GetRestTransformsAttr().Get()
    if rest is not None and len(rest) == count:
        translations, rotations, _ = _decompose(np.array(rest, dtype=np.float64))
        return translations, rotations
    bind = skel.GetBindTransformsAttr().Get()
    if bind is None or len(bind) != count:
        raise ClipReadError(
            f"Skeleton <{skel.GetPath()}> has neither restTransforms nor bindTransforms "
            f"for its {count} joints",
            path=path,
            hint="author restTransforms (local rest pose, one matrix per joint) on the Skeleton",
        )
    world = np.array(bind, dtype=np.float64)
    local = world.copy()
    for joint, parent in enumerate(parents):
        if parent >= 0:
            # Gf matrices use row vectors: world = local * parent_world.
            local[joint] = world[joint] @ np.linalg.inv(world[parent])
    translations, rotations, _ = _decompose(local)
    return translations, rotations


def _decompose(matrices: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Translation, rotation (xyzw) and per-axis scale of row-vector Gf matrices (N, 4, 4)."""
    basis = matrices[:, :3, :3]
    scale = np.linalg.norm(basis, axis=2)
    column_rotation = np.transpose(basis / np.where(scale == 0.0, 1.0, scale)[..., None], (0, 2, 1))
    rotations = Rotation.from_matrix(column_rotation).as_quat()
    return matrices[:, 3, :3].copy(), np.asarray(rotations, dtype=np.float64), scale


def _frame_times(
    path: Path, stage: Usd.Stage, animation: UsdSkel.Animation, *, hold: bool = True
) -> tuple[list[Usd.TimeCode], float, list[str]]:
    """Time codes to sample, and the frame rate they stand for. ``hold``: an animation without
    keys is its pose held over the stage's time codes (else one frame)."""
    rate = float(stage.GetTimeCodesPerSecond())
    attributes = (animation.GetTranslationsAttr(), animation.GetRotationsAttr(), animation.GetScalesAttr())
    samples = sorted({float(t) for attribute in attributes for t in attribute.GetTimeSamples()})
    ranged = stage.HasAuthoredTimeCodeRange() and stage.GetEndTimeCode() >= stage.GetStartTimeCode()
    held = hold and not samples and ranged and stage.GetEndTimeCode() > stage.GetStartTimeCode()
    if not samples and not held:
        return [Usd.TimeCode.Default()], rate, ["the animation has no time samples: read as a single pose"]
    start, end = (samples[0], samples[-1]) if samples else (0.0, 0.0)
    if ranged:
        start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    step, notes = 1.0, []
    steps = np.diff(samples)
    # Keys on a regular step other than one time code (a 30 fps bake in a 60 tcps stage,
    # 120 Hz mocap at 0.2 time codes) are the clip's true rate; fewer than 3 keys prove nothing.
    if len(steps) >= 2 and np.allclose(steps, steps[0], rtol=1e-6, atol=1e-9) and abs(steps[0] - 1.0) > 1e-9:
        step = float(steps[0])
        notes.append(
            f"keys every {step:g} time codes: read at {rate / step:g} fps (timeCodesPerSecond {rate:g})"
        )
    if held:
        # A pose held over the stage's frames (Blender writes a still idle so: values, no keys).
        # An engine imports it over that range, and so is it read: a still pose of that length
        # (sampled at every time code: a Skeleton prim's own transform may still move).
        notes.append(
            f"the animation has no time samples: its pose held over the stage's time codes {start:g}-{end:g}"
        )
    count = int(np.floor((end - start) / step + 1e-6)) + 1
    if count > _MAX_FRAMES:
        raise ClipReadError(
            f"SkelAnimation <{animation.GetPath()}> spans {count} frames",
            path=path,
            hint="check startTimeCode/endTimeCode in the stage metadata",
        )
    return [Usd.TimeCode(start + step * i) for i in range(count)], rate / step, notes


def _sample_animation(
    path: Path, animation: UsdSkel.Animation, layout: _Layout, times: list[Usd.TimeCode], notes: list[str]
) -> tuple[FloatArray, FloatArray]:
    """Per-frame local rotations and translations in skeleton joint order."""
    skeleton = layout.skeleton
    driven = _tokens(animation.GetJointsAttr())
    if not driven:
        raise ClipReadError(
            f"SkelAnimation <{animation.GetPath()}> lists no joints",
            path=path,
            hint="author the animation's joints array (paths of the Skeleton joints it drives)",
        )
    index = {joint: i for i, joint in enumerate(layout.paths)}
    sources = [i for i, joint in enumerate(driven) if joint in index]
    targets = [index[driven[i]] for i in sources]
    if len(sources) < len(driven):
        notes.append(f"{len(driven) - len(sources)} animated joints are not in the skeleton and were ignored")
    frames = len(times)
    rotations = np.tile(skeleton.rest_rotations, (frames, 1, 1))
    translations = np.tile(skeleton.rest_translations, (frames, 1, 1))
    channels = (
        (animation.GetTranslationsAttr(), translations, 3),
        (animation.GetRotationsAttr(), rotations, 4),
    )
    for attribute, out, width in channels:
        if not attribute.HasAuthoredValue():
            notes.append(f"{attribute.GetName()} not authored: the rest pose is used for it{_STRICT}")
            continue
        if attribute.GetNumTimeSamples() == 0:  # one value over every frame (a held pose)
            out[:, targets] = _array(path, attribute, Usd.TimeCode.Default(), len(driven), width)[sources]
            continue
        for frame, time in enumerate(times):
            # GfQuatf is stored imaginary-first, so its array converts straight to our xyzw.
            values = _array(path, attribute, time, len(driven), width)
            out[frame, targets] = values[sources]
    _note_scales(animation, times, notes)
    return quat.normalize(rotations), translations


def _array(path: Path, attribute: Usd.Attribute, time: Usd.TimeCode, count: int, width: int) -> FloatArray:
    value = attribute.Get(time)
    values = np.array(value if value is not None else [], dtype=np.float64).reshape(-1, width)
    if values.shape[0] != count:
        raise ClipReadError(
            f"<{attribute.GetPath()}> has {values.shape[0]} values at time {time.GetValue():g} "
            f"for {count} joints",
            path=path,
            hint="the animation's translations/rotations must have one value per entry of its joints array",
        )
    return values


def _note_scales(animation: UsdSkel.Animation, times: list[Usd.TimeCode], notes: list[str]) -> None:
    attribute = animation.GetScalesAttr()
    if not attribute.HasAuthoredValue():
        notes.append(f"scales not authored{_STRICT}")
        return
    for time in times:
        value = attribute.Get(time)
        if value is not None and len(value) and np.abs(np.array(value, dtype=np.float64) - 1.0).max() > 1e-3:
            notes.append("non-unit joint scales are ignored (clips carry rotation and translation only)")
            return


def _fold_prim_transform(
    skel: UsdSkel.Skeleton,
    skeleton: Skeleton,
    times: list[Usd.TimeCode],
    rotations: FloatArray,
    translations: FloatArray,
    notes: list[str],
) -> Skeleton:
    """Apply the Skeleton prim's local-to-world transform to the root joints (in place)."""
    imageable = UsdGeom.Imageable(skel.GetPrim())
    matrices = np.array([imageable.ComputeLocalToWorldTransform(t) for t in times], dtype=np.float64)
    if np.allclose(matrices, np.eye(4), atol=1e-9):
        return skeleton
    offsets, turns, scales = _decompose(matrices)
    if np.ptp(scales, axis=1).max() > 1e-4:
        notes.append("the Skeleton prim has a non-uniform scale: only its mean scale is applied")
    scale = scales.mean(axis=1)
    roots = [j for j, parent in enumerate(skeleton.parents) if parent < 0]
    children = [j for j, parent in enumerate(skeleton.parents) if parent >= 0]
    # Scaling the skeleton scales every offset; turning and moving it only touches the roots.
    translations[:, children] *= scale[:, None, None]
    for root in roots:
        rotations[:, root] = quat.multiply(turns, rotations[:, root])
        translations[:, root] = offsets + scale[:, None] * quat.rotate(turns, translations[:, root])
    notes.append(f"applied the transform of <{skel.GetPath()}> and its ancestors to the root joints")
    rest_t = skeleton.rest_translations.copy()
    rest_r = skeleton.rest_rotations.copy()
    rest_t[children] *= scale[0]
    rest_r[roots] = quat.multiply(turns[0], rest_r[roots])
    rest_t[roots] = offsets[0] + scale[0] * quat.rotate(turns[0], rest_t[roots])
    return replace(skeleton, rest_translations=rest_t, rest_rotations=rest_r)


def _stage_units(stage: Usd.Stage, notes: list[str]) -> tuple[float | None, UpAxis | None]:
    """Authored metersPerUnit and upAxis; None when unauthored so detection decides.

    USD's fallbacks (centimetres, Y up) are what many exporters forget to override, so an
    unauthored value is treated as unknown rather than trusted.
    """
    meters_per_unit: float | None = None
    up_axis: UpAxis | None = None
    if UsdGeom.StageHasAuthoredMetersPerUnit(stage):
        meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))
    else:
        notes.append("metersPerUnit is not authored (USD would assume centimetres): units are detected")
    if stage.HasAuthoredMetadata(UsdGeom.Tokens.upAxis):
        stated = str(stage.GetMetadata(UsdGeom.Tokens.upAxis))
        if stated in ("Y", "Z"):
            up_axis = "z" if stated == "Z" else "y"
        else:  # Blender writes "X" for a scene whose up is X: no USD up axis, so not trusted
            notes.append(f"upAxis {stated!r} is not a USD up axis (Y or Z): the up axis is detected")
    else:
        notes.append("upAxis is not authored: the up axis is detected")
    return meters_per_unit, up_axis
