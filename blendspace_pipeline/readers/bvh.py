"""BVH clips: the hierarchy parsed line by line, the MOTION block by compiled code in one pass.

Any channel count and order per joint (position channels on any joint replace its OFFSET, as
BVH defines), any rotation order (the CHANNELS order is the intrinsic Euler order), End Sites,
several roots, CRLF or LF line ends, tabs. BVH has no unit and no up axis: `Clip.meters_per_unit`
and `Clip.up_axis` stay None and measurement detects them.

Speed matters because studios keep thousands of mocap takes (1,000 clips are ~460 MB of text).
The MOTION numbers go through four parsers, fastest first, each used only when the one before it
cannot vouch for its result, so all give the same values and the same errors:

1. the package's own kernel (`_kernels.parse_decimals`, when it was compiled at install): plain
   decimals converted exactly (Clinger's fast path), written straight into the channel-major
   array; about 4x pyarrow on a 7 s take. It declines any other spelling or count;
2. pyarrow's CSV reader (~4x numpy's text parser on blocks of 32 KB and more), strict: it is
   kept only when it returns exactly ``Frames`` rows of one float per channel, no empty field
   and no NaN/inf;
3. numpy's ``fromstring``, which ignores line structure (wrapped frames, mixed whitespace);
4. a line-by-line walk that names the ``path:line`` of the first wrong frame.

All of them round every decimal correctly, as Python's ``float`` does, so the values are the
same to the bit. Euler angles of all joints that share a rotation order are converted in one
vectorised call, with the sine and cosine of a channel that never moves taken once.
"""

from __future__ import annotations

import importlib
import math
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, AnyStr

import numpy as np

from blendspace_pipeline import native
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.limits import (
    MAX_FPS,
    MAX_FRAMES_VARIABLE,
    MAX_TRANSLATION,
    MIN_FPS,
    max_frames,
    read_regular_file,
)
from blendspace_pipeline.readers.provenance import strip_bvh_provenance

if TYPE_CHECKING:
    from pyarrow import Table

SUFFIXES = (".bvh",)
_POSITION = {"xposition": 0, "yposition": 1, "zposition": 2}
_ROTATION = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
_MOTION = re.compile(r"^[ \t]*MOTION[ \t]*\r?$", re.MULTILINE | re.IGNORECASE)
_FRAME_TIME = re.compile(r"^[ \t]*Frame[ \t]*Time[ \t]*:[^\n]*", re.MULTILINE | re.IGNORECASE)
_FRAMES = re.compile(r"^[ \t]*Frames[ \t]*:[^\n]*", re.MULTILINE | re.IGNORECASE)
_MOTION_BYTES, _FRAME_TIME_BYTES, _FRAMES_BYTES = (
    re.compile(pattern.pattern.encode(), pattern.flags & ~re.UNICODE)
    for pattern in (_MOTION, _FRAME_TIME, _FRAMES)
)
_STR_SPACE = frozenset(c for c in range(128) if chr(c).isspace())  # what `str.strip` strips, in ASCII
# Unwrapped angles of a long take can pass a few thousand degrees; a million is corrupt data.
_MAX_ANGLE = 1e6
_REEXPORT = "re-export the clip as BVH from the DCC or mocap software"
# pyarrow costs ~70 ms to import, numpy's parser ~30 ms per MB: a process that reads one small
# clip (`blendspace check` of a tiny space) keeps numpy; once it has parsed this many bytes it is
# reading a library and the import pays for itself within a few clips.
ARROW_AFTER_BYTES = 2_000_000
_parsed_bytes = 0
# pyarrow's reader costs ~0.5 ms a call whatever the size (its per-column setup); numpy's ~20 us
# per KB: below this block size (a second of a 60-channel rig at 30 fps) numpy is faster.
ARROW_MIN_BLOCK = 32 * 1024


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
    motion_line: int = 0  # 1-based line of the MOTION keyword (a writer copies the lines above it)
    data_line: int = 0  # 1-based line of the first frame

    @property
    def channel_count(self) -> int:
        return sum(len(j.channels) for j in self.joints)


