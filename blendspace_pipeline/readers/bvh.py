"""BVH clips: the hierarchy parsed line by line, the MOTION block in one vectorised numpy pass.

Any channel count and order per joint (position channels on any joint replace its OFFSET, as
BVH defines), any rotation order (the CHANNELS order is the intrinsic Euler order), End Sites,
several roots, CRLF or LF line ends, tabs. BVH has no unit and no up axis: `Clip.meters_per_unit`
and `Clip.up_axis` stay None and measurement detects them.

Speed matters because studios keep thousands of mocap takes: the MOTION numbers are parsed by
numpy's C float parser in one call and the Euler angles of all joints that share a rotation order
are converted in one vectorised call. Only when the numbers do not add up does the reader walk the
lines one by one, to name the line that is wrong.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendspace_pipeline import quaternions as quat
from blendspace_pipeline.clip import Clip, Skeleton
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.quaternions import FloatArray

SUFFIXES = (".bvh",)
_POSITION = {"xposition": 0, "yposition": 1, "zposition": 2}
_ROTATION = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
_MOTION = re.compile(r"^[ \t]*MOTION[ \t]*\r?$", re.MULTILINE | re.IGNORECASE)
_FRAME_TIME = re.compile(r"^[ \t]*Frame[ \t]*Time[ \t]*:[^\n]*", re.MULTILINE | re.IGNORECASE)
_REEXPORT = "re-export the clip as BVH from the DCC or mocap software"


@dataclass
class BvhJoint:
    name: str
    parent: int
    offset: tuple[float, float, float]
    channels: tuple[str, ...]  # as written, e.g. ("Xposition", ..., "Zrotation")
    line: int
    end_site: tuple[float, float, float] | None = None  # kept so a writer can reproduce it


@dataclass
class BvhHeader:
    """The HIERARCHY section and the MOTION block's header."""

    joints: list[BvhJoint] = field(default_factory=list)
    frames: int = 0
    frame_time: float = 0.0
    frames_line: int = 0
    data_line: int = 0  # 1-based line of the first frame

    @property
    def channel_count(self) -> int:
        return sum(len(j.channels) for j in self.joints)


def read(path: Path) -> list[Clip]:
    text = _text(path)
    # Split only the header into lines; the MOTION numbers go to numpy as one string.
    motion = _MOTION.search(text)
    frame_time = _FRAME_TIME.search(text, motion.end()) if motion else None
    head_end = frame_time.end() if frame_time else len(text)
    lines = text[:head_end].splitlines()
    header = parse_header(lines, path)
    values = _motion(text[head_end:], len(lines), header, path)
    return [_clip(path, header, values)]


