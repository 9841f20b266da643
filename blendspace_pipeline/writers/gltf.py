"""A clip as glTF 2.0 (.glb or .gltf): a joint node hierarchy, a skin and one animation.

Written mainly as an oracle for the glTF reader and for handing clips to engines that import
glTF. glTF is metres and +Y up by definition, so the clip is converted on the way out: lengths
scaled by its metres-per-unit, and a Z-up clip turned -90 degrees about X at its root joints.
Every joint gets LINEAR translation and rotation channels sharing one key-time accessor (frame
``i`` at ``i / fps`` seconds). Joints hang under one non-joint node named after the clip, so a
skeleton with several roots (or none, for a track-only clip) still has a common skin root.

A `.gltf` embeds its buffer as a base64 data URI so the file is self-contained; a `.glb` carries
it in the binary chunk. Bytes are deterministic (no timestamps, float32 values, fixed key order)
and the file is replaced atomically.
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops.up_axis import turn_roots_y_up
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.provenance import GLTF_KEY, Provenance
from blendspace_pipeline.report.atomic import atomic_path

SUFFIXES = (".glb", ".gltf")

_FLOAT = 5126
_GENERATOR = "blendspace-pipeline"


def write_gltf_clip(
    clip: Clip,
    path: Path,
    *,
    meters_per_unit: float | None = None,
    up_axis: str | None = None,
    provenance: Provenance | None = None,
) -> None:
    """Write ``clip`` to ``path`` atomically; ``meters_per_unit``/``up_axis`` override the clip's.

    ``provenance`` (a generated clip's record) goes into the animation's ``extras``.

    Raises `ValueError` when the units or up axis are unknown: glTF has no field for them, so a
    wrong guess would silently scale or tip the character over.
    """
    units = meters_per_unit if meters_per_unit is not None else clip.meters_per_unit
    up = (up_axis or clip.up_axis or "").lower()
    if units is None or not units > 0:
        raise ValueError(f"clip {clip.name!r}: metres per unit unknown; pass meters_per_unit")
    if up not in ("y", "z"):
        raise ValueError(f"clip {clip.name!r}: up axis unknown; pass up_axis='y' or 'z'")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{path}: a glTF clip is written as .glb or .gltf")
    rest_t, rest_r, translations, rotations = _metres_y_up(clip, float(units), up)
    document, blob = _document(clip, rest_t, rest_r, translations, rotations)
    if provenance is not None:
        document["animations"][0]["extras"] = {GLTF_KEY: provenance.as_dict()}
    if suffix == ".glb":
        data = _glb(document, blob)
    else:
        document["buffers"][0]["uri"] = (
            "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        )
        data = (json.dumps(document, indent=1) + "\n").encode()
    _write_atomically(path, data)


def _metres_y_up(clip: Clip, units: float, up: str) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Rest and animated local transforms in metres, +Y up (roots turned when Z is up)."""
    skeleton = clip.skeleton
    rest_t = skeleton.rest_translations * units
    rest_r = quat.normalize(skeleton.rest_rotations.copy())
    translations = clip.translations * units
    rotations = quat.normalize(clip.rotations.copy())
    if up == "z":
        turn_roots_y_up(skeleton, rest_t, rest_r, translations, rotations)
    return rest_t, rest_r, translations, _continuous(rotations)


def _continuous(rotations: FloatArray) -> FloatArray:
    """Flip keys into the hemisphere of the previous key, so any slerp takes the short way."""
    if len(rotations) < 2:
        return rotations
    dots = np.sum(rotations[1:] * rotations[:-1], axis=-1)
    signs = np.concatenate(
        [np.ones((1, rotations.shape[1])), np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)]
    )
    return np.asarray(rotations * signs[..., None], dtype=np.float64)


class _Buffer:
    """One binary buffer, one bufferView and accessor per array."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.size = 0
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def add(self, values: FloatArray, kind: str, *, bounds: bool = False) -> int:
        data = np.ascontiguousarray(values, dtype="<f4").tobytes()
        self.views.append({"buffer": 0, "byteOffset": self.size, "byteLength": len(data)})
        self.chunks.append(data)
        self.size += len(data)  # float32 data keeps every offset 4-byte aligned
        accessor: dict[str, Any] = {
            "bufferView": len(self.views) - 1,
            "componentType": _FLOAT,
            "count": int(values.shape[0]),
            "type": kind,
        }
        if bounds:  # required on animation inputs
            as_float = values.astype(np.float32).astype(np.float64)
            accessor["min"] = [float(v) for v in np.atleast_1d(as_float.min(axis=0))]
            accessor["max"] = [float(v) for v in np.atleast_1d(as_float.max(axis=0))]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _document(
    clip: Clip, rest_t: FloatArray, rest_r: FloatArray, translations: FloatArray, rotations: FloatArray
) -> tuple[dict[str, Any], bytes]:
    skeleton = clip.skeleton
    count = skeleton.joint_count
    buffer = _Buffer()
    times = buffer.add(np.arange(clip.frame_count, dtype=np.float64) / clip.fps, "SCALAR", bounds=True)
    samplers: list[dict[str, Any]] = []
    channels: list[dict[str, Any]] = []
    for joint in range(count):
        for target, values, kind in (
            ("translation", translations[:, joint], "VEC3"),
            ("rotation", rotations[:, joint], "VEC4"),
        ):
            output = buffer.add(values, kind)
            channels.append({"sampler": len(samplers), "target": {"node": joint + 1, "path": target}})
            samplers.append({"input": times, "output": output, "interpolation": "LINEAR"})
    nodes: list[dict[str, Any]] = [
        {
            "name": clip.name,
            "children": [
                j + 1 for j, p in enumerate(skeleton.parents) if p < 0 or not skeleton.has_hierarchy
            ],
        }
    ]
    for joint in range(count):
        node: dict[str, Any] = {
            "name": skeleton.names[joint],
            "translation": [float(v) for v in rest_t[joint]],
            "rotation": [float(v) for v in rest_r[joint]],
        }
        children = [c + 1 for c, p in enumerate(skeleton.parents) if p == joint and skeleton.has_hierarchy]
        if children:
            node["children"] = children
        nodes.append(node)
    document: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": _GENERATOR},
        "scene": 0,
        "scenes": [{"name": clip.name, "nodes": [0]}],
        "nodes": nodes,
        "skins": [{"name": clip.name, "skeleton": 0, "joints": list(range(1, count + 1))}],
        "animations": [{"name": clip.name, "samplers": samplers, "channels": channels}],
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": buffer.size}],
    }
    return document, b"".join(buffer.chunks)


def _glb(document: dict[str, Any], blob: bytes) -> bytes:
    """Header, JSON chunk padded with spaces, BIN chunk padded with zeros (glTF 2.0, 4.4)."""
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return b"".join(
        [
            struct.pack("<4sII", b"glTF", 2, total),
            struct.pack("<II", len(text), 0x4E4F534A),
            text,
            struct.pack("<II", len(blob), 0x004E4942),
            blob,
        ]
    )


def _write_atomically(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=path.suffix) as temporary:
        temporary.write_bytes(data)
