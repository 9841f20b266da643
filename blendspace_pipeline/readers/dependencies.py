"""The other files a clip file is read with: what its bytes alone do not pin.

A USD clip may compose other layers (sublayers, references, payloads: a USD pipeline's animation
layer under a thin shot file) and a `.gltf` keeps its animation in external `.bin` buffers. The
measurement cache and the build stamp had keyed such a clip on its own file only, so an edited
layer or buffer kept the old measurement (even with the stamps deleted). They key on these too.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from urllib.parse import unquote

USD_SUFFIXES = frozenset({".usd", ".usda", ".usdc"})  # a .usdz packs its layers in its own bytes


def file_dependencies(path: Path) -> list[Path]:
    """Absolute paths of the files ``path`` is read with besides itself (sorted; a file named but
    missing is listed too: creating it changes the clip); [] for formats that keep one file."""
    suffix = path.suffix.lower()
    if suffix == ".gltf":
        found = _gltf_buffers(path)
    elif suffix in USD_SUFFIXES:
        found = _usd_layers(path)
    else:
        return []
    own = os.path.normcase(os.path.abspath(path))
    unique = {os.path.normcase(os.path.abspath(p)): Path(os.path.abspath(p)) for p in found}
    unique.pop(own, None)
    return sorted(unique.values(), key=lambda p: p.as_posix())


def _gltf_buffers(path: Path) -> list[Path]:
    """The external buffers (`buffers[].uri` that is no `data:` URI), relative to the file."""
    try:
        document = json.loads(path.read_bytes())
        buffers = document.get("buffers") or []
    except (OSError, ValueError, AttributeError):
        return []  # the reader reports what is wrong with the file
    uris = [b.get("uri") for b in buffers if isinstance(b, dict)]
    return [
        path.parent / unquote(uri)
        for uri in uris
        if isinstance(uri, str) and uri and not uri.startswith("data:")
    ]


def _usd_layers(path: Path) -> list[Path]:
    """Every layer and asset the stage composes from ``path`` (sublayers, references, payloads,
    recursively: `UsdUtils.ComputeAllDependencies`), and the ones it cannot find."""
    try:
        from pxr import Sdf, UsdUtils

        layers, assets, unresolved = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(str(path)))
    except Exception:  # an unreadable stage: the reader reports it
        return []
    found = [Path(layer.realPath) for layer in layers if layer.realPath]
    found += [Path(asset) for asset in assets if asset]
    found += [path.parent / text for text in unresolved if text and "://" not in text]
    return found
