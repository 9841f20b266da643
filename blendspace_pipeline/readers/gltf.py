"""glTF 2.0 clips (.gltf, .glb): one clip per animation that drives the joints of a skin.

The file is parsed here with `json` and `numpy.frombuffer`-style views rather than pygltflib:
the container (GLB header, JSON and BIN chunks, data: URIs, external .bin files) is a few dozen
lines, and owning it means every defect of a broken file becomes a `ClipReadError` naming the
JSON pointer (``accessors[4]``, ``animations[2].channels[0]``) instead of a library exception.

glTF keys are sampled on a constant-rate grid: the rate is the keys' own rate snapped to a common
film/game rate (24, 25, 30, 60, ...). LINEAR and STEP samplers are evaluated exactly as the spec
says (lerp, shortest-arc slerp, hold); CUBICSPLINE is refused because tangents would have to be
evaluated and no locomotion exporter needs them. The skeleton is the skin's joints (plus any
non-joint nodes between joints), parents first. Nodes above the root joints (an "Armature" node
carrying an up-axis rotation or a unit scale) are folded into the root joints so forward
kinematics puts the joints where a glTF viewer does. Uniform node scale is folded into the child
offsets; clips carry no scale. glTF is metres and +Y up by definition.
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote, unquote_to_bytes

import numpy as np
from scipy.spatial.transform import Rotation

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, topological_order
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.limits import allowed_roots, confined, current_roots, read_regular_file

SUFFIXES = (".gltf", ".glb")

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942
_COMPONENTS: dict[int, type[np.generic]] = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
# Normalized integers map to [-1, 1] / [0, 1] with these divisors (glTF 2.0, 3.11).
_NORMALIZED = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_CHANNEL_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
# Key rates snap to these when the keys are one of them (or a whole fraction of one).
_COMMON_RATES = (24.0, 25.0, 30.0, 48.0, 50.0, 60.0, 100.0, 120.0, 24000 / 1001, 30000 / 1001, 60000 / 1001)
_MIN_RATE = 24.0
_ROUNDING = 2e-3  # seconds two steps of one rate may differ by when key times are written to 3 decimals
# Keys further apart than this are poses, not a sampled rate (a still's two keys 8.3 s apart fit
# some common rate within a tenth of a frame by chance): sampled at `_POSE_RATE`.
_POSE_INTERVAL = 0.5
_POSE_RATE = 30.0
_MAX_RATE = 240.0
_MAX_FRAMES = 1_000_000
_KEY_TOLERANCE = 1e-5  # seconds; float32 times are off by ~1e-7 s per second
_REEXPORT = "re-export the file as glTF 2.0 (.glb) with the skin and its animations"


def read(path: Path) -> list[Clip]:
    """Every animation in ``path`` that drives a skin (or, without skins, a node hierarchy)."""
    document = _Document.load(path)
    animations = document.list_of(document.root, "animations", "")
    if not animations:
        raise ClipReadError(
            "the glTF file holds no animations", path=path, hint="export with animations (actions) enabled"
        )
    skins = [document.skin_joints(i) for i in range(len(document.list_of(document.root, "skins", "")))]
    selected: list[tuple[int, list[int]]] = []
    for index in range(len(animations)):
        channels = document.channels(index)
        joints = _joints_for(document, channels, skins)
        if joints:
            selected.append((index, joints))
    if not selected:
        raise ClipReadError(
            "no animation drives the joints of a skin",
            path=path,
            hint="export the armature's actions together with the skinned mesh; animations of other "
            "objects are not locomotion clips",
        )
    names = _clip_names(path, [(i, document.item("animations", i, "").get("name")) for i, _ in selected])
    return [
        _read_clip(document, index, joints, name)
        for (index, joints), name in zip(selected, names, strict=True)
    ]


def buffer_files(path: Path, project: Path | None = None) -> list[Path]:
    """The external buffer files `read` opens for ``path`` (a `.gltf`'s, or a `.glb`'s that name
    files), confined as `read` confines them; [] when the file is no readable glTF (reading it
    says why). Remote and `data:` URIs are no files."""
    try:
        data = read_regular_file(path, what="glTF file")
        root = _parse_glb(path, data)[0] if data[:4] == _GLB_MAGIC else _parse_json(path, data, 0)
    except ClipReadError:
        return []
    buffers = root.get("buffers")
    roots = allowed_roots(path, project)
    found = []
    for buffer in buffers if isinstance(buffers, list) else []:
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if not isinstance(uri, str) or not uri or uri.startswith("data:") or "://" in uri:
            continue
        try:
            found.append(confined(path, unquote(uri), roots, what="glTF buffer"))
        except ClipReadError:
            continue
    return found


def _error(path: Path, message: str, hint: str = _REEXPORT) -> ClipReadError:
    return ClipReadError(message, path=path, hint=hint)


# --- container --------------------------------------------------------------------------------


@dataclass
class _Document:
    """The JSON of a glTF asset and lazy access to its binary buffers."""

    path: Path
    root: dict[str, Any]
    glb_bin: bytes | None
    buffers: dict[int, bytes] = field(default_factory=dict)
    parent: dict[int, int] = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path) -> _Document:
        data = read_regular_file(path, what="glTF file")
        if data[:4] == _GLB_MAGIC:
            root, glb_bin = _parse_glb(path, data)
        elif path.suffix.lower() == ".glb":
            raise _error(path, "not a GLB file (the first 4 bytes are not 'glTF')")
        else:
            root, glb_bin = _parse_json(path, data, 0), None
        document = cls(path, root, glb_bin)
        document.check_version()
        document.parent = document.parent_map()
        return document

    def check_version(self) -> None:
        asset = self.root.get("asset")
        version = asset.get("version") if isinstance(asset, dict) else None
        if not isinstance(version, str) or not version.startswith("2."):
            raise _error(
                self.path,
                f"glTF version {_show(version)} is not supported (asset.version must be 2.x)",
                "convert the file to glTF 2.0 (e.g. import and re-export in Blender)",
            )

    # JSON access that turns every structural defect into a ClipReadError with a pointer.

    def list_of(self, obj: dict[str, Any], key: str, where: str) -> list[Any]:
        value = obj.get(key, [])
        if not isinstance(value, list):
            raise _error(self.path, f"{_join(where, key)} is not an array")
        return value

    def item(self, key: str, index: Any, where: str) -> dict[str, Any]:
        items = self.list_of(self.root, key, "")
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise _error(self.path, f"{where} refers to {key}[{index}], which does not exist")
        value = items[index]
        if not isinstance(value, dict):
            raise _error(self.path, f"{key}[{index}] is not an object")
        return value

    def integer(self, obj: dict[str, Any], key: str, where: str, default: int | None = None) -> int:
        value = obj.get(key, default)
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            state = "missing" if key not in obj else f"{_show(value)}, not a non-negative integer"
            raise _error(self.path, f"{_join(where, key)} is {state}")
        return value

    def numbers(self, obj: dict[str, Any], key: str, where: str, default: list[float]) -> FloatArray:
        value = obj.get(key, default)
        try:
            array = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):  # OverflowError: an integer beyond float range
            array = np.empty(0)
        if array.shape != (len(default),) or not np.isfinite(array).all():
            raise _error(
                self.path, f"{_join(where, key)} must be {len(default)} finite numbers, not {_show(value)}"
            )
        return array

    # Hierarchy.

    def parent_map(self) -> dict[int, int]:
        nodes = self.list_of(self.root, "nodes", "")
        parent: dict[int, int] = {}
        for index in range(len(nodes)):
            data = self.item("nodes", index, f"nodes[{index}]")
            for position, child in enumerate(self.list_of(data, "children", f"nodes[{index}]")):
                where = f"nodes[{index}].children[{position}]"
                self.item("nodes", child, where)
                if child in parent or child == index:
                    raise _error(self.path, f"{where}: node {child} has more than one parent")
                parent[child] = index
        for start in parent:  # a cycle would make every ancestor walk loop forever
            seen, node = {start}, start
            while node in parent:
                node = parent[node]
                if node in seen:
                    raise _error(self.path, f"nodes[{start}]: the node hierarchy has a cycle")
                seen.add(node)
        return parent

    def ancestors(self, node: int) -> list[int]:
        """Parent, grandparent, ... up to a scene root."""
        chain = []
        while node in self.parent:
            node = self.parent[node]
            chain.append(node)
        return chain

    def node_name(self, node: int) -> str:
        name = self.item("nodes", node, "").get("name")
        return name if isinstance(name, str) and name else f"node_{node}"

    def rest_trs(self, node: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Translation, rotation (xyzw), scale of a node's local transform."""
        where = f"nodes[{node}]"
        data = self.item("nodes", node, where)
        if "matrix" in data:
            values = self.numbers(data, "matrix", where, [0.0] * 16)
            return _decompose(values.reshape(4, 4).T)  # glTF matrices are column-major
        translation = self.numbers(data, "translation", where, [0.0, 0.0, 0.0])
        rotation = self.numbers(data, "rotation", where, [0.0, 0.0, 0.0, 1.0])
        scale = self.numbers(data, "scale", where, [1.0, 1.0, 1.0])
        return translation, quat.normalize(rotation), scale

    def skin_joints(self, index: int) -> list[int]:
        where = f"skins[{index}]"
        joints = self.list_of(self.item("skins", index, where), "joints", where)
        for position, joint in enumerate(joints):
            self.item("nodes", joint, f"{where}.joints[{position}]")
        if len(set(joints)) != len(joints):
            raise _error(self.path, f"{where}.joints lists a node twice")
        return list(joints)

    # Buffers and accessors.

    def buffer(self, index: int, where: str) -> bytes:
        if index in self.buffers:
            return self.buffers[index]
        pointer = f"buffers[{index}]"
        buffer = self.item("buffers", index, where)
        length = self.integer(buffer, "byteLength", pointer)
        uri = buffer.get("uri")
        if uri is None:
            if index != 0 or self.glb_bin is None:
                raise _error(self.path, f"{pointer} has no uri and the file has no GLB binary chunk")
            data = self.glb_bin
        elif not isinstance(uri, str):
            raise _error(self.path, f"{pointer}.uri is not a string")
        elif uri.startswith("data:"):
            data = _data_uri(self.path, uri, pointer)
        else:
            data = self._external(uri, pointer)
        if len(data) < length:
            raise _error(
                self.path, f"{pointer} is truncated: {len(data)} bytes of the declared {length}", _TRUNCATED
            )
        self.buffers[index] = data
        return data

    def _external(self, uri: str, pointer: str) -> bytes:
        if "://" in uri:
            raise _error(
                self.path,
                f"{pointer} refers to a remote file ({uri})",
                "download the buffer beside the .gltf",
            )
        file = confined(self.path, unquote(uri), current_roots(self.path), what=f"{pointer} uri")
        try:
            return read_regular_file(file, what=f"external buffer {uri!r}")
        except ClipReadError as error:
            raise _error(
                self.path,
                f"{pointer}: {error.message}",
                "keep the .bin file beside the .gltf, or export a single .glb",
            ) from None

    def accessor(self, index: Any, where: str, widths: tuple[int, ...]) -> FloatArray:
        """Accessor values as float64 (count, width), normalized integers mapped to [-1, 1]."""
        pointer = f"accessors[{index}]"
        accessor = self.item("accessors", index, where)
        component = accessor.get("componentType")
        if not isinstance(component, int) or component not in _COMPONENTS:  # a list is unhashable
            raise _error(
                self.path, f"{pointer}.componentType {_show(component)} is not a glTF component type"
            )
        width = _WIDTHS.get(str(accessor.get("type")), 0)
        if width not in widths:
            raise _error(self.path, f"{pointer} has type {_show(accessor.get('type'))}, unusable for {where}")
        count = self.integer(accessor, "count", pointer)
        dtype = np.dtype(_COMPONENTS[component]).newbyteorder("<")
        if "bufferView" in accessor:
            offset = self.integer(accessor, "byteOffset", pointer, 0)
            raw = self._view(accessor["bufferView"], offset, dtype, count, width, pointer)
        else:
            raw = np.zeros((count, width), dtype=dtype)
        values: FloatArray = raw.astype(np.float64)
        sparse = accessor.get("sparse")
        if sparse is not None:
            self._apply_sparse(sparse, values, dtype, width, pointer)
        if accessor.get("normalized") is True and component in _NORMALIZED:
            values = np.maximum(values / _NORMALIZED[component], -1.0)
        return values

    def _view(
        self, view_index: Any, offset: int, dtype: np.dtype[Any], count: int, width: int, pointer: str
    ) -> Any:
        view = self.item("bufferViews", view_index, pointer)
        where = f"bufferViews[{view_index}]"
        data = self.buffer(self.integer(view, "buffer", where), where)
        start = self.integer(view, "byteOffset", where, 0)
        length = self.integer(view, "byteLength", where)
        if start + length > len(data):
            raise _error(self.path, f"{where} runs past the end of its buffer", _TRUNCATED)
        element = dtype.itemsize * width
        stride = self.integer(view, "byteStride", where, element) or element
        if stride < element:
            raise _error(self.path, f"{where}.byteStride {stride} is smaller than one element ({element})")
        if count == 0:
            return np.zeros((0, width), dtype=dtype)
        if offset + stride * (count - 1) + element > length:
            raise _error(self.path, f"{pointer} reads past the end of {where}", _TRUNCATED)
        return np.ndarray(
            shape=(count, width),
            dtype=dtype,
            buffer=data,
            offset=start + offset,
            strides=(stride, dtype.itemsize),
        )

    def _apply_sparse(
        self, sparse: Any, values: FloatArray, dtype: np.dtype[Any], width: int, pointer: str
    ) -> None:
        where = f"{pointer}.sparse"
        if (
            not isinstance(sparse, dict)
            or not isinstance(sparse.get("indices"), dict)
            or not isinstance(sparse.get("values"), dict)
        ):
            raise _error(self.path, f"{where} needs count, indices and values")
        count = self.integer(sparse, "count", where)
        indices, replacements = sparse["indices"], sparse["values"]
        index_type = indices.get("componentType")
        if index_type not in (5121, 5123, 5125):
            raise _error(
                self.path, f"{where}.indices.componentType {_show(index_type)} is not an unsigned integer"
            )
        index_dtype = np.dtype(_COMPONENTS[index_type]).newbyteorder("<")
        rows = self._view(
            indices.get("bufferView"),
            self.integer(indices, "byteOffset", f"{where}.indices", 0),
            index_dtype,
            count,
            1,
            f"{where}.indices",
        )[:, 0].astype(np.int64)
        if count and rows.max() >= len(values):
            raise _error(self.path, f"{where}.indices point past the accessor's {len(values)} elements")
        new = self._view(
            replacements.get("bufferView"),
            self.integer(replacements, "byteOffset", f"{where}.values", 0),
            dtype,
            count,
            width,
            f"{where}.values",
        )
        values[rows] = new.astype(np.float64)

    # Animations.

    def channels(self, index: int) -> list[_Channel]:
        where = f"animations[{index}]"
        animation = self.item("animations", index, where)
        samplers = self.list_of(animation, "samplers", where)
        channels = []
        for position, channel in enumerate(self.list_of(animation, "channels", where)):
            pointer = f"{where}.channels[{position}]"
            if not isinstance(channel, dict) or not isinstance(channel.get("target"), dict):
                raise _error(self.path, f"{pointer} has no target")
            target = channel["target"]
            sampler = self.integer(channel, "sampler", pointer)
            if sampler >= len(samplers) or not isinstance(samplers[sampler], dict):
                raise _error(self.path, f"{pointer} refers to sampler {sampler}, which does not exist")
            node = target.get("node")
            if node is not None:
                self.item("nodes", node, f"{pointer}.target.node")
            channels.append(
                _Channel(index, position, node, str(target.get("path")), sampler, samplers[sampler])
            )
        return channels

    def keys(self, channel: _Channel) -> tuple[FloatArray, FloatArray, bool]:
        """Key times, key values and whether the sampler steps (STEP) instead of interpolating."""
        where, used_by = channel.sampler_pointer, channel.pointer
        interpolation = channel.sampler_json.get("interpolation", "LINEAR")
        if interpolation == "CUBICSPLINE":
            raise _error(
                self.path,
                f"{where} (used by {used_by}) uses CUBICSPLINE interpolation, which is not read",
                "re-export with linear sampling (Blender glTF export: Animation > Sampling "
                "'Always Sample Animations', interpolation Linear)",
            )
        if interpolation not in ("LINEAR", "STEP"):
            raise _error(
                self.path, f"{where}.interpolation {_show(interpolation)} is not a glTF interpolation"
            )
        times = self.accessor(channel.sampler_json.get("input"), f"{where}.input", (1,))[:, 0]
        width = _CHANNEL_WIDTHS[channel.path]
        values = self.accessor(channel.sampler_json.get("output"), f"{where}.output", (width,))
        if len(times) == 0 or len(values) != len(times):
            raise _error(
                self.path, f"{where} has {len(times)} key times and {len(values)} values (used by {used_by})"
            )
        if not np.isfinite(times).all() or np.any(np.diff(times) < 0):
            raise _error(
                self.path, f"{where}.input: key times are not finite and increasing (used by {used_by})"
            )
        if not np.isfinite(values).all():
            raise _error(self.path, f"{where}.output holds NaN or infinite values (used by {used_by})")
        return times, values, interpolation == "STEP"


