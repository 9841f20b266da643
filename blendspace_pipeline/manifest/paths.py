"""Turn the manifest's `clips:` entries into clip files, without reading them.

Paths and globs are relative to the manifest's folder (absolute paths and `..` work too), and a
backslash counts as a folder separator so a manifest written on Windows builds on Linux CI. The
result is sorted and free of duplicates, so a build does not depend on the order the file system
lists a folder in. Anything that cannot match is an error at the entry's line.
"""

from __future__ import annotations

import contextlib
import difflib
import fnmatch
import glob
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import NoReturn

from blendspace_pipeline.errors import ManifestError
from blendspace_pipeline.manifest.loader import KeyPath, LoadedManifest
from blendspace_pipeline.manifest.models import ClipEntry
from blendspace_pipeline.readers import supported_suffixes

_GLOB_CHARACTERS = re.compile(r"[*?\[]")


@dataclass(frozen=True)
class ResolvedClipFile:
    """One clip file and the manifest entry (and line) it came from."""

    path: Path
    entry: ClipEntry
    entry_index: int
    line: int
    column: int


def resolve_clip_files(
    loaded: LoadedManifest, *, entries: Sequence[ClipEntry] | None = None, key: KeyPath = ("clips",)
) -> list[ResolvedClipFile]:
    """Every clip file of ``entries`` (default: the manifest's `clips:`), each once.

    ``key`` is where ``entries`` sit in the manifest, so a style layer's clips can be resolved
    with ``key=("layers", 0, "clips")`` and still get their own lines in messages.
    """
    entries = loaded.model.clips if entries is None else entries
    matched: list[list[Path]] = []
    missing: list[ManifestError] = []
    for index, entry in enumerate(entries):
        try:
            matched.append(_files_of(loaded, entry, (*key, index)))
        except ManifestError as error:  # every entry that finds nothing, said at once
            missing.append(error)
            matched.append([])
    if missing:
        missing[0].more = list(missing[1:])
        raise missing[0]
    folders: dict[str, str] = {}
    identities = [[_identity(file, folders) for file in files] for files in matched]
    globbed = [_is_glob(loaded, entry) for entry in entries]
    owners = _owners(identities, globbed)

    resolved: list[ResolvedClipFile] = []
    for index, files in enumerate(matched):
        line, column = loaded.locate((*key, index))
        for file, identity in zip(files, identities[index], strict=True):
            # Explicit entries always count: one long take listed twice with two `range:`s is two
            # clips (their names must differ). A glob yields a file to any entry that names it.
            owner = owners[identity]
            if owner == index or (not globbed[index] and not globbed[owner]):
                resolved.append(ResolvedClipFile(file, entries[index], index, line, column))
    return resolved


def _owners(identities: list[list[str]], globbed: list[bool]) -> dict[str, int]:
    """Which entry a file belongs to: the first explicit entry naming it, else the first glob."""
    owners: dict[str, int] = {}
    for index, files in enumerate(identities):
        for identity in files:
            current = owners.get(identity)
            if current is None or (globbed[current] and not globbed[index]):
                owners[identity] = index
    return owners


def _identity(path: Path, folders: dict[str, str]) -> str:
    """The file's real path, as text: two spellings of one file (a symlink, `a/../b`) are one clip.

    A glob's files share a folder, so the folder is resolved once (``folders`` remembers it, by
    its text: no Path is made per file to look it up) and each file costs one `lstat`; resolving
    every path walks every folder above it, per file.
    """
    text = str(path)
    if os.path.islink(text):
        return os.path.normcase(path.resolve())
    folder, name = os.path.split(text)
    real = folders.get(folder)
    if real is None:
        real = folders[folder] = str(path.parent.resolve())
    # normcase: Windows compares paths without case, as Path equality there does.
    return os.path.normcase(os.path.join(real, name))


def _pattern(entry: ClipEntry) -> str:
    return entry.path.replace("\\", "/")


def _absolute(loaded: LoadedManifest, text: str) -> Path:
    return Path(os.path.normpath(loaded.directory / text))


