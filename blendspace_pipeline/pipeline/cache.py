"""Content-addressed measurement cache, so repeated checks (pre-commit, CI) skip clip parsing.

A file's measurements are stored under the SHA-256 of its bytes and name, the tool version, the rig
settings and the trim range: touching a clip, upgrading the tool or changing `skeleton:`
invalidates exactly what it must. Location: `BLENDSPACE_CACHE_DIR`, else the user cache folder.
Writes are atomic; a corrupt or unreadable entry is ignored and rewritten.
"""

from __future__ import annotations

import hashlib
import os
import stat
import tempfile
import time
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from blendspace_pipeline import __version__

if TYPE_CHECKING:  # numpy and the measurement code load only when an entry is read
    from blendspace_pipeline.motion.measure import Measurement


def cache_dir() -> Path | None:
    """Where entries live, or None when caching is switched off (`BLENDSPACE_CACHE_DIR=off`)."""
    configured = os.environ.get("BLENDSPACE_CACHE_DIR")
    if configured is not None:
        return None if configured.lower() in ("", "off", "0", "none") else Path(configured)
    base = os.environ.get("XDG_CACHE_HOME") or os.environ.get("LOCALAPPDATA") or str(Path.home() / ".cache")
    return Path(base) / "blendspace-pipeline"


# A store written by `blendspace index` (a folder or fsspec URL), read when the local cache misses.
LIBRARY_VARIABLE = "BLENDSPACE_LIBRARY_STORE"


# Bumped whenever the same clip would measure differently (a new feature, a changed detection),
# so a developer's or CI's cache never serves results of older code under an unchanged version.
# 3: detection from the body, sway-free heading; 4: foot contacts and plant phases;
# 5: readers refuse out-of-range data (frame rate, angles, sizes) that earlier revisions measured;
# 6: an assumed facing of a track set without hierarchy (Godot) is a detection guess, and a clip
# travelling under 1 mm/s has direction 0 (not the angle of its drift); 7: the joints' parents
# (`joint_parents`), so `inconsistent-skeleton` sees another hierarchy; 8: the stride-sway fit
# keeps the facing's mean (direction, forward and lateral speed were off by up to 17 deg); 9: a
# stepping clip with no whole stride says so (`partial_stride`), and a file's unit that makes the
# legs no body's is a `units` guess; 10: a guess records whether the value was stated (`stated`);
# 11: the feet check the hip line (swapped labels, mirrored exports), more naming schemes find
# the hips, stated forward / root / units the body contradicts are doubted, a moving fallback root;
# 12: the knees (then the toes) are the legs' witness, net extent for roots, a child's unit noted;
# 13: a file's up axis the body contradicts is doubted, root motion faster than any body is doubted,
# a single-frame pose among a file's animations is left out; 14: a root that jumps in one frame;
# 15: keys held at either end (a scene range longer than the action) are left out, and the hips of
# rigs whose names say nothing are found by the skeleton's shape; 16: the same, as finished (15 was
# used by intermediate versions of it, whose caches must not be read); 17: nameless rigs whose rest
# pose is an exported frame (armature-only FBX, Blender USD) find their legs, the moving ones first;
# 18: the same where every joint moves, both legs of a pair moving, and a stated range's note on the
# held keys it keeps (17 was used by intermediate versions); 19: a posed frame's legs outrank a
# moving coat's chains (feet before none, both looks ranked together); 20: glTF key times rounded
# to a few decimals read at their rate, a clip an earlier build made is read `tpose: keep`; 21: the
# same as finished (glTF keys half a second apart are poses; 20 was used by intermediate versions);
# 22: `up_source` (a file's stated axis is not pooled), unit and `range: auto` doubts; 23: foot
# contacts on slopes, stairs and in-place clips.
MEASUREMENT_REVISION = 23


def cache_key(
    path: Path,
    settings_key: str,
    time_range: tuple[float, float] | str | None,
    digest_of_file: str | None = None,
) -> str:
    """The entry of one file's measurements; ``digest_of_file`` saves hashing when it is known."""
    digest = hashlib.sha256((digest_of_file or content_digest(path)).encode())
    # The file name too: clips are named after it, so two copies of one take must not share names.
    digest.update(f"|{path.name}|{__version__}|{MEASUREMENT_REVISION}|{settings_key}|{time_range!r}".encode())
    return digest.hexdigest()


def dependency_state(paths: list[Path]) -> list[list[str]]:
    """Each dependency of a clip file (`readers.dependencies`) as [path, stat key, digest], with
    "" for the stat key and digest of one that does not exist."""
    state = []
    for path in paths:
        try:
            info = path.stat()
        except OSError:
            state.append([str(path), "", ""])
            continue
        if not stat.S_ISREG(info.st_mode) or info.st_size > MAX_DEPENDENCY_BYTES:
            # A buffer at /dev/zero, a FIFO, or one past what the readers take: never read (the
            # reader says why; a 16 GiB sparse buffer was hashed for 22 s first).
            state.append([str(path), stat_key(path, info), "not read"])
            continue
        state.append([str(path), stat_key(path, info), content_digest(path)])
    return state


