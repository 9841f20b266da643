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
    # `~` is the user's home folder (a folder literally named `~` is never what was meant).
    configured = Path(loaded.model.output.dir.replace("\\", "/")).expanduser()
    return configured if configured.is_absolute() else loaded.directory / configured


def placed_record(generation: Path) -> dict[str, str]:
    """``generation``'s record of the clips it placed: relative path -> SHA-256 (empty without
    one: an older generation, or none)."""
    try:
        placed = json.loads((generation / PLACED).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in placed.items()} if isinstance(placed, dict) else {}


def still_placed(target: Path, generation: Path, relative: str, digest: str) -> bool:
    """Whether ``target`` is still the clip ``generation`` placed there: the same file (a hard
    link into the generation) with the same bytes (an edit in place changes both links)."""
    try:
        return os.path.samefile(target, generation / relative) and file_sha256(target) == digest
    except OSError:
        return False


def authored(
    loaded: LoadedManifest, files: list[ResolvedClipFile], out: Path | None
) -> list[ResolvedClipFile]:
    """``files`` without the clips the last build of this manifest placed, where a glob matched
    them. A clip named by its own entry stays a source (a build never overwrites it), and one the
    user edited or saved anew is theirs. Costs a read of the record and a stat per globbed file;
    a clip is hashed only when a glob reached it."""
    # Asked once per manifest entry, not per file (each asking stats the entry's pattern).
    glob_entry: dict[int, bool] = {}
    for f in files:
        if id(f.entry) not in glob_entry:
            glob_entry[id(f.entry)] = is_glob_entry(loaded, f.entry)
    globbed = {i for i, f in enumerate(files) if glob_entry[id(f.entry)]}
    if not globbed:
        return files
    # The folders a build of this manifest may have placed these clips in: this command's output
    # folder, and the one above each globbed clip's folder (`<out>/clips/`, a beta layer's
    # `<out>/clips/<layer>/`): a `build --out .` places its clips beside the sources, and a later
    # `check` (which looks in `output.dir`) had read its mirror as a take.
    homes = {output_folder(loaded, out)}
    for index in globbed:
        folder = files[index].path.parent
        homes |= {folder.parent, folder.parent.parent}
    placed: dict[tuple[int, int], tuple[Path, Path, str, str]] = {}
    for out_dir in sorted(homes, key=lambda p: p.as_posix()):
        generation = out_dir / GENERATIONS / safe_file_stem(loaded.model.name) / CURRENT
        for relative, digest in placed_record(generation).items():
            try:
                info = (out_dir / relative).stat()
            except OSError:
                continue
            placed.setdefault((info.st_dev, info.st_ino), (out_dir, generation, relative, digest))
    if not placed:
        return files
    kept = []
    for index, resolved in enumerate(files):
        try:
            info = resolved.path.stat()
        except OSError:
            kept.append(resolved)
            continue
        mine = placed.get((info.st_dev, info.st_ino)) if index in globbed else None
        if mine is not None and still_placed(mine[0] / mine[2], mine[1], mine[2], mine[3]):
            continue
        kept.append(resolved)
    return kept
