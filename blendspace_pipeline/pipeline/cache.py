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
from dataclasses import asdict
from pathlib import Path
from typing import Any

from blendspace_pipeline import __version__
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
# 3: readers refuse out-of-range data (frame rate, angles, sizes) that revision 2 measured.
MEASUREMENT_REVISION = 3


def cache_key(path: Path, settings_key: str, time_range: tuple[float, float] | None) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    # The file name too: clips are named after it, so two copies of one take must not share names.
    digest.update(f"|{path.name}|{__version__}|{MEASUREMENT_REVISION}|{settings_key}|{time_range!r}".encode())
    return digest.hexdigest()


def load(key: str) -> list[tuple[str, Measurement]] | None:
    folder = cache_dir()
    if folder is None:
        return None
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