def known_dependencies(
    path: Path, digest: str, project: Path | None, find: Callable[[], list[Path]]
) -> list[list[str]]:
    """The `dependency_state` of a clip file's dependencies (``find`` lists them:
    `readers.dependencies.file_dependencies`), the list remembered by the file's content, path and
    project: a clip whose measurements the cache holds is not parsed again only to list them (a
    USD clip's walk opens every layer, a glTF is read whole). The list holds while every file on
    it reads the same: a listed layer that names one more file has another digest."""
    folder = cache_dir()
    entry = None
    if folder is not None:
        where = f"{digest}|{os.path.abspath(path)}|{project and os.path.abspath(project)}|{__version__}|{MEASUREMENT_REVISION}"
        entry = folder / "dependencies" / f"{hashlib.sha256(where.encode()).hexdigest()}.json"
        try:
            known = loads(entry.read_bytes())
            state = dependency_state([Path(p) for p in known["paths"]])
            if state == known["state"]:
                return state
        except (OSError, ValueError, KeyError, TypeError):
            pass
    paths = find()
    state = dependency_state(paths)
    if entry is not None:
        write_atomic(entry, dumps({"paths": [str(p) for p in paths], "state": state}))
    return state


MAX_DEPENDENCY_BYTES = 2 * 1024**3  # the readers' own limit (`readers.limits.MAX_FILE_BYTES`)


def dependency_settings(settings_key: str, state: list[list[str]]) -> str:
    """``settings_key`` with a clip's dependencies' contents (`dependency_state`), for its cache
    key: the same file read with another layer or buffer is another entry. Unchanged without
    dependencies, so single-file clips keep their entries."""
    if not state:
        return settings_key
    digest = hashlib.sha256("\n".join(f"{path}|{digest}" for path, _, digest in state).encode())
    return f"{settings_key}|dependencies:{digest.hexdigest()}"


def _settled_key(key: str) -> bool:
    """`settled` for a `stat_key` (path|size|mtime|inode); a missing file ("") has nothing to settle."""
    if not key:
        return True
    try:
        mtime_ns = int(key.rsplit("|", 3)[2])
    except (IndexError, ValueError):
        return False
    return time.time_ns() - mtime_ns > 2_000_000_000


def dependencies_moved(state: list[list[str]]) -> bool:
    """Whether any dependency's stat moved since ``state`` was taken (or one appeared or went)."""
    for path, known, _ in state:
        try:
            info = os.stat(path)
        except OSError:
            if known:
                return True
            continue
        if stat_key(Path(path), info) != known:
            return True
    return False


def stat_key(path: Path, info: os.stat_result) -> str:
    """What identifies one version of a file without reading it."""
    return f"{path.absolute()}|{info.st_size}|{info.st_mtime_ns}|{info.st_ino}"


def settled(info: os.stat_result) -> bool:
    """A file modified in the last seconds may change again within the clock's granularity with
    the same size (git's "racy" case): its digest is remembered only once its mtime has settled."""
    return time.time_ns() - info.st_mtime_ns > 2_000_000_000


# Digests this process has computed or read, by stat key: the build's stamp asks for the digests
# the measure stage (or its workers, through the pack) already knows.
_KNOWN_DIGESTS: dict[str, str] = {}
# Smaller files are hashed again rather than remembered on disk: creating a memo file costs more
# (about a millisecond on common file systems) than hashing a few megabytes.
MEMO_MIN_BYTES = 4 << 20


def content_digest(path: Path) -> str:
    """SHA-256 of the file's bytes, remembered by (path, size, mtime, inode): a file whose stat did
    not move is not read again, so a rebuild after one edit hashes one clip, not the library."""
    info = path.stat()
    stat_key_ = stat_key(path, info)
    if stat_key_ in _KNOWN_DIGESTS:
        return _KNOWN_DIGESTS[stat_key_]
    folder = cache_dir()
    entry = None
    if folder is not None and info.st_size >= MEMO_MIN_BYTES:
        entry = folder / "digests" / f"{hashlib.sha256(stat_key_.encode()).hexdigest()}.txt"
        try:
            return entry.read_text(encoding="ascii").strip()
        except OSError:
            pass
    value = file_sha256(path)
    if settled(info):
        remember_digest(stat_key_, value)
        if entry is not None:
            write_atomic(entry, value)
    return value


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, read in 1 MiB blocks (no memo: see `content_digest`)."""
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def forget_digests() -> None:
    """Drop the digests this process knows (benchmarks time runs as if each were the first)."""
    _KNOWN_DIGESTS.clear()


def remember_digest(key: str, digest: str) -> None:
    """Note a settled file's digest for the rest of this process (see `_KNOWN_DIGESTS`)."""
    _KNOWN_DIGESTS[key] = digest


def dumps(value: Any) -> str:
    """Compact JSON of plain data (dicts, lists, str, numbers, None), as `json.loads` reads it back,
    serialised by pydantic-core (Rust): a 1,000-clip pack in 9 ms instead of `json.dumps`' 43 ms.
    Imported here: the no-op path (`stamp.replay`) never needs it."""
    import pydantic_core

    return pydantic_core.to_json(value).decode("utf-8")


