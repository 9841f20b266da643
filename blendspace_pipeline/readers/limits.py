"""Hard limits and safe file access for every clip reader.

A pipeline tool runs unattended on untrusted changes (pre-commit, build farms), so no input may
crash it, hang it or make it read outside the project:

- files are opened without blocking and must be *regular* files (a FIFO would hang the read, a
  device such as /dev/zero would fill the memory) no larger than `MAX_FILE_BYTES`;
- a file a clip refers to (a glTF buffer, a USD sublayer or reference) must resolve inside the
  clip's own folder tree or the manifest's project folder (symlinks resolved); `..` and absolute
  references that leave both are refused;
- a clip may not exceed `max_frames()` frames, `MAX_JOINTS` joints or a sane frame rate, and its
  values must be of a size a body can have (a 1e308 offset overflows forward kinematics).

The frame limit is `BLENDSPACE_MAX_FRAMES` (default `DEFAULT_MAX_FRAMES`): 100,000 frames is
13.9 minutes at 120 fps, longer than any locomotion take; raise it for longer takes.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Sequence
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.clip import Clip

MAX_FILE_BYTES = 2 * 1024**3  # 2 GiB: a ten-minute 120 fps take of a 200-joint rig is ~100 MB
MAX_JOINTS = 2_000
DEFAULT_MAX_FRAMES = 100_000
MAX_FRAMES_VARIABLE = "BLENDSPACE_MAX_FRAMES"
MIN_FPS, MAX_FPS = 1.0, 10_000.0
# Translations in the file's own unit (cm for most BVH): 1e7 cm is 100 km, no body part is there.
MAX_TRANSLATION = 1e7


def max_frames() -> int:
    text = os.environ.get(MAX_FRAMES_VARIABLE, "")
    try:
        value = int(text)
    except ValueError:
        return DEFAULT_MAX_FRAMES
    return value if value > 0 else DEFAULT_MAX_FRAMES


def read_regular_file(path: Path, *, what: str = "file", limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``limit`` bytes; never blocks."""
    try:
        # O_NONBLOCK: opening a FIFO with no writer returns at once instead of waiting forever.
        handle = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as error:
        raise ClipReadError(
            f"cannot read the {what}: {error.strerror or error}", path=path, hint="check the path"
        ) from None
    try:
        info = os.fstat(handle)
        _check_info(info, path, what, limit)
        with os.fdopen(handle, "rb", closefd=True) as stream:
            handle = -1
            # Ask for the size fstat saw (+1 to notice growth): `read(limit + 1)` allocated a
            # 2 GiB buffer per call, 0.8 ms, more than reading a 0.5 MB take from the page cache.
            data = stream.read(min(info.st_size, limit) + 1)
            if len(data) > info.st_size:  # the file grew since fstat: read on up to the limit
                data += stream.read(limit + 1 - len(data))
    except OSError as error:
        raise ClipReadError(
            f"cannot read the {what}: {error.strerror or error}", path=path, hint="check the path"
        ) from None
    finally:
        if handle >= 0:
            os.close(handle)
    if len(data) > limit:
        raise ClipReadError(f"the {what} is larger than the limit of {limit:,} bytes", path=path)
    return data


def check_regular(path: Path, *, what: str = "file") -> None:
    """Raise unless ``path`` is a regular file (without opening it)."""
    try:
        info = path.stat()
    except OSError as error:
        raise ClipReadError(
            f"cannot read the {what}: {error.strerror or error}", path=path, hint="check the path"
        ) from None
    _check_info(info, path, what, MAX_FILE_BYTES)


def _check_info(info: os.stat_result, path: Path, what: str, limit: int) -> None:
    """Raise unless ``info`` is a regular file of at most ``limit`` bytes."""
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a device, FIFO or socket"
        raise ClipReadError(
            f"the {what} is not a regular file ({kind})",
            path=path,
            hint="point the manifest at the clip file itself",
        )
    if info.st_size > limit:
        raise ClipReadError(
            f"the {what} is {info.st_size:,} bytes, more than the limit of {limit:,}",
            path=path,
            hint="split the take into shorter clips",
        )


# The roots the clip being read may refer into; `read_clips` sets them around `adapter.read`. An
# adapter called directly (tests, tools) gets the clip's own folder too.
REFERENCE_ROOTS: ContextVar[list[Path] | None] = ContextVar("REFERENCE_ROOTS", default=None)


def current_roots(clip_path: Path) -> list[Path]:
    return REFERENCE_ROOTS.get() or allowed_roots(clip_path)


def allowed_roots(clip_path: Path, project: Path | None = None) -> list[Path]:
    roots = [clip_path.resolve().parent]
    if project is not None:
        roots.append(project.resolve())
    return roots


def confined(clip_path: Path, reference: str | Path, roots: Sequence[Path], *, what: str) -> Path:
    """``reference`` (relative to the clip's folder) resolved, if it stays inside ``roots``."""
    try:
        target = (clip_path.parent / reference).resolve()
    except (RuntimeError, OSError, ValueError) as error:  # a symlink loop (RuntimeError before 3.13), a NUL
        raise ClipReadError(
            f"cannot follow the {what} {str(reference)!r}: {error}",
            path=clip_path,
            hint="a symlink there points back at itself; point it at the file",
        ) from None
    if not any(target == root or target.is_relative_to(root) for root in roots):
        raise ClipReadError(
            f"the {what} {str(reference)!r} lies outside the project ({target})",
            path=clip_path,
            hint="keep referenced files beside the clip or inside the manifest's folder; "
            "references that leave the project are never read",
        )
    return target


def check_clip_limits(clip: Clip) -> None:
    """Frames, joints, frame rate and value sizes within what a real clip can have."""
    frames, joints = clip.rotations.shape[:2]
    limit = max_frames()
    if frames > limit:
        raise ClipReadError(
            f"clip {clip.name!r} has {frames:,} frames, more than the limit of {limit:,}",
            path=clip.source,
            hint=f"trim the take (or split it), or raise the limit with {MAX_FRAMES_VARIABLE}=<frames>",
        )
    if joints > MAX_JOINTS:
        raise ClipReadError(
            f"clip {clip.name!r} has {joints:,} joints, more than the limit of {MAX_JOINTS:,}",
            path=clip.source,
            hint="export the body skeleton only (no face or cloth joints)",
        )
    if not MIN_FPS <= clip.fps <= MAX_FPS:
        raise ClipReadError(
            f"clip {clip.name!r} has a frame rate of {clip.fps:.6g} fps, outside {MIN_FPS:g}..{MAX_FPS:g}",
            path=clip.source,
            hint="the frame time (BVH 'Frame Time:', USD timeCodesPerSecond) is wrong; "
            "e.g. 'Frame Time: 0.033333' for 30 fps",
        )
    for label, values in (
        ("translation", clip.translations),
        ("rest offset", clip.skeleton.rest_translations),
    ):
        if values.size and float(np.max(np.abs(values))) > MAX_TRANSLATION:
            raise ClipReadError(
                f"clip {clip.name!r}: a {label} is larger than {MAX_TRANSLATION:g} units",
                path=clip.source,
                hint="re-export the clip; such a value is corrupt data, not a body",
            )
