"""FBX clips through ufbx, the open FBX loader, by its Python binding `pufbx` (optional extra).

``pip install 'blendspace-pipeline[fbx]'`` installs `pufbx`, which compiles ufbx from source
(a C compiler and several minutes); without it reading an FBX is an input error that says so.

One clip per animation stack (take), named like the other multi-animation formats: the file stem
for a single take, ``<stem>/<take>`` for several. Each take is baked by ufbx (``ufbx_bake_anim``
composes FBX's pre/post rotations, pivots and rotation orders into plain local translations and
quaternions) at the file's own frame rate.

The file's axis and unit settings are honoured: ufbx leaves transforms in file units and axes
(pufbx loads without conversion options and does not expose the scene settings), so this module
reads ``GlobalSettings`` from the file itself: ``UnitScaleFactor`` (centimetres per unit) gives
the metres per unit, ``UpAxis``/``UpAxisSign`` the up axis, ``CoordAxis``/``FrontAxis`` the
handedness, ``TimeMode``/``CustomFrameRate`` the frame rate. Skeletons are the bone (LimbNode)
nodes and the nodes above them (an armature's own node), so world positions are the file's.
"""

from __future__ import annotations

import importlib
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, UpAxis
from blendspace_pipeline.motion.quaternions import FloatArray

SUFFIXES = (".fbx",)

INSTALL_HINT = (
    "install the FBX extra: pip install 'blendspace-pipeline[fbx]' (it builds the ufbx loader from "
    "source: needs a C compiler and takes several minutes); or export the clip as glTF/GLB, USD or BVH"
)
_REEXPORT = "re-export it from your DCC (FBX 7.x), or export the clip as glTF/GLB, USD or BVH"
_BINARY_MAGIC = b"Kaydara FBX Binary  \x00"
# FbxTime::EMode (ufbx_time_mode) -> frames per second; 14 is "custom" (CustomFrameRate).
_TIME_MODES = {
    1: 120.0, 2: 100.0, 3: 60.0, 4: 50.0, 5: 48.0, 6: 30.0, 7: 30.0, 8: 30000 / 1001, 9: 30000 / 1001,
    10: 25.0, 11: 24.0, 12: 1000.0, 13: 24000 / 1001, 15: 96.0, 16: 72.0, 17: 60000 / 1001,
}  # fmt: skip
_DEFAULT_FPS = 30.0
_SETTINGS = ("UpAxis", "UpAxisSign", "FrontAxis", "FrontAxisSign", "CoordAxis", "CoordAxisSign",
             "UnitScaleFactor", "TimeMode", "CustomFrameRate")  # fmt: skip


@dataclass(frozen=True)
class Settings:
    """What the file's ``GlobalSettings`` say about its space and time."""

    meters_per_unit: float
    up_axis: UpAxis
    fps: float


def read(path: Path) -> list[Clip]:
    try:
        # By name: the optional binding may be absent (and is untyped for mypy where it is not).
        pufbx: Any = importlib.import_module("pufbx")
    except ImportError:
        raise ClipReadError(
            "reading FBX needs the optional pufbx package", path=path, hint=INSTALL_HINT
        ) from None
    settings = read_settings(path)
    try:
        scene = pufbx.load_fbx(str(path))
    except Exception as error:  # ufbx reports a corrupt or unsupported file as UFBXError
        raise ClipReadError(f"not a readable FBX file: {error}", path=path, hint=_REEXPORT) from None
    joints = _joints(scene)
    if not joints:
        raise ClipReadError(
            "the FBX file has no skeleton (no LimbNode bones)",
            path=path,
            hint="export the armature/skeleton with its animation",
        )
    stacks = list(scene.anim_stacks)
    if not stacks:
        raise ClipReadError(
            "the FBX file holds no animation take", path=path, hint="export with animation baked"
        )
    names = _clip_names(path, [stack.name for stack in stacks])
    return [
        _clip(pufbx, scene, stack, joints, name, path, settings)
        for stack, name in zip(stacks, names, strict=True)
    ]