def loads(data: bytes) -> Any:
    """JSON parsed by pydantic-core (a 1,000-clip pack in 16 ms instead of 35); ValueError when it
    is not JSON."""
    import pydantic_core

    return pydantic_core.from_json(data)


def write_atomic(target: Path, text: str) -> None:
    """Write a cache folder's file in one rename; a folder that refuses (read-only, full) is
    ignored: a cache must never fail a build."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=target.parent, suffix=".tmp")
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(temporary, target)
    except OSError:
        pass


def load(key: str) -> list[tuple[str, Measurement]] | None:
    folder = cache_dir()
    if folder is None:
        return None
    try:
        return from_json(loads((folder / f"{key}.json").read_bytes()))
    except (OSError, ValueError):
        return None


def from_json(entries: Any) -> list[tuple[str, Measurement]] | None:
    """Stored entries as measurements; None for anything an older or damaged entry holds."""
    from blendspace_pipeline.motion.measure import Measurement

    try:
        return [(entry["name"], Measurement(**entry["measurement"])) for entry in entries]
    except (KeyError, TypeError, ValueError):
        return None


def to_json(measured: list[tuple[str, Measurement]]) -> list[dict[str, Any]]:
    return [{"name": name, "measurement": _plain(m)} for name, m in measured]


def _plain(value: Any) -> Any:
    """`dataclasses.asdict` without its deep copy (10,000 measurements: 3 s -> 0.1 s): the result
    is only serialised, never mutated, so the measurement's own lists and dicts are shared."""
    if is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, list) and value and is_dataclass(value[0]):
        return [_plain(item) for item in value]
    return value


def store(key: str, measured: list[tuple[str, Measurement]]) -> None:
    folder = cache_dir()
    if folder is not None:
        write_atomic(folder / f"{key}.json", dumps(to_json(measured)))


class Pack:
    """Everything one manifest's last run measured, in one file beside the per-clip entries.

    A warm run of a 10,000-clip manifest would otherwise open two small files per clip (its
    digest memo and its entry): 20,000 opens, seconds on a network home folder. The pack holds
    the run's stat keys -> content digests and cache keys -> entries, so a clip whose stat did not
    move costs one `stat` and a dictionary lookup. It is only a shortcut: a miss falls back to the
    per-clip cache, and the pack is rewritten (atomically) with exactly what the run used, so it
    never grows past one manifest's clips.
    """

    def __init__(self, owner: Path, part: str = "clips") -> None:
        folder = cache_dir()
        name = hashlib.sha256(
            f"{Path(owner).absolute()}|{part}|{__version__}|{MEASUREMENT_REVISION}".encode()
        )
        self.path = None if folder is None else folder / "packs" / f"{name.hexdigest()}.json"
        self.digests: dict[str, str] = {}
        self.entries: dict[str, Any] = {}
        # Per stat key of a clip file with dependencies: their `dependency_state`.
        self.dependencies: dict[str, list[list[str]]] = {}
        self.used_digests: dict[str, str] = {}
        self.used_entries: dict[str, Any] = {}
        self.used_dependencies: dict[str, list[list[str]]] = {}
        if self.path is not None:
            try:
                stored = loads(self.path.read_bytes())
                self.digests, self.entries = dict(stored["digests"]), dict(stored["entries"])
                self.dependencies = dict(stored.get("dependencies") or {})
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                pass  # no pack yet, or a damaged one: the per-clip cache still answers

    def digest(self, path: Path, info: os.stat_result) -> str | None:
        return self.digests.get(stat_key(path, info))

    def dependencies_of(self, path: Path, info: os.stat_result) -> list[list[str]] | None:
        """The `dependency_state` the last run read ``path`` with ([] for none), or None when
        one of those files moved since (the clip is read again)."""
        state = self.dependencies.get(stat_key(path, info), [])
        return None if dependencies_moved(state) else state

    def load(self, key: str) -> list[tuple[str, Measurement]] | None:
        stored = self.entries.get(key)
        return None if stored is None else from_json(stored)

    def remember(
        self,
        path: Path,
        info: os.stat_result,
        digest: str,
        key: str,
        measured: list[tuple[str, Measurement]],
        dependencies: list[list[str]] | None = None,
    ) -> None:
        # A file (or a dependency) modified in the last seconds may change again with the same
        # size and mtime: remembered only once all of them have settled.
        if settled(info) and all(_settled_key(known) for _, known, _ in dependencies or []):
            known = stat_key(path, info)
            self.used_digests[known] = digest
            remember_digest(known, digest)
            if dependencies:
                self.used_dependencies[known] = dependencies
        self.used_entries[key] = self.entries[key] if key in self.entries else to_json(measured)

    def save(self) -> None:
        """Write what this run used, unless it is what the pack already holds."""
        if self.path is None or (
            self.used_digests == self.digests
            and self.used_entries.keys() == self.entries.keys()
            and self.used_dependencies == self.dependencies
        ):
            return
        stored = {"digests": self.used_digests, "entries": self.used_entries}
        if self.used_dependencies:
            stored["dependencies"] = self.used_dependencies
        write_atomic(self.path, dumps(stored))