@dataclass(frozen=True)
class _Channel:
    animation: int
    position: int
    node: int | None
    path: str  # translation | rotation | scale | weights
    sampler: int
    sampler_json: dict[str, Any]

    @property
    def pointer(self) -> str:
        return f"animations[{self.animation}].channels[{self.position}]"

    @property
    def sampler_pointer(self) -> str:
        return f"animations[{self.animation}].samplers[{self.sampler}]"


_TRUNCATED = "the file is truncated or corrupt; re-export or download it again"


def _show(value: object, limit: int = 60) -> str:
    """A short repr for messages: a fuzzed file may hold a 5,000-digit number or a huge list."""
    try:
        text = repr(value)
    except ValueError:  # int too large to print
        text = "a huge number"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _parse_glb(path: Path, data: bytes) -> tuple[dict[str, Any], bytes | None]:
    """Header (magic, version, length), then chunks of (length, type, payload)."""
    if len(data) < 12:
        raise _error(path, "the GLB header is truncated", _TRUNCATED)
    _, version, length = struct.unpack_from("<4sII", data)
    if version != 2:
        raise _error(path, f"GLB container version {version} is not supported (2 expected)")
    if length > len(data):
        raise _error(
            path, f"the GLB file is truncated: its header says {length} bytes, it has {len(data)}", _TRUNCATED
        )
    offset, json_chunk, bin_chunk = 12, None, None
    while offset + 8 <= length:
        chunk_length, chunk_type = struct.unpack_from("<II", data, offset)
        start, end = offset + 8, offset + 8 + chunk_length
        if end > length:
            raise _error(path, f"the GLB chunk at byte {offset} runs past the end of the file", _TRUNCATED)
        if chunk_type == _CHUNK_JSON and json_chunk is None:
            json_chunk = (start, data[start:end])
        elif chunk_type == _CHUNK_BIN and bin_chunk is None and json_chunk is not None:
            bin_chunk = data[start:end]
        offset = end
    if json_chunk is None:
        raise _error(path, "the GLB file has no JSON chunk", _TRUNCATED)
    return _parse_json(path, json_chunk[1], json_chunk[0]), bin_chunk