def read(path: Path) -> list[Clip]:
    header, by_channel = parse(path)
    return [_clip(path, header, by_channel)]


def parse(path: Path) -> tuple[BvhHeader, FloatArray]:
    """The header and the MOTION values, (channels, frames): the text parsed, not yet a `Clip`."""
    raw = _raw(path)
    if raw.isascii():
        # Nearly every BVH: located in the bytes, only the header decoded, and the C CSV parser
        # reads the MOTION block in the file's own buffer (fresh pages cost more than parsing).
        end = _content_end(raw)
        motion_at, head_end = _head_bounds(raw, end, _MOTION_BYTES, _FRAME_TIME_BYTES, _FRAMES_BYTES)
        header = _parse_header_remembered(raw[:head_end].decode("ascii"), motion_at, path)
        data_start = raw.count(b"\n", 0, head_end) + 1  # the 1-based line that the block begins on
        block: bytes | memoryview = memoryview(raw)[head_end:end]
    else:
        # A generated clip's provenance is a comment after the last frame; it is not motion data.
        text = _without_provenance(_decoded(raw))
        header, head_end = _split_header(text, path)
        data_start = text.count("\n", 0, head_end) + 1
        block = text[head_end:].encode()
    return header, _motion(block, data_start, header, path)


def _without_provenance(text: str) -> str:
    """`strip_bvh_provenance` on the last line with text only: the record can be nowhere else, and
    searching a 0.5 MB take for it from the end cost more than parsing its header."""
    end = len(text)
    while end and text[end - 1].isspace():  # the same characters `str.strip` removes
        end -= 1
    line_start = text.rfind("\n", 0, end) + 1
    if line_start == 0:
        return strip_bvh_provenance(text)
    # From the newline before that line: `strip_bvh_provenance` checks the record starts a line.
    tail = text[line_start - 1 :]
    kept = strip_bvh_provenance(tail)
    return text if kept is tail else text[: line_start - 1 + len(kept)]


def _content_end(raw: bytes) -> int:
    """`_without_provenance` on ASCII bytes: the length of the text without its provenance line."""
    end = len(raw)
    while end and raw[end - 1] in _STR_SPACE:
        end -= 1
    line_start = raw.rfind(b"\n", 0, end) + 1
    if line_start == 0:
        return len(strip_bvh_provenance(raw.decode("ascii")))
    return line_start - 1 + len(strip_bvh_provenance(raw[line_start - 1 :].decode("ascii")))


def read_header(path: Path) -> BvhHeader:
    """Only the HIERARCHY and the MOTION header (what a writer needs from a template)."""
    return _split_header(bvh_text(path), path)[0]


def _split_header(text: str, path: Path) -> tuple[BvhHeader, int]:
    """The parsed header and the offset in ``text`` where the frame numbers start."""
    head_end = _head_end(text, len(text), _MOTION, _FRAME_TIME, _FRAMES)
    return parse_header(text[:head_end].split("\n"), path), head_end


def _head_end(
    text: AnyStr,
    end: int,
    motion: re.Pattern[AnyStr],
    frame_time: re.Pattern[AnyStr],
    frames: re.Pattern[AnyStr],
) -> int:
    return _head_bounds(text, end, motion, frame_time, frames)[1]


def _head_bounds(
    text: AnyStr,
    end: int,
    motion: re.Pattern[AnyStr],
    frame_time: re.Pattern[AnyStr],
    frames: re.Pattern[AnyStr],
) -> tuple[int | None, int]:
    """Where the first MOTION line starts (None: no such line) and where the frame numbers start in ``text[:end]`` (str, or ASCII bytes: the same offsets).

    The header ends after whichever of the "Frames:" and "Frame Time:" lines comes last.
    Lines are counted on "\n" alone (CRLF ends with it too), the same count the motion
    block uses, so every reported line number is the one an editor shows.
    """
    found = motion.search(text, 0, end)
    if found:
        time_line = frame_time.search(text, found.end(), end)
        frames_line = frames.search(text, found.end(), end)
        if time_line and frames_line:
            return found.start(), max(time_line.end(), frames_line.end())
    return None, end


