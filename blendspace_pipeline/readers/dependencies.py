"""The other files a clip file is read with: what its bytes alone do not pin.

A USD clip may compose other layers (sublayers, references, payloads: a USD pipeline's animation
layer under a thin shot file) and a `.gltf` keeps its animation in external `.bin` buffers. The
measurement cache and the build stamp had keyed such a clip on its own file only, so an edited
layer or buffer kept the old measurement (even with the stamps deleted). They key on these too.
"""

from __future__ import annotations

import os
from pathlib import Path

USD_SUFFIXES = frozenset({".usd", ".usda", ".usdc"})  # a .usdz packs its layers in its own bytes


def may_have_dependencies(path: Path) -> bool:
    """Whether files of ``path``'s format can be read with others (USD layers, glTF buffers)."""
    return path.suffix.lower() in _GLTF_SUFFIXES or path.suffix.lower() in USD_SUFFIXES


_GLTF_SUFFIXES = frozenset({".gltf", ".glb"})


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
    if suffix in _GLTF_SUFFIXES:  # a GLB's buffers may name files too (the reader follows them)
        from blendspace_pipeline.readers.gltf import buffer_files

        found = buffer_files(path, project)
    elif suffix in USD_SUFFIXES:
        from blendspace_pipeline.readers.usd import composed_layers

        found = composed_layers(path, project, keep)
    else:
        return []
    own = os.path.normcase(os.path.abspath(path))
    unique = {os.path.normcase(os.path.abspath(p)): Path(os.path.abspath(p)) for p in found}
    unique.pop(own, None)
    return sorted(unique.values(), key=lambda p: p.as_posix())