# --- GlobalSettings ---------------------------------------------------------------------------


def read_settings(path: Path) -> Settings:
    """Units, up axis and frame rate from the file's ``GlobalSettings`` (binary or ASCII FBX)."""
    data = path.read_bytes()
    if data.startswith(_BINARY_MAGIC) and len(data) < 27:
        raise ClipReadError("the FBX file is truncated (no header)", path=path, hint=_REEXPORT)
    values = _binary_settings(path, data) if data.startswith(_BINARY_MAGIC) else _ascii_settings(data)
    up, up_sign = int(values.get("UpAxis", 1)), int(values.get("UpAxisSign", 1))
    if up not in (1, 2) or up_sign != 1:
        axis = "XYZ"[up] if up in (0, 1, 2) else str(up)
        raise ClipReadError(
            f"FBX up axis {'-' if up_sign < 0 else '+'}{axis} is not supported (only +Y or +Z up)",
            path=path,
            hint="re-export with Y up (Maya, Blender's default) or Z up (3ds Max, Unreal)",
        )
    axes = np.zeros((3, 3))
    for row, (axis, sign) in enumerate(
        (("CoordAxis", "CoordAxisSign"), ("UpAxis", "UpAxisSign"), ("FrontAxis", "FrontAxisSign"))
    ):
        index = int(values.get(axis, (0, 1, 2)[row]))
        axes[row, index if index in (0, 1, 2) else row] = float(np.sign(values.get(sign, 1)) or 1)
    if np.linalg.det(axes) < 0:
        # Right x Up = Front in every right-handed FBX (Maya, Blender, 3ds Max); turning signs and
        # left/right would flip silently in a left-handed one.
        raise ClipReadError(
            "the FBX file uses a left-handed axis system",
            path=path,
            hint="re-export with a right-handed system (Maya Y-up, or Z-up as 3ds Max writes)",
        )
    scale = float(values.get("UnitScaleFactor", 1.0))
    if not scale > 0:
        raise ClipReadError(f"FBX UnitScaleFactor {scale} is not positive", path=path, hint=_REEXPORT)
    mode = int(values.get("TimeMode", 0))
    custom = float(values.get("CustomFrameRate", 0.0))
    fps = _TIME_MODES.get(mode, custom if custom > 0 else _DEFAULT_FPS)
    return Settings(meters_per_unit=scale / 100.0, up_axis="z" if up == 2 else "y", fps=fps)


def _ascii_settings(data: bytes) -> dict[str, float]:
    text = data.decode("utf-8", errors="replace")
    start = text.find("GlobalSettings:")
    block = text[start:] if start >= 0 else ""
    values: dict[str, float] = {}
    for name in _SETTINGS:
        match = re.search(
            rf'P:\s*"{name}"\s*,\s*"[^"]*"\s*,\s*"[^"]*"\s*,\s*"[^"]*"\s*,\s*([-+0-9.eE]+)', block
        )
        if match:
            values[name] = float(match.group(1))
    return values


def _binary_settings(path: Path, data: bytes) -> dict[str, float]:
    """Walk the binary node records to GlobalSettings > Properties70 > P (FBX 7.x layout)."""
    version = struct.unpack_from("<I", data, 23)[0]
    wide = version >= 7500  # 64-bit record headers from FBX 7.5
    offset = 27
    try:
        while offset < len(data):
            record = _record(data, offset, wide)
            if record is None:
                break
            name, end, properties_end, _ = record
            if name == "GlobalSettings":
                return _properties70(data, properties_end, end, wide)
            offset = end
    except (struct.error, IndexError, ValueError, zlib.error):
        raise ClipReadError("the FBX file is truncated or corrupt", path=path, hint=_REEXPORT) from None
    return {}