def bvh_text(path: Path) -> str:
    """The file's text as the reader reads it (see `_decoded` for its encodings)."""
    return _decoded(_raw(path))


def _decoded(raw: bytes) -> str:
    """The text of a BVH's bytes: UTF-8; else Windows-1252 when every character outside ASCII it
    gives is a letter (`Épaule_G`, `Muñeca_I`); else Shift-JIS (cp932: MikuMikuDance's `左足`,
    most Japanese tools), whose bytes read as Windows-1252 give punctuation and symbols (‰, ‘, ˜);
    else Latin-1, which takes any bytes. A name read as U+FFFD would match nothing the manifest
    names, and Shift-JIS tried first turned accented Latin names into kana."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        pass
    try:
        western = raw.decode("cp1252")
    except UnicodeDecodeError:
        western = None
    if western is not None and all(c.isascii() or c.isalpha() for c in western):
        return western
    try:
        return raw.decode("cp932")
    except UnicodeDecodeError:
        return western if western is not None else raw.decode("latin-1")


def _raw(path: Path) -> bytes:
    raw = read_regular_file(path, what="BVH file")
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]  # a UTF-8 byte-order mark, written by some Windows tools
    if b"\x00" in raw[:4096]:
        raise ClipReadError("not a text BVH file (binary data)", path=path, line=1, hint=_REEXPORT)
    if b"\r" in raw and b"\n" not in raw:
        # Classic Mac line endings (lone CR), still written by some old exporters.
        raw = raw.replace(b"\r", b"\n")
    return raw


# Hierarchies already parsed, by the text above their MOTION line: a library's takes share a few
# rigs, and walking a 19-joint hierarchy line by line cost a tenth of reading a 0.46 MB take.
_HIERARCHIES: dict[str, tuple[BvhJoint, ...]] = {}
_HIERARCHIES_SIZE = 256


def _parse_header_remembered(text: str, motion_at: int | None, path: Path) -> BvhHeader:
    """`parse_header` of ``text`` (everything up to the first frame), the hierarchy remembered.

    ``motion_at`` is where the first line that is MOTION alone starts (`_head_bounds`), or None.

    The hierarchy part of `parse_header` reads the lines up to the first MOTION line and nothing
    else, so a text whose lines above that MOTION line are the same as an earlier file's has the
    same joints; only its MOTION header (frames, frame time: its own errors and line numbers) is
    parsed again. Only a hierarchy that parsed without error is remembered, and its joints are
    copied each time (a writer appends to the list it gets).
    """
    lines = text.split("\n")
    if motion_at is None:
        return parse_header(lines, path)
    hierarchy = text[:motion_at]  # the regex's `^` anchors its match at the start of that line
    motion_index = hierarchy.count("\n")  # 0-based index of the MOTION line
    joints = _HIERARCHIES.get(hierarchy)
    if joints is None:
        header = parse_header(lines, path)
        # Remembered only when parsing stopped at that same line (a stray "MOTION x" line above
        # it, which the regex skips, would have stopped it earlier: such a file is parsed anew).
        if header.motion_line == motion_index + 1:
            if len(_HIERARCHIES) >= _HIERARCHIES_SIZE:
                _HIERARCHIES.clear()
            _HIERARCHIES[hierarchy] = tuple(_copy_joint(j) for j in header.joints)
        return header
    header = BvhHeader(joints=[_copy_joint(j) for j in joints], motion_line=motion_index + 1)
    _motion_header(lines, motion_index + 1, header, path)
    return header


def _copy_joint(joint: BvhJoint) -> BvhJoint:
    # Its fields are immutable values; the constructor is 5x faster than `copy.copy` here.
    return BvhJoint(joint.name, joint.parent, joint.offset, joint.channels, joint.line, joint.end_site)


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
                owner = next((i for i in reversed(stack) if i >= 0), None)
                if owner is None:  # a stray `{` opened a block that belongs to no joint
                    raise ClipReadError("OFFSET outside a joint", path=path, line=number, hint=_REEXPORT)
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
            header.motion_line = number
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
        where = _last_line(lines)
        what = "no HIERARCHY" if not seen_hierarchy else "the file ends before MOTION"
        raise ClipReadError(f"truncated BVH: {what}", path=path, line=where, hint=_REEXPORT)
    if not header.joints:
        raise ClipReadError("the hierarchy has no joints", path=path, line=1, hint=_REEXPORT)
    return header


def _last_line(lines: list[str]) -> int:
    """The 1-based number of the last line with text (where a truncated file stops)."""
    return next((n for n in range(len(lines), 0, -1) if lines[n - 1].strip()), 1)


def _floats(tokens: list[str], count: int, what: str, path: Path, number: int) -> tuple[float, float, float]:
    try:
        values = [float(t) for t in tokens[:count]]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
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
            "truncated BVH: the MOTION header is incomplete",
            path=path,
            line=_last_line(lines),
            hint=_REEXPORT,
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
    if not 1.0 / MAX_FPS <= header.frame_time <= 1.0 / MIN_FPS:
        raise ClipReadError(
            f"Frame Time {found['frame time'][0][:30]!r} is {1.0 / header.frame_time:.6g} fps, "
            f"outside {MIN_FPS:g}..{MAX_FPS:g} fps",
            path=path,
            line=found["frame time"][1],
            hint="e.g. 'Frame Time: 0.033333' for 30 fps",
        )
    header.frames_line = found["frames"][1]
    header.data_line = index + 1
    if header.frames > max_frames():
        raise ClipReadError(
            f"the clip has {header.frames:,} frames, more than the limit of {max_frames():,}",
            path=path,
            line=header.frames_line,
            hint=f"trim or split the take, or raise the limit with {MAX_FRAMES_VARIABLE}=<frames>",
        )
    if header.frames <= 0:
        raise ClipReadError(
            f"the clip has no frames (Frames: {header.frames})",
            path=path,
            line=header.frames_line,
            hint="export the animation with its keys",
        )


def _motion(block: bytes | memoryview, data_start: int, header: BvhHeader, path: Path) -> FloatArray:
    """(channels, frames) values, channel-major (what the Euler conversion reads row by row).

    ``block`` (UTF-8) starts at the end of the last MOTION header line, which is line
    ``data_start``. The C parsers are tried in turn (see the module docstring); only a wrong
    count, a token they cannot read or a NaN/inf sends the reader line by line to name the culprit.
    """
    channels = header.channel_count
    if channels == 0:
        raise ClipReadError(
            "the hierarchy has no CHANNELS: nothing in the file moves",
            path=path,
            line=header.motion_line,
            hint="export the skeleton with its animation channels",
        )
    by_channel = _motion_native(block, header.frames, channels)
    if by_channel is None:
        by_channel = _motion_python(block, data_start, header, path)
    _check_magnitudes(by_channel, header, data_start, path)
    return by_channel


def _motion_python(block: bytes | memoryview, data_start: int, header: BvhHeader, path: Path) -> FloatArray:
    """`_motion` without the compiled kernel: pyarrow, numpy, then the line-by-line walk."""
    global _parsed_bytes
    channels = header.channel_count
    _parsed_bytes += len(block)
    fast = len(block) >= ARROW_MIN_BLOCK and (
        _parsed_bytes > ARROW_AFTER_BYTES or "pyarrow.csv" in sys.modules
    )
    csv = _arrow_csv() if fast else None
    by_channel = None if csv is None else _motion_arrow(csv, block, header.frames, channels)
    if by_channel is None:
        data = bytes(block).decode("utf-8", errors="replace")
        with warnings.catch_warnings():
            # Older numpy warns (DeprecationWarning) instead of raising on a token it cannot parse.
            warnings.simplefilter("error", DeprecationWarning)
            try:
                values = np.fromstring(data, dtype=np.float64, sep=" ")
            except (ValueError, DeprecationWarning):
                values = np.zeros(0)
        if not (values.size == header.frames * channels and np.isfinite(values).all()):
            values = _motion_slow(data.split("\n"), data_start, header, path)
        by_channel = np.ascontiguousarray(values.reshape(header.frames, channels).T)
    return by_channel


def _motion_native(block: bytes | memoryview, frames: int, channels: int) -> FloatArray | None:
    """The (channels, frames) values by the compiled kernel, or None when it is not built or
    declines the block (a spelling or a number it cannot convert exactly, a wrong count)."""
    kernels = native.kernels
    if kernels is None:
        return None
    by_channel = np.empty((channels, frames))
    return by_channel if kernels.parse_decimals(block, by_channel, frames, channels) else None


def _arrow_csv() -> ModuleType | None:
    """``pyarrow.csv``, or None when pyarrow is not installed (numpy's parser then does it all)."""
    try:
        return importlib.import_module("pyarrow.csv")
    except ImportError:
        return None


def _motion_arrow(
    csv: ModuleType, block: bytes | memoryview, frames: int, channels: int
) -> FloatArray | None:
    """The (channels, frames) values by pyarrow's CSV reader, or None when it cannot vouch for them.

    One field per value between single delimiters: the delimiter (space or tab) and a trailing
    delimiter are read from the first frame line, as exporters write every line alike. Any line
    that differs (a run of spaces, a value too many or too few, a wrapped frame, a stray token)
    makes the reader fail or gives a wrong row count, a NaN or inf fails the finiteness check, and
    None hands the block to numpy. pyarrow parses floats with fast_float, correctly rounded like
    numpy and ``float``, so a table it returns whole holds exactly the values they would give.
    """
    import pyarrow as pa

    first = bytes(block[:4096]).lstrip(b"\r\n").split(b"\n", 1)[0].rstrip(b"\r")
    delimiter = "\t" if b"\t" in first and b" " not in first else " "
    trailing = first.endswith(delimiter.encode())
    # Blank lines after the last frame hold no value (but keep that frame's trailing delimiter).
    end = len(block)
    while end and block[end - 1] in b" \t\r\n":
        end -= 1
    if trailing and end < len(block) and block[end] == ord(delimiter):
        end += 1
    block = block[:end]
    read_options, parse_options, convert_options = _arrow_options(csv, channels, trailing, delimiter)
    try:
        table: Table = csv.read_csv(
            pa.py_buffer(block),
            read_options=read_options,
            parse_options=parse_options,
            convert_options=convert_options,
        )
    except (pa.ArrowException, ValueError):
        return None
    if table.num_rows != frames or table.num_columns != channels + trailing:
        return None
    if trailing:
        if not all(_all_empty(chunk) for chunk in table.column(channels).chunks):
            return None  # a value after what the first line left empty: one value too many
        table = table.select(range(channels))
    by_channel = _channel_major(table, channels, frames)
    # Finite when every channel's extremes are: a NaN propagates into both, an inf into one.
    if not (np.isfinite(by_channel.max(axis=1)).all() and np.isfinite(by_channel.min(axis=1)).all()):
        return None  # the slow path names the line with the NaN or inf
    return by_channel


# Option objects per (channels, trailing delimiter, delimiter): a library's takes share a few
# layouts. The block size is the largest pyarrow takes, so the whole block is one chunk.
_ARROW_OPTIONS: dict[tuple[int, bool, str], tuple[Any, Any, Any]] = {}
_ARROW_BLOCK = 2**31 - 1


def _arrow_options(csv: ModuleType, channels: int, trailing: bool, delimiter: str) -> tuple[Any, Any, Any]:
    key = (channels, trailing, delimiter)
    found = _ARROW_OPTIONS.get(key)
    if found is None:
        import pyarrow as pa

        names = [f"c{index}" for index in range(channels + trailing)]
        types = {name: pa.float64() for name in names[:channels]}
        if trailing:
            types[names[-1]] = pa.string()  # the field after the last delimiter: must be empty
        found = (
            csv.ReadOptions(use_threads=False, column_names=names, block_size=_ARROW_BLOCK),
            csv.ParseOptions(delimiter=delimiter, quote_char=False),
            # No null spellings: an empty field is an error, "nan" a NaN (caught by the caller).
            csv.ConvertOptions(column_types=types, null_values=[]),
        )
        if len(_ARROW_OPTIONS) >= 64:
            _ARROW_OPTIONS.clear()
        _ARROW_OPTIONS[key] = found
    return found


def _channel_major(table: Table, channels: int, frames: int) -> FloatArray:
    """The (channels, frames) array of a table of ``channels`` float64 columns without nulls.

    One column-major tensor copy when the table is one record batch (pyarrow >= 16), the same
    values as copying the columns one by one (the fallback), at a fraction of the calls."""
    batches = table.to_batches()
    if len(batches) == 1 and hasattr(batches[0], "to_tensor"):
        # (frames, channels) in column-major order: its transpose is C-contiguous, row r channel r.
        values = np.asarray(batches[0].to_tensor(row_major=False)).T
        if values.shape == (channels, frames) and values.flags.c_contiguous:
            return np.asarray(values, dtype=np.float64)
    by_channel = np.empty((channels, frames))
    for index in range(channels):
        by_channel[index] = table.column(index).to_numpy()
    return by_channel


def _all_empty(strings: Any) -> bool:
    """Whether every value of a pyarrow string array is "" (its first and last offsets agree)."""
    offsets = np.frombuffer(strings.buffers()[1], dtype=np.int32)
    return bool(offsets[strings.offset] == offsets[strings.offset + len(strings)])


def _check_magnitudes(by_channel: FloatArray, header: BvhHeader, data_start: int, path: Path) -> None:
    """Angles beyond `_MAX_ANGLE` degrees and positions beyond `MAX_TRANSLATION` are corrupt data:
    finite, but sine and cosine of 1e308 mean nothing and positions that big overflow FK.

    ``by_channel`` is (channels, frames); the error names the first bad value in file order."""
    rotation = np.array(
        [name.lower() in _ROTATION for joint in header.joints for name in joint.channels], dtype=bool
    )
    limits = np.where(rotation, _MAX_ANGLE, MAX_TRANSLATION)
    # Per-channel extremes first: no (channels, frames) temporaries on the path every clip takes.
    if not ((by_channel.max(axis=1) > limits) | (by_channel.min(axis=1) < -limits)).any():
        return
    values = by_channel.T
    over = np.abs(values) > limits
    frame, column = (int(i) for i in np.argwhere(over)[0])
    kind = "rotation" if rotation[column] else "position"
    raise ClipReadError(
        f"frame {frame}, channel {column + 1}: {kind} {values[frame, column]:.6g} is out of range "
        f"(|value| <= {limits[column]:g})",
        path=path,
        line=data_start + 1 + frame,
        hint="such a value is corrupt data; " + _REEXPORT,
    )


def _motion_slow(lines: list[str], data_start: int, header: BvhHeader, path: Path) -> FloatArray:
    """Parse the frame lines one by one and name the first that is wrong.

    Also the fallback for numbers Python reads but numpy's parser does not (``1_000``): when no
    line is wrong the values parsed here are the result.
    """
    channels = header.channel_count
    rows = [i for i, line in enumerate(lines) if line.strip()]
    parsed: list[list[float]] = []
    for count, row in enumerate(rows[: header.frames], start=1):
        tokens = lines[row].split()
        if len(tokens) != channels:
            raise ClipReadError(
                f"frame {count} has {len(tokens)} values; the hierarchy has {channels} channels",
                path=path,
                line=data_start + row,
                hint="the file is truncated or its hierarchy does not match the motion",
            )
        parsed.append(
            [
                _motion_value(token, count, column, path, data_start + row)
                for column, token in enumerate(tokens)
            ]
        )
    if len(rows) < header.frames:
        raise ClipReadError(
            f"truncated BVH: 'Frames:' says {header.frames} but the file has {len(rows)} frames",
            path=path,
            line=(data_start + rows[-1]) if rows else header.frames_line,
            hint="the file was cut off; re-export it, or correct 'Frames:' to the frames present",
        )
    if len(rows) > header.frames:
        raise ClipReadError(
            f"'Frames:' says {header.frames} but the file has {len(rows)} frame lines",
            path=path,
            line=data_start + rows[header.frames],
            hint="correct 'Frames:' or remove the extra lines",
        )
    return np.array(parsed, dtype=np.float64).reshape(header.frames, channels)


def _motion_value(token: str, frame: int, column: int, path: Path, line: int) -> float:
    try:
        value = float(token)
    except ValueError:
        raise ClipReadError(
            f"frame {frame}, channel {column + 1}: {token[:30]!r} is not a number",
            path=path,
            line=line,
            hint=_REEXPORT,
        ) from None
    if not math.isfinite(value):
        raise ClipReadError(
            f"frame {frame}, channel {column + 1}: {token[:30]!r} is not a finite number",
            path=path,
            line=line,
            hint="NaN or inf usually comes from a broken constraint or a division by zero in the DCC; "
            "re-export the clip",
        )
    return value


def _clip(path: Path, header: BvhHeader, by_channel: FloatArray) -> Clip:
    """The clip from the (channels, frames) values: row r of ``by_channel`` is channel r."""
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
                translations[:, index, _POSITION[key]] = by_channel[column]
            else:
                order += _ROTATION[key]
                rotation_columns.append(column)
            column += 1
        by_order.setdefault(order, []).append((index, rotation_columns))
    # A channel that never moves (a rig's fingers, a mocap knee's twist: 50 of a procedural walk's
    # 60 channels, a quarter of a CMU take's) is converted once; so is a joint none of whose
    # channels moves, its quaternion repeated on every frame.
    # Equal extremes: every value the same (the values are finite; 0.0 and -0.0 count as equal,
    # as they do for ==). Two reductions along the rows, no (channels, frames) comparison array.
    still = by_channel.max(axis=1) == by_channel.min(axis=1)
    for order, members in by_order.items():
        indices = np.array([m[0] for m in members])
        if not order:
            rotations[:, indices] = quat.IDENTITY
            continue
        columns = np.array([m[1] for m in members]).T  # (letters, joints)
        fixed = still[columns].all(axis=0)
        if fixed.any():
            first = by_channel[columns[:, fixed], :1]  # (letters, joints, 1)
            rotations[:, indices[fixed]] = _still_quaternions(first, order)
        if not fixed.all():
            # (letters, joints, frames), contiguous: one block of angles per letter of the order.
            angles = by_channel[columns[:, ~fixed]]
            rotations[:, indices[~fixed]] = euler_quaternions(angles, order).T
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


# Quaternions of still joints by their angles: a library's takes of one rig hold the same angles
# on the joints that never move (a procedural walk: 15 of 19 joints), and converting them cost
# as much as converting the moving ones (a few dozen numpy calls on tiny arrays).
_STILL: dict[tuple[str, tuple[int, ...], bytes], FloatArray] = {}
_STILL_SIZE = 1024


def _still_quaternions(first: FloatArray, order: str) -> FloatArray:
    """(joints, 4): `euler_quaternions` of ``first`` (letters, joints, 1), remembered by its bytes."""
    key = (order, first.shape, first.tobytes())
    found = _STILL.get(key)
    if found is None:
        found = np.ascontiguousarray(euler_quaternions(first, order)[..., 0].T)
        found.flags.writeable = False  # shared between clips
        if len(_STILL) >= _STILL_SIZE:
            _STILL.clear()
        _STILL[key] = found
    return found


def euler_quaternions(angles_deg: FloatArray, order: str) -> FloatArray:
    """`quaternions.from_euler` with the axis first: ``angles_deg`` is (len(order), ...) and the
    result (4, ...) holds x, y, z, w.

    Same convention (intrinsic, ``R = R[order[0]] * R[order[1]] * ...``), but each step multiplies
    by a one-axis quaternion in closed form on whole contiguous rows, so reading a BVH costs about
    one sine and one cosine per angle; the general Hamilton product was a third of read time.
    """
    sines, cosines = _half_angle_sines(np.asarray(angles_deg, dtype=np.float64))
    # Written into preallocated rows (`out=`): the same products and sums, without a fresh
    # temporary per term (fresh pages cost as much as the arithmetic on a 0.5 MB take).
    q = np.empty((4, *sines.shape[1:]))
    first = "XYZ".index(order[0].upper())
    if len(order) > 1 and order[1].upper() != order[0].upper():
        # The first two one-axis factors multiplied out: each part has a single term (what the
        # general step below gives too, as its other terms are exact zeros).
        k = "XYZ".index(order[1].upper())
        i, j = (k + 1) % 3, (k + 2) % 3
        s0, c0, s1, c1 = sines[0], cosines[0], sines[1], cosines[1]
        np.multiply(s1, c0, out=q[k])
        np.multiply(c1, c0, out=q[3])
        if first == i:
            np.multiply(c1, s0, out=q[i])
            np.negative(np.multiply(s1, s0, out=q[j]), out=q[j])
        else:
            np.multiply(s1, s0, out=q[i])
            np.multiply(c1, s0, out=q[j])
        start = 2
    else:
        q[:3] = 0.0
        q[first], q[3] = sines[0], cosines[0]
        start = 1
    if start < len(order):
        step, term = np.empty_like(q), np.empty_like(q[0])
    for row in range(start, len(order)):
        # q * (s e_k + c): with (k, i, j) cyclic, the k, i, j and w parts below.
        k = "XYZ".index(order[row].upper())
        i, j = (k + 1) % 3, (k + 2) % 3
        s, c = sines[row], cosines[row]
        for part, (first_term, second_term, sign) in (
            (k, (k, 3, 1)),
            (i, (i, j, 1)),
            (j, (j, i, -1)),
            (3, (3, k, -1)),
        ):
            np.multiply(c, q[first_term], out=step[part])  # c q[.] +/- s q[.]
            np.multiply(s, q[second_term], out=term)
            (np.add if sign > 0 else np.subtract)(step[part], term, out=step[part])
        q, step = step, q
    return q


def _half_angle_sines(angles_deg: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Sine and cosine of half of every angle (degrees); a row constant along the last axis (a
    channel that never moves) costs one sine and one cosine, the bulk of the conversion's time."""
    if angles_deg.ndim < 2 or angles_deg.shape[-1] < 2:
        half = np.radians(angles_deg) * 0.5
        return np.sin(half), np.cos(half)
    rows = angles_deg.reshape(-1, angles_deg.shape[-1])
    still = (rows == rows[:, :1]).all(axis=1)
    if not still.any():
        half = np.radians(angles_deg) * 0.5
        return np.sin(half), np.cos(half)
    sines, cosines = np.empty_like(rows), np.empty_like(rows)
    moving = ~still
    half = np.radians(rows[moving]) * 0.5
    sines[moving], cosines[moving] = np.sin(half), np.cos(half)
    half = np.radians(rows[still, 0]) * 0.5
    sines[still], cosines[still] = np.sin(half)[:, None], np.cos(half)[:, None]
    return sines.reshape(angles_deg.shape), cosines.reshape(angles_deg.shape)
