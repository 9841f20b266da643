"""The other files a clip file is read with: what its bytes alone do not pin.

A USD clip may compose other layers (sublayers, references, payloads: a USD pipeline's animation
layer under a thin shot file) and a `.gltf` keeps its animation in external `.bin` buffers. The
measurement cache and the build stamp had keyed such a clip on its own file only, so an edited
layer or buffer kept the old measurement (even with the stamps deleted). They key on these too.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path
from urllib.parse import unquote

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.readers.limits import allowed_roots, check_regular, confined, read_regular_file

USD_SUFFIXES = frozenset({".usd", ".usda", ".usdc"})  # a .usdz packs its layers in its own bytes


def file_dependencies(
    path: Path, project: Path | None = None, keep: list[object] | None = None
) -> list[Path]:
    """Absolute paths of the files ``path`` is read with besides itself (sorted; a file named but
    missing is listed too: creating it changes the clip); [] for formats that keep one file.
    Only files the readers may open count (inside the clip's folder or ``project``, the
    manifest's: `limits.confined`); a reference elsewhere is reported when the clip is read.
    ``keep``: receives what was opened to find them (USD layers), for the caller to hold while it
    reads the clip."""
    suffix = path.suffix.lower()
    if suffix in (".gltf", ".glb"):  # a GLB's buffers may name files too (the reader follows them)
        found = _gltf_buffers(path, project)
    elif suffix in USD_SUFFIXES:
        from blendspace_pipeline.readers.usd import composed_layers

        found = composed_layers(path, project, keep)
    else:
        return []
    own = os.path.normcase(os.path.abspath(path))
    unique = {os.path.normcase(os.path.abspath(p)): Path(os.path.abspath(p)) for p in found}
    unique.pop(own, None)
    return sorted(unique.values(), key=lambda p: p.as_posix())


def _gltf_buffers(path: Path, project: Path | None) -> list[Path]:
    """The external buffers (`buffers[].uri` that is no `data:` URI), relative to the file."""
    try:
        check_regular(path, what="glTF file")
        document = json.loads(
            _glb_json(path) if path.suffix.lower() == ".glb" else read_regular_file(path, what="glTF file")
        )
        buffers = document.get("buffers") or []
    except (ClipReadError, OSError, ValueError, AttributeError, RecursionError):
        return []  # the reader reports what is wrong with the file
    roots = allowed_roots(path, project)
    found = []
    for buffer in buffers:
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if not isinstance(uri, str) or not uri or uri.startswith("data:"):
            continue
        try:
            found.append(confined(path, unquote(uri), roots, what="glTF buffer"))
        except (ClipReadError, OSError, ValueError, RuntimeError):  # RuntimeError: a symlink loop
            continue
    return found


def _glb_json(path: Path) -> bytes:
    """The JSON chunk of a binary glTF (its first chunk), read without the binary one."""
    with open(path, "rb") as stream:
        header = stream.read(20)
        if len(header) < 20 or header[:4] != b"glTF" or header[16:20] != b"JSON":
            return b"{}"
        length = struct.unpack_from("<I", header, 12)[0]
        if length > MAX_GLB_JSON_BYTES:
            return b"{}"
        return stream.read(length)


MAX_GLB_JSON_BYTES = 256 * 1024**2  # the reader refuses more