def _parse_json(path: Path, data: bytes, offset: int) -> dict[str, Any]:
    where = f" (in the GLB JSON chunk at byte {offset})" if offset else ""
    try:
        root = json.loads(data.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise _error(path, f"not a glTF file: the JSON is not UTF-8 text{where}", _TRUNCATED) from None
    except RecursionError:
        raise _error(path, f"the glTF JSON nests too deeply to be a glTF file{where}", _TRUNCATED) from None
    except json.JSONDecodeError as error:
        line, column = (error.lineno, error.colno) if not offset else (None, None)
        raise ClipReadError(
            f"not valid glTF JSON: {error.msg}{where}", path=path, line=line, column=column, hint=_TRUNCATED
        ) from None
    if not isinstance(root, dict):
        raise _error(path, "not a glTF file: the JSON is not an object")
    return root


def _data_uri(path: Path, uri: str, pointer: str) -> bytes:
    header, _, payload = uri.partition(",")
    if header.endswith(";base64"):
        try:
            return base64.b64decode(payload, validate=True)
        except (binascii.Error, ValueError):
            raise _error(path, f"{pointer}: the base64 data URI is corrupt", _TRUNCATED) from None
    return unquote_to_bytes(payload)


def _decompose(matrix: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """TRS of a column-vector 4x4 matrix (a mirroring matrix keeps its sign in the X scale)."""
    basis = matrix[:3, :3]
    scale = np.linalg.norm(basis, axis=0)
    if not np.all(scale > 1e-12):  # a collapsed node: no rotation can be read from it
        return matrix[:3, 3].copy(), quat.IDENTITY.copy(), scale
    if np.linalg.det(basis) < 0:
        scale[0] = -scale[0]
    rotation = Rotation.from_matrix(basis / scale).as_quat()
    return matrix[:3, 3].copy(), np.asarray(rotation, dtype=np.float64), scale


# --- skeleton and sampling ----------------------------------------------------------------------


def _joints_for(document: _Document, channels: list[_Channel], skins: list[list[int]]) -> list[int]:
    """The joint nodes the animation drives: the skin it animates most, or (no skins at all)
    every animated node and its ancestors."""
    targets = {c.node for c in channels if c.node is not None and c.path in _CHANNEL_WIDTHS}
    if skins:
        overlap = [len(targets & set(joints)) for joints in skins]
        best = int(np.argmax(overlap))
        return skins[best] if overlap[best] else []
    nodes = set()
    for node in targets:
        nodes.add(node)
        nodes.update(document.ancestors(node))
    return sorted(nodes)


@dataclass(frozen=True)
class _Layout:
    nodes: list[int]  # joint nodes, parents first
    parents: tuple[int, ...]
    above: dict[int, list[int]]  # root joint -> nodes above it, top first (folded into it)


def _layout(document: _Document, skin: list[int]) -> _Layout:
    """Skin joints plus any non-joint node between two joints, ordered parents first."""
    joints = set(skin)
    extra: list[int] = []
    for joint in skin:
        chain = document.ancestors(joint)
        hit = next((i for i, node in enumerate(chain) if node in joints), None)
        if hit is not None:
            extra += [node for node in chain[:hit] if node not in joints and node not in extra]
    nodes = list(skin) + extra
    position = {node: i for i, node in enumerate(nodes)}
    parents = [position.get(document.parent.get(node, -1), -1) for node in nodes]
    order = topological_order(parents)
    ordered = [nodes[i] for i in order]
    new_index = {old: new for new, old in enumerate(order)}
    new_parents = tuple(new_index[parents[old]] if parents[old] >= 0 else -1 for old in order)
    above = {
        node: list(reversed(document.ancestors(node)))
        for node, parent in zip(ordered, new_parents, strict=True)
        if parent < 0
    }
    return _Layout(ordered, new_parents, above)


def _joint_names(document: _Document, nodes: list[int]) -> tuple[str, ...]:
    names = [document.node_name(node) for node in nodes]
    return tuple(
        name if names.count(name) == 1 else f"{name}_{node}" for name, node in zip(names, nodes, strict=True)
    )


def _key_interval(times: FloatArray) -> float:
    """The time between a channel's keys: for keys on a regular step, their span over their count
    (key times written to 3 or 4 decimals are each off by up to half the last digit, which no
    longer tells 24 fps from 23.976, nor 60 from 58.8); else the median step."""
    steps = np.diff(times)
    positive = steps[steps > 0]
    # Regular: every step the same but for rounding to 3 decimals (hand keys on frames 0, 2, 4, 7
    # are no regular step: their span over their count read 24 fps keys at 120).
    if len(positive) == len(steps) and positive.max() - positive.min() <= _ROUNDING:
        return float(times[-1] - times[0]) / len(steps)
    return float(np.median(steps))


def _frame_rate(intervals: list[float], notes: list[str]) -> float:
    """The keys' rate snapped to a common rate (15 fps keys sample at 30)."""
    if not intervals:
        return 30.0
    interval = min(intervals)
    rate = 1.0 / interval
    if interval > _POSE_INTERVAL:
        notes.append(
            f"keys every {interval:.4g} s at least (poses, no frame rate): sampled at {_POSE_RATE:g} fps"
        )
        return _POSE_RATE

    def frames_off(common: float) -> float | None:
        """How far the interval is from a whole number of ``common``'s frames, when within 1 %
        of it and a tenth of a frame at most, else None."""
        multiple = common / rate
        whole = round(multiple)
        off = abs(multiple - whole)
        return off if whole >= 1 and off < 0.01 * min(whole, 10) else None

    # The rate that fits best (the first listed on a tie: 24 for keys every 0.5 s, 12 frames at
    # 24 or 15 at 30), NTSC rates among them (a 29.97 fps scene's still read at 120).
    fits = [
        (off, index) for index, common in enumerate(_COMMON_RATES) if (off := frames_off(common)) is not None
    ]
    if fits:
        chosen = _COMMON_RATES[min(fits)[1]]
    else:
        # Irregular keys: their own rate, but never so coarse that interpolated arcs are lost.
        chosen = 30.0 if rate < _MIN_RATE else min(round(rate, 3), _MAX_RATE)
    notes.append(f"keys every {interval * 1000:.4g} ms: sampled at {chosen:g} fps")
    return chosen


def sample_keys(
    times: FloatArray, values: FloatArray, at: FloatArray, step: bool, rotation: bool
) -> FloatArray:
    """Keys evaluated at times ``at`` as glTF (and Godot) do: the first/last key holds outside
    the keys; ``step`` holds each key until the next; else lerp, or shortest-arc slerp for
    ``rotation`` (unit quaternions). ``times`` must be non-decreasing."""
    last = len(times) - 1
    # Key times are float32: a key a rounding error after a frame still counts as on it.
    index = np.clip(np.searchsorted(times, at + _KEY_TOLERANCE, side="right") - 1, 0, last)
    if step or last == 0:
        return np.asarray(values[index], dtype=np.float64)
    following = np.minimum(index + 1, last)
    span = times[following] - times[index]
    fraction = np.clip((at - times[index]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    fraction = np.where(span > 0, fraction, 0.0)
    if rotation:
        return quat.slerp(values[index], values[following], fraction)
    return np.asarray(
        values[index] + (values[following] - values[index]) * fraction[:, None], dtype=np.float64
    )


@dataclass
class _Tracks:
    """Per-frame local TRS of every node that matters, rest values where not animated."""

    translation: dict[int, FloatArray]
    rotation: dict[int, FloatArray]
    scale: dict[int, FloatArray]  # (F,) uniform scale


def _read_clip(document: _Document, index: int, skin: list[int], name: str) -> Clip:
    path = document.path
    notes: list[str] = []
    layout = _layout(document, skin)
    involved = set(layout.nodes) | {node for chain in layout.above.values() for node in chain}
    channels = [c for c in document.channels(index) if c.node in involved and c.path in _CHANNEL_WIDTHS]
    _note_ignored(document, index, involved, notes)
    keyed = [(channel, *document.keys(channel)) for channel in channels]
    start = min((float(times[0]) for _, times, _, _ in keyed), default=0.0)
    end = max((float(times[-1]) for _, times, _, _ in keyed), default=0.0)
    intervals = [_key_interval(t) for _, t, _, _ in keyed if len(t) > 1 and np.diff(t).max() > 0]
    fps = _frame_rate([i for i in intervals if i > 0], notes)
    count = int(np.floor((end - start) * fps + 0.5)) + 1
    if count > _MAX_FRAMES:
        raise _error(path, f"animations[{index}] spans {end - start:g} s, too long for a clip")
    if start > 0:
        notes.append(f"the animation starts at {start:g} s: frame 0 is that time")
    at = start + np.arange(count) / fps
    tracks = _rest_tracks(document, involved, count)
    scaled = False
    for channel, times, values, step in keyed:
        assert channel.node is not None
        if channel.path == "rotation":
            tracks.rotation[channel.node] = sample_keys(times, quat.normalize(values), at, step, True)
        elif channel.path == "translation":
            tracks.translation[channel.node] = sample_keys(times, values, at, step, False)
        else:
            sampled = sample_keys(times, values, at, step, False)
            scaled = scaled or bool(np.ptp(sampled, axis=1).max() > 1e-4 * np.abs(sampled).max())
            tracks.scale[channel.node] = sampled.mean(axis=1)
    scaled = scaled or any(np.ptp(document.rest_trs(node)[2]) > 1e-4 for node in involved)
    if scaled:
        notes.append("non-uniform node scale is applied as its mean (clips carry no scale)")
    rotations, translations = _compose(layout, tracks, count, notes)
    rest = _compose(layout, _rest_tracks(document, involved, 1), 1, [])
    skeleton = Skeleton(_joint_names(document, layout.nodes), layout.parents, rest[1][0], rest[0][0])
    return Clip(
        name=name,
        source=path,
        skeleton=skeleton,
        rotations=rotations,
        translations=translations,
        fps=fps,
        meters_per_unit=1.0,
        up_axis="y",
        notes=notes,
    )


def _note_ignored(document: _Document, index: int, involved: set[int], notes: list[str]) -> None:
    channels = document.channels(index)
    if any(c.path == "weights" for c in channels):
        notes.append("morph target weights are ignored")
    if any(c.node is None for c in channels):
        notes.append("channels without a target node (extensions such as KHR_animation_pointer) are ignored")
    outside = sum(
        1 for c in channels if c.node is not None and c.node not in involved and c.path != "weights"
    )
    if outside:
        notes.append(f"{outside} channels drive nodes outside the skeleton and were ignored")


def _rest_tracks(document: _Document, nodes: set[int], count: int) -> _Tracks:
    tracks = _Tracks({}, {}, {})
    for node in nodes:
        translation, rotation, scale = document.rest_trs(node)
        tracks.translation[node] = np.tile(translation, (count, 1))
        tracks.rotation[node] = np.tile(rotation, (count, 1))
        tracks.scale[node] = np.full(count, float(np.mean(scale)))
    return tracks


def _compose(layout: _Layout, tracks: _Tracks, count: int, notes: list[str]) -> tuple[FloatArray, FloatArray]:
    """Local joint rotations and translations with the nodes above the roots folded in and each
    parent's accumulated uniform scale applied to its children's offsets."""
    joints = len(layout.nodes)
    rotations = np.empty((count, joints, 4))
    translations = np.empty((count, joints, 3))
    world_scale = np.empty((count, joints))
    folded = False
    for joint, (node, parent) in enumerate(zip(layout.nodes, layout.parents, strict=True)):
        offset, turn, scale = tracks.translation[node], tracks.rotation[node], tracks.scale[node]
        if parent >= 0:
            rotations[:, joint] = turn
            translations[:, joint] = world_scale[:, parent, None] * offset
            world_scale[:, joint] = world_scale[:, parent] * scale
            continue
        above_t, above_r, above_s = np.zeros((count, 3)), np.tile(quat.IDENTITY, (count, 1)), np.ones(count)
        for ancestor in layout.above[node]:
            above_t = above_t + above_s[:, None] * quat.rotate(above_r, tracks.translation[ancestor])
            above_r = quat.multiply(above_r, tracks.rotation[ancestor])
            above_s = above_s * tracks.scale[ancestor]
        folded = folded or not (
            np.allclose(above_t, 0.0)
            and np.allclose(above_s, 1.0)
            and np.allclose(np.abs(above_r[:, 3]), 1.0)
        )
        rotations[:, joint] = quat.multiply(above_r, turn)
        translations[:, joint] = above_t + above_s[:, None] * quat.rotate(above_r, offset)
        world_scale[:, joint] = above_s * scale
    if folded:
        notes.append("the transform of the nodes above the skin's root joints is folded into the root joints")
    if np.abs(world_scale - 1.0).max() > 1e-6:
        notes.append("node scale is folded into the joint offsets (clips carry no scale)")
    return quat.normalize(rotations), translations


def _clip_names(path: Path, names: list[tuple[int, Any]]) -> list[str]:
    """The file stem for a single animation, ``<stem>/<animation>`` for several (as spec.md says);
    an unnamed animation is ``animation_<index>``, a repeated name gets ``_2``, ``_3``..."""
    if len(names) == 1:
        return [path.stem]
    labels = [name if isinstance(name, str) and name else f"animation_{i}" for i, name in names]
    unique: list[str] = []
    for label in labels:
        candidate, counter = label, 1
        while candidate in unique:
            counter += 1
            candidate = f"{label}_{counter}"
        unique.append(candidate)
    return [f"{path.stem}/{label}" for label in unique]
