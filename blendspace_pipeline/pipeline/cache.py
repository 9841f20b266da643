"""Content-addressed measurement cache, so repeated checks (pre-commit, CI) skip clip parsing.

A file's measurements are stored under the SHA-256 of its bytes and name, the tool version, the rig
settings and the trim range: touching a clip, upgrading the tool or changing `skeleton:`
invalidates exactly what it must. Location: `BLENDSPACE_CACHE_DIR`, else the user cache folder.
Writes are atomic; a corrupt or unreadable entry is ignored and rewritten.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from dataclasses import asdict
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


# Bumped whenever the same clip would measure differently (a new feature, a changed detection),
# so a developer's or CI's cache never serves results of older code under an unchanged version.
# 3: detection from the body, sway-free heading; 4: foot contacts and plant phases;
# 5: readers refuse out-of-range data (frame rate, angles, sizes) that earlier revisions measured.
MEASUREMENT_REVISION = 5


def cache_key(path: Path, settings_key: str, time_range: tuple[float, float] | str | None) -> str:
    digest = hashlib.sha256(content_digest(path).encode())
    # The file name too: clips are named after it, so two copies of one take must not share names.
    digest.update(f"|{path.name}|{__version__}|{MEASUREMENT_REVISION}|{settings_key}|{time_range!r}".encode())
    return digest.hexdigest()


def content_digest(path: Path) -> str:
    """SHA-256 of the file's bytes, remembered by (path, size, mtime, inode): a file whose stat did
    not move is not read again, so a rebuild after one edit hashes one clip, not the library."""
    info = path.stat()
    folder = cache_dir()
    stat_key = f"{path.absolute()}|{info.st_size}|{info.st_mtime_ns}|{info.st_ino}"
    entry = None
    if folder is not None:
        entry = folder / "digests" / f"{hashlib.sha256(stat_key.encode()).hexdigest()}.txt"
        try:
            return entry.read_text(encoding="ascii").strip()
        except OSError:
            pass
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    value = digest.hexdigest()
    # A file modified in the last seconds may change again within the clock's granularity with
    # the same size (git's "racy" case): it is remembered only once its mtime has settled.
    if entry is not None and time.time_ns() - info.st_mtime_ns > 2_000_000_000:
        _write_atomic(entry, value)
    return value


def _write_atomic(target: Path, text: str) -> None:
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=target.parent, suffix=".tmp")
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(temporary, target)
    except OSError:
        pass  # a read-only or full cache folder must never fail a build


def load(key: str) -> list[tuple[str, Measurement]] | None:
    folder = cache_dir()
    if folder is None:
        return None
    from blendspace_pipeline.motion.measure import Measurement

    try:
        entries: list[dict[str, Any]] = json.loads((folder / f"{key}.json").read_text(encoding="utf-8"))
        return [(entry["name"], Measurement(**entry["measurement"])) for entry in entries]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def store(key: str, measured: list[tuple[str, Measurement]]) -> None:
    folder = cache_dir()
    if folder is None:
        return
    payload = json.dumps([{"name": name, "measurement": asdict(m)} for name, m in measured])
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(payload)
        os.replace(temporary, folder / f"{key}.json")
    except OSError:
        pass  # a read-only or full cache folder must never fail a build
