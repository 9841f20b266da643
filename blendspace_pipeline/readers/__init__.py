"""Clip readers, one adapter module per format, chosen by file suffix.

Each adapter module exposes ``SUFFIXES`` (lower-case, with the dot) and
``read(path: Path) -> list[Clip]`` returning one clip per animation in the file. Adapters raise
`ClipReadError` with a path, a line when the format has lines, and a hint.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.clip import Clip, validate_clip
from blendspace_pipeline.readers.limits import (
    REFERENCE_ROOTS,
    allowed_roots,
    check_clip_limits,
    check_regular,
)

# Module names, not imports: an adapter's heavy dependency (pxr) loads only when used.
_ADAPTERS = {
    ".bvh": "bvh",
    ".usd": "usd",
    ".usda": "usd",
    ".usdc": "usd",
    ".usdz": "usd",
    ".gltf": "gltf",
    ".glb": "gltf",
    ".tres": "godot_tres",
    ".fbx": "fbx",  # needs the optional pufbx package; the adapter says how to install it
}

_NOT_READABLE = {
    ".ma": "Maya scenes need Maya to evaluate",
    ".mb": "Maya scenes need Maya to evaluate",
    ".blend": "Blender files need Blender to evaluate",
}


def supported_suffixes() -> list[str]:
    return sorted(_ADAPTERS)


def adapter_for(path: Path) -> ModuleType:
    suffix = path.suffix.lower()
    if suffix in _ADAPTERS:
        return importlib.import_module(f"blendspace_pipeline.readers.{_ADAPTERS[suffix]}")
    formats = ", ".join(supported_suffixes())
    if suffix in _NOT_READABLE:
        raise ClipReadError(
            f"{_NOT_READABLE[suffix]}",
            path=path,
            hint=f"export the clip from your DCC as glTF/GLB, USD (UsdSkel) or BVH; readable: {formats}",
        )
    raise ClipReadError(
        f"unsupported clip format {suffix or '(no suffix)'!r}",
        path=path,
        hint=f"readable formats: {formats}",
    )


def read_clips(path: Path, *, project: Path | None = None) -> list[Clip]:
    """All animations in ``path`` as validated clips, within the limits of `limits`.

    Files the clip refers to (glTF buffers, USD layers) are read only inside the clip's own folder
    tree or the ``project`` folder (the manifest's; `limits.confined`).
    """
    adapter = adapter_for(path)
    try:
        exists = path.is_file()
    except OSError:  # a name too long for the file system, a loop of symlinks
        exists = False
    if not exists:
        raise ClipReadError("clip file not found", path=path, hint="check the path in the manifest")
    check_regular(path, what="clip file")
    roots = allowed_roots(path, project)
    token = REFERENCE_ROOTS.set(roots)
    try:
        clips: list[Clip] = adapter.read(path)
    finally:
        REFERENCE_ROOTS.reset(token)
    if not clips:
        raise ClipReadError("file holds no animation", path=path, hint="export at least one animation")
    for clip in clips:
        validate_clip(clip)
        check_clip_limits(clip)
    return clips