def _text(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise ClipReadError(f"cannot read the file: {error.strerror or error}", path=path) from None
    if b"\x00" in raw[:4096]:
        raise ClipReadError("not a text BVH file (binary data)", path=path, line=1, hint=_REEXPORT)
    return raw.decode("utf-8", errors="replace")


def parse_header(lines: list[str], path: Path) -> BvhHeader:
    """Parse HIERARCHY up to the first frame line; raises with the offending line number."""
    header = BvhHeader()
    stack: list[int] = []  # open joints; -2 marks an open End Site
    pending: tuple[str, int] | None = None  # a ROOT/JOINT/End Site keyword waiting for its "{"
    seen_hierarchy = False
    index = 0
    while index < len(lines):
        number = index + 1
        tokens = lines[index].split()
        index += 1
        if not tokens:
            continue
        word = tokens[0].upper()
        if not seen_hierarchy:
            if word != "HIERARCHY":
                raise ClipReadError(
                    f"expected HIERARCHY, found {tokens[0][:40]!r}", path=path, line=number, hint=_REEXPORT
                )
            seen_hierarchy = True
            continue
        if word in ("ROOT", "JOINT"):
            if len(tokens) < 2:
                raise ClipReadError(f"{tokens[0]} without a name", path=path, line=number, hint=_REEXPORT)
            if word == "JOINT" and not stack:
                raise ClipReadError("JOINT outside any ROOT", path=path, line=number, hint=_REEXPORT)
            name = " ".join(tokens[1:]).rstrip("{").strip()
            parent = stack[-1] if stack else -1
            if parent == -2:
                raise ClipReadError("a joint inside an End Site", path=path, line=number, hint=_REEXPORT)
            header.joints.append(BvhJoint(name, parent, (0.0, 0.0, 0.0), (), number))
            pending = ("joint", len(header.joints) - 1)
            if tokens[-1].endswith("{"):
                stack.append(pending[1])
                pending = None
        elif word == "END":
            if not stack or stack[-1] == -2:
                raise ClipReadError("End Site outside a joint", path=path, line=number, hint=_REEXPORT)
            pending = ("end", stack[-1])
            if tokens[-1].endswith("{"):
                stack.append(-2)
                pending = None
        elif word == "{":
            if pending is None:
                raise ClipReadError("unexpected '{'", path=path, line=number, hint=_REEXPORT)
            stack.append(pending[1] if pending[0] == "joint" else -2)
            pending = None
        elif word == "}":
            if not stack:
                raise ClipReadError("unbalanced '}'", path=path, line=number, hint=_REEXPORT)
            stack.pop()
        elif word == "OFFSET":
            offset = _floats(tokens[1:], 3, "OFFSET", path, number)
            if not stack:
                raise ClipReadError("OFFSET outside a joint", path=path, line=number, hint=_REEXPORT)
            if stack[-1] == -2:
                owner = next(i for i in reversed(stack) if i >= 0)
                header.joints[owner].end_site = offset
            else:
                header.joints[stack[-1]].offset = offset
        elif word == "CHANNELS":
            _channels(header, stack, tokens, path, number)
        elif word == "MOTION":
            if stack or pending is not None:
                raise ClipReadError(
                    "MOTION before the hierarchy is closed (missing '}')",
                    path=path,
                    line=number,
                    hint=_REEXPORT,
                )
            _motion_header(lines, index, header, path)
            break
        else:
            raise ClipReadError(
                f"unexpected {tokens[0][:40]!r} in the hierarchy",
                path=path,
                line=number,
                hint="expected ROOT, JOINT, End Site, OFFSET, CHANNELS, braces or MOTION",
            )
    else:
        where = len(lines) or 1
        what = "no HIERARCHY" if not seen_hierarchy else "the file ends before MOTION"
        raise ClipReadError(f"truncated BVH: {what}", path=path, line=where, hint=_REEXPORT)
    if not header.joints:
        raise ClipReadError("the hierarchy has no joints", path=path, line=1, hint=_REEXPORT)
    return header


def _floats(tokens: list[str], count: int, what: str, path: Path, number: int) -> tuple[float, float, float]:
    try:
        values = [float(t) for t in tokens[:count]]
    except ValueError:
        values = []
    if len(values) != count:
        raise ClipReadError(f"{what} needs {count} numbers", path=path, line=number, hint=_REEXPORT)
    return (values[0], values[1], values[2])


def _channels(header: BvhHeader, stack: list[int], tokens: list[str], path: Path, number: int) -> None:
    if not stack or stack[-1] < 0:
        raise ClipReadError("CHANNELS outside a joint", path=path, line=number, hint=_REEXPORT)
    try:
        count = int(tokens[1])
    except (IndexError, ValueError):
        raise ClipReadError("CHANNELS needs a count", path=path, line=number, hint=_REEXPORT) from None
    names = tuple(tokens[2:])
    if len(names) != count:
        raise ClipReadError(
            f"CHANNELS says {count} but lists {len(names)}", path=path, line=number, hint=_REEXPORT
        )
    for name in names:
        if name.lower() not in _POSITION and name.lower() not in _ROTATION:
            raise ClipReadError(
                f"unknown channel {name!r}",
                path=path,
                line=number,
                hint="channels are Xposition/Yposition/Zposition and Xrotation/Yrotation/Zrotation",
            )
    header.joints[stack[-1]].channels = names


def _motion_header(lines: list[str], index: int, header: BvhHeader, path: Path) -> None:
    found: dict[str, tuple[str, int]] = {}
    while index < len(lines) and len(found) < 2:
        text = lines[index].strip()
        index += 1
        if not text:
            continue
        key, _, value = text.partition(":")
        key = key.strip().lower()
        if key not in ("frames", "frame time"):
            raise ClipReadError(
                f"expected 'Frames:' and 'Frame Time:' after MOTION, found {text[:40]!r}",
                path=path,
                line=index,
                hint=_REEXPORT,
            )
        found[key] = (value.strip(), index)
    if len(found) < 2:
        raise ClipReadError(
            "truncated BVH: the MOTION header is incomplete", path=path, line=len(lines), hint=_REEXPORT
        )
    try:
        header.frames = int(found["frames"][0])
    except ValueError:
        raise ClipReadError(
            f"Frames: is not a whole number ({found['frames'][0]!r})",
            path=path,
            line=found["frames"][1],
            hint=_REEXPORT,
        ) from None
    try:
        header.frame_time = float(found["frame time"][0])
    except ValueError:
        header.frame_time = float("nan")
    if not header.frame_time > 0 or not np.isfinite(header.frame_time):
        raise ClipReadError(
            f"Frame Time must be a positive number of seconds, not {found['frame time'][0]!r}",
            path=path,
            line=found["frame time"][1],
            hint="e.g. 'Frame Time: 0.033333' for 30 fps",
        )
    header.frames_line = found["frames"][1]
    header.data_line = index + 1
    if header.frames <= 0:
        raise ClipReadError(
            "the clip has no frames (Frames: 0)",
            path=path,
            line=header.frames_line,
            hint="export the animation with its keys",
        )


def _motion(data: str, lines_before: int, header: BvhHeader, path: Path) -> FloatArray:
    """(frames, channels) values; the fast path is one numpy parse of the whole block.

    Line breaks inside the block do not matter when the count is right (some exporters wrap long
    frames); only a wrong count sends the reader line by line to find the culprit.
    """
    channels = header.channel_count
    if channels == 0:
        return np.zeros((header.frames, 0))
    expected = header.frames * channels
    try:
        values = np.fromstring(data, dtype=np.float64, sep=" ")
    except ValueError:  # a token that is not a number: find it below
        values = np.zeros(0)
    if values.size == expected:
        return values.reshape(header.frames, channels)
    lines = data.split("\n")
    rows = [i for i, line in enumerate(lines) if line.strip()]
    return _motion_slow(lines, rows, lines_before, header, path)


def _motion_slow(
    lines: list[str], rows: list[int], lines_before: int, header: BvhHeader, path: Path
) -> FloatArray:
    """Walk the frame lines to name the first one that is wrong (``lines_before``: header lines)."""
    channels = header.channel_count
    for count, row in enumerate(rows[: header.frames], start=1):
        tokens = lines[row].split()
        if len(tokens) != channels:
            raise ClipReadError(
                f"frame {count} has {len(tokens)} values; the hierarchy has {channels} channels",
                path=path,
                line=lines_before + row,
                hint="the file is truncated or its hierarchy does not match the motion",
            )
        for column, token in enumerate(tokens):
            try:
                float(token)
            except ValueError:
                raise ClipReadError(
                    f"frame {count}, channel {column + 1}: {token[:30]!r} is not a number",
                    path=path,
                    line=lines_before + row,
                    hint=_REEXPORT,
                ) from None
    if len(rows) < header.frames:
        raise ClipReadError(
            f"truncated BVH: Frames: says {header.frames} but the file has {len(rows)}",
            path=path,
            line=(lines_before + rows[-1]) if rows else header.frames_line,
            hint="the file was cut off; re-export it, or correct 'Frames:' to the frames present",
        )
    raise ClipReadError(
        f"Frames: says {header.frames} but the file has {len(rows)} frame lines",
        path=path,
        line=lines_before + rows[header.frames],
        hint="correct 'Frames:' or remove the extra lines",
    )


def _clip(path: Path, header: BvhHeader, values: FloatArray) -> Clip:
    joints = header.joints
    frames = header.frames
    count = len(joints)
    rest = np.array([j.offset for j in joints], dtype=np.float64)
    translations = np.broadcast_to(rest, (frames, count, 3)).copy()
    rotations = np.empty((frames, count, 4))
    by_order: dict[str, list[tuple[int, list[int]]]] = {}
    column = 0
    for index, joint in enumerate(joints):
        order = ""
        rotation_columns = []
        for name in joint.channels:
            key = name.lower()
            if key in _POSITION:
                translations[:, index, _POSITION[key]] = values[:, column]
            else:
                order += _ROTATION[key]
                rotation_columns.append(column)
            column += 1
        by_order.setdefault(order, []).append((index, rotation_columns))
    for order, members in by_order.items():
        indices = [m[0] for m in members]
        if not order:
            rotations[:, indices] = quat.IDENTITY
            continue
        angles = values[:, [c for m in members for c in m[1]]].reshape(frames, len(members), len(order))
        rotations[:, indices] = quat.from_euler(angles, order)
    skeleton = Skeleton(
        names=tuple(j.name for j in joints),
        parents=tuple(j.parent for j in joints),
        rest_translations=rest,
        rest_rotations=np.tile(quat.IDENTITY, (count, 1)),
    )
    return Clip(
        name=path.stem,
        source=path,
        skeleton=skeleton,
        rotations=rotations,
        translations=translations,
        fps=1.0 / header.frame_time,
    )
