"""What the last build of a manifest published, as later builds must see it: where its outputs
go, and which clips in its clips folder it placed there (so a glob over that folder, as with
`output.dir: .` and `clips/*.bvh`, does not read them back as authored takes)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from blendspace_pipeline.manifest import LoadedManifest
from blendspace_pipeline.manifest.paths import ResolvedClipFile, is_glob_entry
from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.pipeline.cache import file_sha256

GENERATIONS = ".blendspace"  # OUT/.blendspace/<space>/g-<hash>/: one folder per published set
CURRENT = "current"  # OUT/.blendspace/<space>/current -> the published generation
# Each generation's record of the clips it placed in the clips folder, with their SHA-256: a
# placed clip is a hard link to the generation's file, so an edit in place changes both; this
# record is what tells a later build that the clip is no longer the one it placed.
PLACED = ".placed.json"


def output_folder(loaded: LoadedManifest, out: Path | None) -> Path:
    """Where ``loaded``'s outputs go: ``out`` (--out) when given, else its `output.dir`."""
    if out is not None:
        return out
    configured = Path(loaded.model.output.dir.replace("\\", "/"))
    return configured if configured.is_absolute() else loaded.directory / configured


def placed_clips(out_dir: Path, space_name: str) -> set[tuple[int, int]]:
    """(device, inode) of each clip the published generation of ``space_name`` placed under
    ``out_dir`` that is still that file with those bytes. Empty when there is no such record."""
    generation = out_dir / GENERATIONS / safe_file_stem(space_name) / CURRENT
    try:
        placed = json.loads((generation / PLACED).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set()
    found: set[tuple[int, int]] = set()
    for relative, digest in placed.items() if isinstance(placed, dict) else ():
        target = out_dir / relative
        try:
            if os.path.samefile(target, generation / relative) and file_sha256(target) == digest:
                info = target.stat()
                found.add((info.st_dev, info.st_ino))
        except (OSError, TypeError):
            continue
    return found


def authored(
    loaded: LoadedManifest, files: list[ResolvedClipFile], out: Path | None
) -> list[ResolvedClipFile]:
    """``files`` without the clips the last build of this manifest placed, where a glob matched
    them. A clip named by its own entry stays a source (a build never overwrites it), and one the
    user edited or saved anew is theirs."""
    if not any(is_glob_entry(loaded, f.entry) for f in files):
        return files
    placed = placed_clips(output_folder(loaded, out), loaded.model.name)
    if not placed:
        return files
    kept = []
    for resolved in files:
        try:
            info = resolved.path.stat()
        except OSError:
            kept.append(resolved)
            continue
        if (info.st_dev, info.st_ino) in placed and is_glob_entry(loaded, resolved.entry):
            continue
        kept.append(resolved)
    return kept