def _record(data: bytes, offset: int, wide: bool) -> tuple[str, int, int, list[Any]] | None:
    """(name, end offset, where nested records start, properties) or None for the null record."""
    if wide:
        end, count, length = struct.unpack_from("<QQQ", data, offset)
        offset += 24
    else:
        end, count, length = struct.unpack_from("<III", data, offset)
        offset += 12
    name_length = data[offset]
    name = data[offset + 1 : offset + 1 + name_length].decode("ascii", errors="replace")
    offset += 1 + name_length
    if end == 0:
        return None
    properties, cursor = [], offset
    for _ in range(count):
        value, cursor = _property(data, cursor)
        properties.append(value)
    return name, int(end), offset + int(length), properties


def _property(data: bytes, offset: int) -> tuple[Any, int]:
    kind = chr(data[offset])
    offset += 1
    scalars = {"Y": "<h", "C": "<?", "I": "<i", "F": "<f", "D": "<d", "L": "<q"}
    if kind in scalars:
        value = struct.unpack_from(scalars[kind], data, offset)[0]
        return value, offset + struct.calcsize(scalars[kind])
    if kind in "SR":
        length = struct.unpack_from("<I", data, offset)[0]
        raw = data[offset + 4 : offset + 4 + length]
        return (raw.decode("utf-8", errors="replace") if kind == "S" else raw), offset + 4 + length
    if kind in "fdlib":
        _, _, compressed = struct.unpack_from("<III", data, offset)
        return None, offset + 12 + compressed  # arrays are never settings: skipped, not decoded
    raise ValueError(f"unknown FBX property type {kind!r}")


def _properties70(data: bytes, offset: int, end: int, wide: bool) -> dict[str, float]:
    values: dict[str, float] = {}
    while offset < end:
        record = _record(data, offset, wide)
        if record is None:
            break
        name, record_end, nested, _ = record
        if name == "Properties70":
            cursor = nested
            while cursor < record_end:
                entry = _record(data, cursor, wide)
                if entry is None:
                    break
                _, entry_end, _, fields = entry
                if len(fields) >= 5 and fields[0] in _SETTINGS and isinstance(fields[4], (int, float)):
                    values[str(fields[0])] = float(fields[4])
                cursor = entry_end
        offset = record_end
    return values


# --- skeleton and takes -----------------------------------------------------------------------


def _joints(scene: Any) -> list[Any]:
    """Bone nodes and every node above them (but the scene root), parents before children."""
    keep: dict[int, Any] = {}
    for node in scene.nodes:
        if node.bone is None:
            continue
        current = node
        while current is not None and not current.is_root and current.typed_id not in keep:
            keep[current.typed_id] = current
            current = current.parent
    return sorted(keep.values(), key=lambda n: (n.node_depth, n.typed_id))


def _clip_names(path: Path, takes: list[str]) -> list[str]:
    """The stem for one take, ``<stem>/<take>`` for several (the take's name after any ``|``)."""
    if len(takes) == 1:
        return [path.stem]
    names: list[str] = []
    for index, take in enumerate(takes):
        label = take.split("|")[-1] or f"take_{index}"
        candidate, counter = f"{path.stem}/{label}", 1
        while candidate in names:
            counter += 1
            candidate = f"{path.stem}/{label}_{counter}"
        names.append(candidate)
    return names


