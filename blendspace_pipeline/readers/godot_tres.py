"""Godot text resources (.tres) holding `Animation`s: one clip per animation.

Two track layouts are read:

* Godot 3 (``format=2``): ``tracks/N/type = "transform"`` with 12 floats per key (time,
  transition, location xyz, rotation quaternion xyzw, scale xyz). The values are the bone's pose
  *relative to its rest pose*, which lives in the model (.glb/.escn), not in this file.
* Godot 4 (``format=3``): separate ``position_3d`` / ``rotation_3d`` / ``scale_3d`` tracks with
  5 / 6 / 5 floats per key (time, transition, values), holding the bone's local pose.

An Animation resource names its bones (``NodePath("Skeleton3D:hips")``) but carries neither the
hierarchy nor the rest pose, so the clip has a flat skeleton (``has_hierarchy=False``, every
joint its own root, identity rest): each joint's transform is exactly its track, and measurement
reads root motion from a single joint's track (the bone called ``root`` in most Godot rigs).
Keys are resampled to a constant rate — ``1 / step`` when the resource sets ``step``, else
30 fps — with linear interpolation for locations and slerp for rotations (nearest-key tracks
hold). Godot's units are metres and its up axis is +Y.

An ``AnimationLibrary`` resource (Godot 4) yields one clip per Animation sub-resource. Key arrays
are parsed with numpy; parse errors carry the line they start on.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.gltf import sample_keys

SUFFIXES = (".tres",)

DEFAULT_FPS = 30.0
_MAX_FRAMES = 1_000_000
_HEADER = re.compile(
    r"\[\s*([A-Za-z_]+)((?:\s+[A-Za-z_]+\s*=\s*(?:\"(?:[^\"\\]|\\.)*\"|[^\s\]]+))*)\s*\]\s*$"
)
_ATTRIBUTE = re.compile(r"([A-Za-z_]+)\s*=\s*(\"(?:[^\"\\]|\\.)*\"|[^\s\]]+)")
_PROPERTY = re.compile(r"([^\s=\[][^=]*?)\s*=\s*(.*)$", re.DOTALL)
_STRING = re.compile(r"\"(?:[^\"\\]|\\.)*\"")
_STRING_END = re.compile(r"(?:[^\"\\]|\\.)*\"")
_FLOAT_ARRAY = re.compile(
    r"(PackedFloat32Array|PackedFloat64Array|PoolRealArray|RealArray|FloatArray)\s*\((.*)\)\s*$", re.DOTALL
)
_NODE_PATH = re.compile(r"NodePath\s*\(\s*(\"(?:[^\"\\]|\\.)*\")\s*\)\s*$")
_TRACK = re.compile(r"tracks/(\d+)/(\w+)$")
_LIBRARY_ENTRY = re.compile(r"&?\"((?:[^\"\\]|\\.)*)\"\s*:\s*SubResource\s*\(\s*\"?([^\")]+?)\"?\s*\)")
# Floats per key and the slice holding the values, per track type.
_LAYOUTS = {
    "transform": (12, {"position": slice(2, 5), "rotation": slice(5, 9)}),
    "position_3d": (5, {"position": slice(2, 5)}),
    "rotation_3d": (6, {"rotation": slice(2, 6)}),
    "scale_3d": (5, {}),
}
_KEY_WORDS = {
    "transform": "time, transition, location xyz, rotation xyzw, scale xyz",
    "position_3d": "time, transition, x, y, z",
    "rotation_3d": "time, transition, x, y, z, w",
    "scale_3d": "time, transition, x, y, z",
}
_REEXPORT = "save the animation as a Godot Animation resource (.tres) or export the model as glTF"


@dataclass
class _Value:
    text: str
    line: int


@dataclass
class _Section:
    kind: str  # gd_resource, ext_resource, sub_resource, resource
    attributes: dict[str, str]
    line: int
    properties: dict[str, _Value] = field(default_factory=dict)


def read(path: Path) -> list[Clip]:
    """Every Animation in ``path`` as a clip (one for an Animation resource)."""
    sections = _parse(path, _text(path))
    if not sections or sections[0].kind not in ("gd_resource", "gd_scene"):
        raise ClipReadError(
            "not a Godot text resource (the first section is not [gd_resource ...])",
            path=path,
            line=sections[0].line if sections else None,
            hint=_REEXPORT,
        )
    header = sections[0]
    kind = header.attributes.get("type", "")
    if header.kind == "gd_resource" and kind == "Animation":
        body = next((s for s in sections if s.kind == "resource"), None)
        if body is None:
            raise ClipReadError("the Animation resource has no [resource] section", path=path, hint=_REEXPORT)
        return [_read_animation(path, path.stem, body)]
    if header.kind == "gd_resource" and kind == "AnimationLibrary":
        return _read_library(path, sections)
    what = f"a {kind} resource" if header.kind == "gd_resource" else "a scene (.tscn content)"
    raise ClipReadError(
        f"{what}, not an Animation",
        path=path,
        line=header.line,
        hint="list the Animation .tres files themselves (for a blend space resource, the animations "
        "it places); " + _REEXPORT,
    )


def _text(path: Path) -> str:
    try:
        return path.read_bytes().decode("utf-8-sig")
    except OSError as error:
        raise ClipReadError(f"cannot read the file: {error.strerror or error}", path=path) from None
    except UnicodeDecodeError as error:
        line = path.read_bytes()[: error.start].count(b"\n") + 1
        raise ClipReadError(
            "not a Godot text resource: the file is not UTF-8 text", path=path, line=line, hint=_REEXPORT
        ) from None


# --- text resource syntax -----------------------------------------------------------------------


def _parse(path: Path, text: str) -> list[_Section]:
    """Sections with their ``name = value`` properties; a value runs on while brackets are open."""
    sections: list[_Section] = []
    lines = text.split("\n")
    number = 0
    while number < len(lines):
        line = lines[number].strip()
        start = number + 1
        number += 1
        if not line or line.startswith(";"):
            continue
        if line.startswith("["):
            header = _HEADER.match(line)
            if header is None:
                raise ClipReadError(
                    "malformed section header",
                    path=path,
                    line=start,
                    column=1,
                    hint="expected [type key=value ...]",
                )
            attributes = {k: _unquote(v) for k, v in _ATTRIBUTE.findall(header.group(2))}
            sections.append(_Section(header.group(1), attributes, start))
            continue
        prop = _PROPERTY.match(line)
        if prop is None or not sections:
            raise ClipReadError(
                "expected `name = value`" + ("" if sections else " inside a [section]"),
                path=path,
                line=start,
                column=1,
                hint="the file is truncated or was edited by hand; " + _REEXPORT,
            )
        value = prop.group(2)
        depth, quoted = _scan(value, False)
        while (depth > 0 or quoted) and number < len(lines):
            value += "\n" + lines[number]
            more, quoted = _scan(lines[number], quoted)
            depth += more
            number += 1
        if depth != 0 or quoted:
            problem = (
                "an unterminated string" if quoted else f"{'a missing' if depth > 0 else 'an extra'} bracket"
            )
            raise ClipReadError(
                f"the value of {prop.group(1)!r} is not closed ({problem})",
                path=path,
                line=start,
                hint="the file is truncated or was edited by hand; " + _REEXPORT,
            )
        sections[-1].properties[prop.group(1).strip('"')] = _Value(value.strip(), start)
    return sections


def _scan(line: str, quoted: bool) -> tuple[int, bool]:
    """Open minus closed brackets of ``line`` outside strings, and whether the line ends inside
    a string (Godot strings, such as embedded script source, may span lines)."""
    if quoted:
        end = _STRING_END.match(line)
        if end is None:
            return 0, True
        line = line[end.end() :]
    if '"' in line:
        line = _STRING.sub("", line)
        if '"' in line:  # a string opens here and runs on
            return _depth(line.partition('"')[0]), True
    return _depth(line), False


def _depth(bare: str) -> int:
    return sum(bare.count(c) for c in "([{") - sum(bare.count(c) for c in ")]}")


def _unquote(text: str) -> str:
    if len(text) >= 2 and text[0] == text[-1] == '"':
        return re.sub(r"\\(.)", r"\1", text[1:-1])
    return text


def _string(path: Path, value: _Value, what: str) -> str:
    text = value.text
    node_path = _NODE_PATH.match(text)
    if node_path:
        text = node_path.group(1)
    if not (len(text) >= 2 and text[0] == text[-1] == '"'):
        raise ClipReadError(
            f"{what} is not a string: {text[:40]}", path=path, line=value.line, hint=_REEXPORT
        )
    return _unquote(text)


def _number(path: Path, value: _Value | None, what: str, default: float) -> float:
    if value is None:
        return default
    try:
        return float(value.text)
    except ValueError:
        raise ClipReadError(
            f"{what} is not a number: {value.text[:40]}", path=path, line=value.line
        ) from None


def _floats(path: Path, value: _Value, what: str) -> FloatArray:
    array = _FLOAT_ARRAY.match(value.text)
    if array is None:
        raise ClipReadError(
            f"{what} is not a float array: {value.text[:40]}",
            path=path,
            line=value.line,
            hint="transform keys are written as PackedFloat32Array( ... ) / PoolRealArray( ... ); "
            + _REEXPORT,
        )
    body = array.group(2).strip()
    if not body:
        return np.empty(0)
    try:
        return np.array(body.split(","), dtype=np.float64)
    except ValueError:
        bad = next(item.strip() for item in body.split(",") if not _is_float(item))
        raise ClipReadError(
            f"{what} holds {bad[:30]!r}, not a number", path=path, line=value.line, hint=_REEXPORT
        ) from None


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# --- animations ---------------------------------------------------------------------------------


def _read_library(path: Path, sections: list[_Section]) -> list[Clip]:
    """Godot 4 AnimationLibrary: ``_data = { "walk": SubResource("Animation_x"), ... }``."""
    animations = {s.attributes.get("id", ""): s for s in sections if s.kind == "sub_resource"}
    animations = {k: s for k, s in animations.items() if s.attributes.get("type") == "Animation"}
    body = next((s for s in sections if s.kind == "resource"), None)
    data = body.properties.get("_data") if body else None
    entries = _LIBRARY_ENTRY.findall(data.text) if data else []
    named = [(_unquote(f'"{name}"'), animations[ident]) for name, ident in entries if ident in animations]
    if not named:  # no _data table: the sub-resources' own names
        named = [(_resource_name(path, s, ident), s) for ident, s in animations.items()]
    if not named:
        raise ClipReadError(
            "the AnimationLibrary holds no Animation sub-resources",
            path=path,
            hint="save the animations inside the library (not as external files), or list their .tres files",
        )
    if len(named) == 1:
        return [_read_animation(path, path.stem, named[0][1])]
    return [_read_animation(path, f"{path.stem}/{name}", section) for name, section in named]


def _resource_name(path: Path, section: _Section, ident: str) -> str:
    value = section.properties.get("resource_name")
    return _string(path, value, "resource_name") if value is not None else ident


@dataclass
class _Track:
    index: int
    kind: str
    joint: str  # the NodePath, e.g. "Skeleton3D:hips"
    interpolation: int
    times: FloatArray
    values: dict[str, FloatArray]  # "position" (K, 3) / "rotation" (K, 4)
    eased: bool  # some key has a transition (easing) other than linear


def _read_animation(path: Path, name: str, section: _Section) -> Clip:
    properties = section.properties
    notes: list[str] = []
    tracks = _tracks(path, properties, notes)
    if not tracks:
        raise ClipReadError(
            "the Animation has no 3D transform tracks",
            path=path,
            line=section.line,
            hint="export the skeleton animation with bone tracks (transform, or position_3d/rotation_3d)",
        )
    length = _number(path, properties.get("length"), "length", 1.0)
    step = _number(path, properties.get("step"), "step", 0.0)
    if not (np.isfinite(length) and length >= 0):
        raise ClipReadError(f"length {length} is not a duration", path=path, line=properties["length"].line)
    fps = 1.0 / step if np.isfinite(step) and step > 0 else DEFAULT_FPS
    intervals = length * fps
    count = max(round(intervals), 0) + 1
    if count > _MAX_FRAMES:
        raise ClipReadError(
            f"length {length:g} s at {fps:g} fps is {count} frames, too many for a clip",
            path=path,
            line=properties["length"].line if "length" in properties else section.line,
        )
    if count > 1 and abs(intervals - (count - 1)) > 1e-3:
        # A whole number of frames keeps the last frame on the animation's end.
        notes.append(
            f"{fps:g} fps does not divide the length {length:g} s: sampled at {(count - 1) / length:.4g} fps"
        )
        fps = (count - 1) / length
    source = f"step {step:g} s" if step > 0 else f"no step property, default {DEFAULT_FPS:g} fps"
    notes.append(f"keys resampled at {fps:.4g} fps ({source})")
    _note_loop(properties, notes)
    at = np.arange(count) / fps
    joints = sorted({t.joint for t in tracks}, key=lambda j: min(t.index for t in tracks if t.joint == j))
    rotations = np.tile(quat.IDENTITY, (count, len(joints), 1))
    translations = np.zeros((count, len(joints), 3))
    for track in tracks:
        joint = joints.index(track.joint)
        step_keys = track.interpolation == 0
        if "position" in track.values:
            translations[:, joint] = sample_keys(track.times, track.values["position"], at, step_keys, False)
        if "rotation" in track.values:
            rotations[:, joint] = sample_keys(
                track.times, quat.normalize(track.values["rotation"]), at, step_keys, True
            )
    count_joints = len(joints)
    skeleton = Skeleton(
        names=_joint_names(joints),
        parents=(-1,) * count_joints,
        rest_translations=np.zeros((count_joints, 3)),
        rest_rotations=np.tile(quat.IDENTITY, (count_joints, 1)),
        has_hierarchy=False,
    )
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


def _tracks(path: Path, properties: dict[str, _Value], notes: list[str]) -> list[_Track]:
    grouped: dict[int, dict[str, _Value]] = {}
    for key, value in properties.items():
        match = _TRACK.match(key)
        if match:
            grouped.setdefault(int(match.group(1)), {})[match.group(2)] = value
    tracks: list[_Track] = []
    skipped: dict[str, int] = {}
    kinds: set[str] = set()
    for index in sorted(grouped):
        fields = grouped[index]
        kind = _string(path, fields["type"], f"tracks/{index}/type") if "type" in fields else ""
        if kind not in _LAYOUTS:
            skipped[kind or "untyped"] = skipped.get(kind or "untyped", 0) + 1
            continue
        if "enabled" in fields and fields["enabled"].text == "false":
            skipped["disabled"] = skipped.get("disabled", 0) + 1
            continue
        track = _track(path, index, kind, fields)
        kinds.add(kind)
        if track.interpolation in (2, 4):
            notes.append(f"track {index} ({track.joint}) uses cubic interpolation: sampled linearly")
        if track.values:
            tracks.append(track)
    eased = [t.joint for t in tracks if t.eased]
    if eased:
        notes.append(
            f"key easing (transition other than 1) on {len(eased)} tracks is ignored: sampled linearly"
        )
    if skipped:
        listed = ", ".join(f"{n} {kind}" for kind, n in sorted(skipped.items()))
        notes.append(f"tracks ignored: {listed}")
    if "scale_3d" in kinds or "transform" in kinds:
        notes.append("bone scale keys are ignored (clips carry rotation and translation only)")
    if "transform" in kinds:
        notes.append(
            "Godot 3 transform tracks are poses relative to each bone's rest, which lives in the model: "
            "joints are read without hierarchy or rest"
        )
    elif kinds:
        notes.append("bone poses are read without hierarchy or rest (they live in the model)")
    return tracks


def _track(path: Path, index: int, kind: str, fields: dict[str, _Value]) -> _Track:
    where = f"tracks/{index}"
    if "keys" not in fields or "path" not in fields:
        missing = "keys" if "keys" not in fields else "path"
        line = min(v.line for v in fields.values())
        raise ClipReadError(f"{where} has no {missing}", path=path, line=line, hint=_REEXPORT)
    if "compressed" in fields and fields["compressed"].text == "true":
        raise ClipReadError(
            f"{where} is compressed",
            path=path,
            line=fields["compressed"].line,
            hint="disable animation compression in the import settings and save the Animation again",
        )
    joint = _string(path, fields["path"], f"{where}/path")
    keys = _floats(path, fields["keys"], f"{where}/keys")
    width, slices = _LAYOUTS[kind]
    if keys.size % width:
        raise ClipReadError(
            f"{where}/keys has {keys.size} numbers, not a multiple of {width} ({_KEY_WORDS[kind]})",
            path=path,
            line=fields["keys"].line,
            hint=_REEXPORT,
        )
    rows = keys.reshape(-1, width)
    times = rows[:, 0]
    if not np.isfinite(times).all() or np.any(np.diff(times) < 0):
        raise ClipReadError(
            f"{where}/keys: key times are not finite and increasing", path=path, line=fields["keys"].line
        )
    interpolation = int(_number(path, fields.get("interp"), f"{where}/interp", 1.0))
    values = {name: rows[:, part] for name, part in slices.items()} if len(rows) else {}
    eased = bool(np.any(np.abs(rows[:, 1] - 1.0) > 1e-6)) and interpolation != 0
    return _Track(index, kind, joint, interpolation, times, values, eased)


def _note_loop(properties: dict[str, _Value], notes: list[str]) -> None:
    loop = properties.get("loop")
    mode = properties.get("loop_mode")
    if (loop is not None and loop.text == "true") or (mode is not None and mode.text in ("1", "2")):
        notes.append(
            "the animation loops" + (" (ping-pong)" if mode is not None and mode.text == "2" else "")
        )


def _joint_names(paths: list[str]) -> tuple[str, ...]:
    """The bone name after ':' (the node path for node tracks); the full path when two clash."""
    bones = [p.rsplit(":", 1)[-1] if ":" in p else p for p in paths]
    return tuple(bone if bones.count(bone) == 1 else p for bone, p in zip(bones, paths, strict=True))