def is_glob_entry(loaded: LoadedManifest, entry: ClipEntry) -> bool:
    """Whether ``entry``'s path is a glob (not a file whose name has glob characters)."""
    return _is_glob(loaded, entry)


def _is_glob(loaded: LoadedManifest, entry: ClipEntry) -> bool:
    text = _pattern(entry)
    # A file really named `walk[1].bvh` is that file, not a character class.
    return bool(_GLOB_CHARACTERS.search(text)) and not _safe_is_file(_absolute(loaded, text))


def _files_of(loaded: LoadedManifest, entry: ClipEntry, key: KeyPath) -> list[Path]:
    text = _pattern(entry)
    if not text.strip():
        _fail(loaded, key, "the clip path is empty", "write a file or a glob, e.g. path: clips/*.bvh")
    if not _is_glob(loaded, entry):
        return [_plain_file(loaded, text, key)]
    files = _glob(loaded, text, key)
    if entry.name is not None and len(files) > 1:
        _fail(
            loaded,
            key,
            f"the entry is named {entry.name!r} but its glob {entry.path!r} matched {len(files)} files",
            f"a name belongs to one clip: drop `name:` or narrow the glob (it matched {_listing(files)})",
        )
    if entry.position is not None and len(files) > 1:  # every clip of the glob had been put there
        _fail(
            loaded,
            key,
            f"the entry places its clip at {list(entry.position)} but its glob {entry.path!r} matched "
            f"{len(files)} files",
            f"a position belongs to one clip: give each clip its own entry (it matched {_listing(files)})",
        )
    return files


def _plain_file(loaded: LoadedManifest, text: str, key: KeyPath) -> Path:
    path = _absolute(loaded, text)
    if len(path.name.encode()) > 255 or len(str(path).encode()) > 4095:
        _fail(
            loaded,
            key,
            f"the clip path is too long for the file system ({len(text)} characters)",
            "file names hold at most 255 bytes; rename the clip file",
        )
    if _safe_is_file(path):
        return path
    if _safe_is_dir(path):
        _fail(
            loaded,
            key,
            f"{text!r} is a folder, not a clip file",
            f"use a glob to take the clips in it, e.g. path: {text.rstrip('/')}/*.bvh",
        )
    _fail(loaded, key, f"clip file {text!r} not found", _missing_hint(path, loaded.directory))


def _missing_hint(path: Path, base: Path | None = None) -> str:
    folder = path.parent
    other_case = _in_other_case(path)
    if other_case is not None:
        try:
            shown = os.path.relpath(other_case, base).replace(os.sep, "/") if base else str(other_case)
        except ValueError:  # another drive (Windows)
            shown = str(other_case)
        return (
            f"did you mean {shown!r}? The names differ in letter case only: Linux (and CI) tell "
            "them apart, Windows and macOS do not"
        )
    if not folder.is_dir():
        existing = next((p for p in folder.parents if p.is_dir()), None)
        return f"the folder {folder} does not exist" + (
            f" (nearest existing folder: {existing})" if existing else ""
        )
    names = sorted(p.name for p in folder.iterdir() if p.is_file())
    close = difflib.get_close_matches(path.name, names, n=3)
    if close:
        return f"did you mean {' or '.join(repr(n) for n in close)}? (looked in {folder})"
    return f"looked in {folder}, which holds: {_listing([folder / n for n in names]) or 'no files'}"


def _in_other_case(path: Path) -> Path | None:
    """The existing file ``path`` names up to letter case (`Clips/Walk.bvh` for `clips/walk.bvh`),
    found from its nearest existing folder down, one unambiguous name at a time; else None."""
    missing: list[str] = []
    found = path
    while not found.exists():
        if found.parent == found:
            return None
        missing.append(found.name)
        found = found.parent
    for name in reversed(missing):
        try:
            matches = [entry for entry in os.listdir(found) if entry.casefold() == name.casefold()]
        except OSError:
            return None
        if len(matches) != 1:
            return None
        found = found / matches[0]
    return found if found.is_file() else None