def _clip(
    pufbx: Any, scene: Any, stack: Any, joints: list[Any], name: str, path: Path, settings: Settings
) -> Clip:
    ids = [node.typed_id for node in joints]
    index = {node_id: i for i, node_id in enumerate(ids)}
    parents = tuple(index.get(n.parent.typed_id, -1) if n.parent is not None else -1 for n in joints)
    rest_t = np.array([n.local_transform.translation.as_array() for n in joints], dtype=np.float64)
    rest_r = np.array([n.local_transform.rotation.as_array() for n in joints], dtype=np.float64)
    begin, end = float(stack.time_begin), float(stack.time_end)
    frames = max(1, round((end - begin) * settings.fps) + 1)
    times = begin + np.arange(frames) / settings.fps
    rest_s = np.array([n.local_transform.scale.as_array() for n in joints], dtype=np.float64)
    translations = np.repeat(rest_t[None], frames, axis=0)
    rotations = np.repeat(rest_r[None], frames, axis=0)
    scales = np.repeat(rest_s[None], frames, axis=0)
    try:
        baked = pufbx.bake_anim(scene, stack.anim, resample_rate=settings.fps)
    except Exception as error:
        raise ClipReadError(
            f"cannot evaluate take {stack.name!r}: {error}", path=path, hint=_REEXPORT
        ) from None
    for node in baked.modified_nodes:
        joint = index.get(node.typed_id)
        if joint is None:
            continue
        translations[:, joint] = _sample(node.translation_keys, times, ("x", "y", "z"))
        rotations[:, joint] = _sample_rotation(node.rotation_keys, times)
        scales[:, joint] = _sample(node.scale_keys, times, ("x", "y", "z"))
    names = tuple(n.name for n in joints)
    rest_t = _unscaled(rest_t[None], rest_s[None], parents, names, path)[0]
    translations = _unscaled(translations, scales, parents, names, path)
    skeleton = Skeleton(names, parents, rest_t, quat.normalize(rest_r))
    return Clip(
        name=name,
        source=path,
        skeleton=skeleton,
        rotations=rotations,
        translations=translations,
        fps=settings.fps,
        meters_per_unit=settings.meters_per_unit,
        up_axis=settings.up_axis,
    )


def _unscaled(
    translations: FloatArray, scales: FloatArray, parents: tuple[int, ...], names: tuple[str, ...], path: Path
) -> FloatArray:
    """Translations with every ancestor's scale applied, so the clip needs no scale channel.

    An FBX armature node often scales its bones (Blender writes 100 on the armature with the
    bones in its own units): a joint's offset is then worth its parents' accumulated scale. A
    uniform scale commutes with rotation, so scaling each offset by that product keeps every
    world position. Non-uniform scale cannot be expressed this way and is refused.
    """
    spread = np.ptp(scales, axis=-1) / np.maximum(np.abs(scales).max(axis=-1), 1e-12)
    if (spread > 1e-3).any():
        joint = int(np.argwhere(spread > 1e-3)[0][1])
        raise ClipReadError(
            f"joint {names[joint]!r} is scaled non-uniformly",
            path=path,
            hint="apply (freeze) the scale in your DCC before exporting, or scale uniformly",
        )
    uniform = scales.mean(axis=-1)
    world = np.ones_like(uniform)  # accumulated scale of each joint (itself included)
    result = translations.copy()
    for joint, parent in enumerate(parents):
        if parent >= 0:
            result[:, joint] *= world[:, parent, None]
            world[:, joint] = world[:, parent] * uniform[:, joint]
        else:
            world[:, joint] = uniform[:, joint]
    return result


def _sample(keys: Any, times: FloatArray, fields: tuple[str, ...]) -> FloatArray:
    """Linear keys (ufbx bakes to linear) evaluated at ``times``; held outside the keyed range."""
    values = keys["value"]
    return np.stack([np.interp(times, keys["time"], values[f]) for f in fields], axis=-1)


def _sample_rotation(keys: Any, times: FloatArray) -> FloatArray:
    values = np.stack([keys["value"][f] for f in ("x", "y", "z", "w")], axis=-1)
    # Keys into one hemisphere first, so that component-wise interpolation takes the short way.
    for i in range(1, len(values)):
        if np.dot(values[i], values[i - 1]) < 0:
            values[i] = -values[i]
    sampled = np.stack([np.interp(times, keys["time"], values[:, c]) for c in range(4)], axis=-1)
    return quat.normalize(sampled)
