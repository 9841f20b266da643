"""`check --changed FILE...`: from the files a commit changes to the manifests to check.

pre-commit passes the changed files that match the hook's `files:` pattern: manifests, layer
manifests, clip files and their companions. A manifest is checked when it changed or when any
file it reads changed (a clip, a style layer's clip, a beta layer's manifest or that manifest's
clips). A layer manifest is checked through the manifest that uses it. Manifests are found under
the current folder (pre-commit runs at the repository root): YAML files that say
`schema_version:` at the top level. Only paths are resolved here; no clip is read.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.manifest import load_manifest
from blendspace_pipeline.manifest.models import BetaLayer, ClipEntry, StyleLayer
from blendspace_pipeline.manifest.paths import resolve_clip_files

_YAML = (".yaml", ".yml")
_MANIFEST_MARK = re.compile(rb"^schema_version\s*:", re.MULTILINE)
_SKIP_FOLDERS = {".git", ".hg", ".svn", "node_modules", "__pycache__", ".blendspace"}
MAX_MANIFEST_BYTES = 1024 * 1024
MAX_SCANNED_FILES = 200_000


def looks_like_manifest(path: Path) -> bool:
    try:
        if path.suffix.lower() not in _YAML or not path.is_file() or path.stat().st_size > MAX_MANIFEST_BYTES:
            return False
        return bool(_MANIFEST_MARK.search(path.read_bytes()))
    except OSError:
        return False


def find_manifests(root: Path) -> list[Path]:
    found: list[Path] = []
    scanned = 0
    for folder, folders, files in os.walk(root):  # never follows folder symlinks: no loops
        folders[:] = sorted(f for f in folders if f not in _SKIP_FOLDERS and not f.startswith(".blendspace"))
        for name in sorted(files):
            scanned += 1
            if scanned > MAX_SCANNED_FILES:
                return found
            path = Path(folder) / name
            if looks_like_manifest(path):
                found.append(path)
    return found


def _key(path: Path) -> Path:
    try:
        return path.resolve()
    except OSError:
        return Path(os.path.abspath(path))


def inputs_of(manifest: Path, depth: int = 0) -> tuple[set[Path], set[Path], list[str]]:
    """(every file ``manifest`` reads, its beta layers' manifests, the absolute path patterns its
    clip entries name); just itself if it does not load. A clip list with a missing file still
    names its patterns: a deleted clip is a change to the manifest that named it."""
    files = {_key(manifest)}
    layers: set[Path] = set()
    patterns: list[str] = []
    try:
        loaded = load_manifest(manifest)
    except InputError:
        return files, layers, patterns  # `check` reports it; a broken manifest reads itself
    lists: list[tuple[list[ClipEntry] | None, tuple[str | int, ...]]] = [(None, ("clips",))]
    for index, layer in enumerate(loaded.model.layers):
        if isinstance(layer, StyleLayer):
            entries = [ClipEntry(path=c) if isinstance(c, str) else c for c in layer.clips]
            lists.append((entries, ("layers", index, "clips")))
        elif isinstance(layer, BetaLayer) and depth < 8:
            beta = loaded.directory / layer.manifest.replace("\\", "/")
            layers.add(_key(beta))
            beta_files, _, beta_patterns = inputs_of(beta, depth + 1)
            files |= beta_files
            patterns += beta_patterns
    for listed, key in lists:
        named = loaded.model.clips if listed is None else listed
        patterns += [os.path.abspath(loaded.directory / e.path.replace("\\", "/")) for e in named]
        with contextlib.suppress(InputError):  # a missing clip: `check` reports it
            files |= {_key(f.path) for f in resolve_clip_files(loaded, entries=listed, key=key)}
    # A .gltf's buffer is usually `<stem>.bin` beside it (Blender's "glTF Separate" export).
    files |= {f.with_suffix(".bin") for f in files if f.suffix.lower() == ".gltf"}
    return files, layers, patterns


def manifests_for(changed: Sequence[Path], root: Path) -> list[Path]:
    """The manifests to check for ``changed`` files, in a stable order. A changed file that is
    gone (deleted, renamed away) selects the manifests whose clip entries name it."""
    wanted = {_key(p) for p in changed}
    gone = [os.path.abspath(p) for p in changed if not os.path.lexists(p)]
    selected: dict[Path, Path] = {}
    layer_of_selected: set[Path] = set()
    candidates = find_manifests(root)
    candidates += [
        p for p in changed if looks_like_manifest(p) and _key(p) not in {_key(c) for c in candidates}
    ]
    for manifest in candidates:
        files, layers, patterns = inputs_of(manifest)
        if files & wanted or any(_names(pattern, path) for pattern in patterns for path in gone):
            selected[_key(manifest)] = manifest
            layer_of_selected |= layers
    return [path for key, path in selected.items() if key not in layer_of_selected]


def _names(pattern: str, path: str) -> bool:
    """Whether a clip entry's absolute ``pattern`` (a path or a glob) names ``path``. Case folded
    where the file system does (Windows); a `*` may match across folders here, which only checks
    a manifest more often."""
    path, pattern = os.path.normcase(path), os.path.normcase(pattern)
    return path == pattern or fnmatch.fnmatch(path, pattern)  # `walk[1].bvh` is also that file


def relative_names(paths: Iterable[Path], root: Path) -> list[Path]:
    out = []
    for path in paths:
        try:
            out.append(path.relative_to(root))
        except ValueError:
            out.append(path)
    return out