# A glob visits at most this many folder entries: a clip library is thousands of files, a symlink
# farm or the root of a disk is millions.
MAX_GLOB_ENTRIES = 200_000
BLEND_SPACE_SUFFIXES = (".blendspace.usda", ".blendspace.usd", ".blendspace.usdc")  # the outputs
MAX_CLIP_FILES = 10_000


def _glob(loaded: LoadedManifest, text: str, key: KeyPath) -> list[Path]:
    root, pattern = _split_glob(loaded, text)
    if not _safe_is_dir(root):
        found: list[Path] = []
    elif "**" in pattern:
        found = _walk_glob(loaded, root, pattern, key)
    elif "/" not in pattern:
        found = _folder_files(root, pattern)
    else:
        base = str(root)  # joined as text: one Path per file, not three
        found = [
            Path(os.path.normpath(os.path.join(base, name))) for name in glob.glob(pattern, root_dir=root)
        ]
        found = [p for p in found if os.path.isfile(p)]
    files = sorted(found, key=lambda p: p.as_posix())
    if len(files) > MAX_CLIP_FILES:
        _fail(
            loaded,
            key,
            f"glob {text!r} matched {len(files):,} files, more than the limit of {MAX_CLIP_FILES:,}",
            "narrow the glob to the clips of this blend space",
        )
    readable = set(supported_suffixes())
    # A blend-space asset (`N.blendspace.usda`, this tool's or another manifest's) is no take: a
    # `**/*.usda` glob (of `clips:` or a style layer) reached one where the outputs sit under the
    # manifest's folder but not where this command looks for them (`build --out .`, then
    # `check`), and the run failed.
    clips = [
        p for p in files if p.suffix.lower() in readable and not p.name.lower().endswith(BLEND_SPACE_SUFFIXES)
    ]
    if not clips:
        _fail(
            loaded,
            key,
            f"glob {text!r} matched no {'readable clip ' if files else ''}files",
            _no_match_hint(root, files, readable),
        )
    return clips


def _folder_files(root: Path, pattern: str) -> list[Path]:
    """The files in ``root`` whose names match ``pattern`` (one folder's part of a glob, such as
    `*.bvh`), as `glob` matches them (hidden names only by a pattern that starts with a dot; case
    as the system compares names). The folder listing tells each entry's type, so a library of
    1,000 clips costs no `stat` per file (a symlink is followed: one `stat` for it)."""
    hidden = pattern.startswith(".")
    found: list[Path] = []
    base = str(root)
    try:
        with os.scandir(root) as listing:
            for entry in listing:
                if (hidden or not entry.name.startswith(".")) and fnmatch.fnmatch(entry.name, pattern):
                    with contextlib.suppress(OSError):  # a link to nowhere, a name removed meanwhile
                        if entry.is_file():
                            found.append(Path(os.path.normpath(os.path.join(base, entry.name))))
    except OSError:  # a folder we may not list matches nothing, as with `glob`
        return []
    return found


def _walk_glob(loaded: LoadedManifest, root: Path, pattern: str, key: KeyPath) -> list[Path]:
    """`**` globbing that visits every real folder once.

    `glob.glob(recursive=True)` follows folder symlinks without remembering where it has been, so
    two links to `.` make it walk an exponential tree (a hang). Here each folder is entered once,
    by its resolved path, and hidden names are skipped as glob skips them.
    """
    parts = tuple(p for p in pattern.split("/") if p)
    found: list[Path] = []
    seen: set[Path] = set()
    visited = 0
    pending: list[tuple[Path, tuple[str, ...]]] = [(root, ())]
    while pending:
        folder, relative = pending.pop()
        try:
            real = folder.resolve()
            if real in seen:
                continue
            seen.add(real)
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError:
            continue  # unreadable folder or a loop the resolver refused: nothing to match there
        for entry in entries:
            visited += 1
            if visited > MAX_GLOB_ENTRIES:
                _fail(
                    loaded,
                    key,
                    f"glob {pattern!r} visits more than {MAX_GLOB_ENTRIES:,} folder entries",
                    "start the glob in the clip folder (e.g. clips/**/*.bvh), not at a large tree",
                )
            if entry.name.startswith("."):
                continue
            names = (*relative, entry.name)
            try:
                is_dir = entry.is_dir()
            except OSError:
                continue
            if is_dir:
                pending.append((Path(entry.path), names))
            elif _matches(parts, names):
                found.append(Path(os.path.normpath(entry.path)))
    return found


def searched_folders(loaded: LoadedManifest, entries: Sequence[ClipEntry] | None = None) -> list[Path]:
    """The folders the globs of ``entries`` (default: `clips:`) look in, the root of each even
    when it does not exist yet: a clip added to any of them (also to a sub-folder that held no
    clip) changes its modification time, and a build stamp (`pipeline.stamp`) watches them."""
    folders: list[Path] = []
    for entry in loaded.model.clips if entries is None else entries:
        if not _is_glob(loaded, entry):
            continue
        root, pattern = _split_glob(loaded, _pattern(entry))
        folders.append(root)
        if "**" in pattern:
            folders += _folders_under(root)
        elif "/" in pattern:  # `clips/*/*/walk.bvh`: the folders each leading part matches
            parts = pattern.split("/")[:-1]
            for depth in range(1, len(parts) + 1):
                leading = "/".join(parts[:depth])
                folders += [
                    root / name for name in glob.glob(leading, root_dir=root) if (root / name).is_dir()
                ]
    return folders


def _folders_under(root: Path) -> list[Path]:
    """Every folder below ``root`` a `**` glob enters (each real folder once; hidden ones skipped,
    as `_walk_glob` skips them; at most `MAX_GLOB_ENTRIES` looked at)."""
    found: list[Path] = []
    seen: set[Path] = set()
    pending = [root]
    visited = 0
    while pending and visited <= MAX_GLOB_ENTRIES:
        folder = pending.pop()
        try:
            real = folder.resolve()
            if real in seen:
                continue
            seen.add(real)
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for entry in entries:
            visited += 1
            try:
                if not entry.name.startswith(".") and entry.is_dir():
                    pending.append(Path(entry.path))
                    found.append(Path(entry.path))
            except OSError:
                continue
    return found


def _matches(pattern: tuple[str, ...], names: tuple[str, ...]) -> bool:
    """Whether the path components ``names`` match the glob components (`**` = any folders)."""
    if not pattern:
        return not names
    if pattern[0] == "**":
        return any(_matches(pattern[1:], names[skip:]) for skip in range(len(names) + 1))
    return bool(names) and fnmatch.fnmatchcase(names[0], pattern[0]) and _matches(pattern[1:], names[1:])


def _safe_is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:  # a name longer than the file system allows, a symlink loop
        return False


def _safe_is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except OSError:
        return False


def _split_glob(loaded: LoadedManifest, text: str) -> tuple[Path, str]:
    """The fixed leading folders of a glob, and the rest; only the rest is matched.

    Globbing relative to a fixed root keeps brackets or stars in the manifest's own folder name
    from being read as pattern characters.
    """
    parts = PurePosixPath(text).parts
    fixed = 0
    while fixed < len(parts) - 1 and not _GLOB_CHARACTERS.search(parts[fixed]):
        fixed += 1
    root = _absolute(loaded, str(PurePosixPath(*parts[:fixed]))) if fixed else loaded.directory
    return root, "/".join(parts[fixed:])


def _no_match_hint(root: Path, files: list[Path], readable: set[str]) -> str:
    if not root.is_dir():
        return f"the folder {root} does not exist"
    if files:
        return f"it matched {_listing(files)}; readable formats: {', '.join(sorted(readable))}"
    return f"looked in {root}; check the pattern (`**` matches sub-folders) and the file suffixes"


def _listing(paths: Sequence[Path], limit: int = 5) -> str:
    names = [p.name for p in paths[:limit]]
    return ", ".join(names) + (f" and {len(paths) - limit} more" if len(paths) > limit else "")


def _fail(loaded: LoadedManifest, key: KeyPath, message: str, hint: str) -> NoReturn:
    line, column = loaded.locate((*key, "path"))
    raise ManifestError(message, path=loaded.path, line=line, column=column, hint=hint)
