"""Build stamps: a `build` or `check` whose inputs and outputs did not move returns at once.

A finished run records, per invocation (command, manifests, options, working folder, tool
version and the fingerprint of its code, measurement revision), what it read and wrote: every input file (manifests, clips,
layer manifests and clips, the rule modules it ran) and every folder that holds a clip (a file
added to a globbed folder changes the folder's mtime), each with its size, mtime and SHA-256,
every output with the same, and what the run printed and its exit code. The next identical
invocation checks the stamp with stat calls only: when every size and mtime matches, it prints
the recorded text and returns the recorded exit code without reading a clip or importing the
pipeline. Content hashes are read only for files whose stat moved (a `touch`, a checkout that
rewrote the same bytes): unchanged bytes still count as up to date. Anything else (a changed
byte, a missing output, another tool version) and the command runs as usual, through the
measurement cache, so an edit re-measures only the clips it touched.

Stamps live in the cache folder (`BLENDSPACE_CACHE_DIR`, `stamps/`), keyed by the invocation:
the same manifest built to two folders, or checked with and without `--strict`, keeps two.
`BLENDSPACE_CACHE_DIR=off` switches them off with the cache. Runs that ended in bad input (exit 2)
or wrote SARIF (its log describes the rules, which a replay would have to load) are not stamped.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from blendspace_pipeline import __version__
from blendspace_pipeline.pipeline.cache import (
    MEASUREMENT_REVISION,
    cache_dir,
    content_digest,
    dumps,
    file_sha256,
    loads,
    write_atomic,
)

STAMP_VERSION = 1


@dataclass(frozen=True)
class FileState:
    path: str
    size: int  # -1 for a folder (its size means nothing), -2 for a file that did not exist
    mtime_ns: int
    sha256: str  # "" for folders and missing files


RESULT_VARIABLES = (
    "BLENDSPACE_NO_PLUGINS",
    "BLENDSPACE_RULE_PATH",
    "BLENDSPACE_MAX_FRAMES",
    "SOURCE_DATE_EPOCH",
)


def invocation_key(command: str, manifests: Sequence[Path], options: dict[str, object]) -> str:
    """What makes two runs the same: the command, its manifests and options, where it runs, and
    the code that runs it (an edited checkout of the tool under the same version, a package
    installed, upgraded or removed: `server.address.installed_fingerprint`, ~1-2 ms)."""
    from blendspace_pipeline.server.address import installed_fingerprint

    described = {
        "command": command,
        "manifests": [str(Path(m).absolute()) for m in manifests],
        "options": {k: str(v) for k, v in sorted(options.items())},
        # Switches that change what a run reads or reports (plugins, rule folders, limits, dates).
        "environment": {name: os.environ.get(name, "") for name in RESULT_VARIABLES},
        "cwd": os.getcwd(),
        "version": __version__,
        "code": installed_fingerprint(),
        "revision": MEASUREMENT_REVISION,
        "stamp": STAMP_VERSION,
    }
    return hashlib.sha256(json.dumps(described, sort_keys=True).encode()).hexdigest()


def _stamp_path(key: str) -> Path | None:
    folder = cache_dir()
    return None if folder is None else folder / "stamps" / f"{key}.json"


def file_state(path: str | Path, known: dict[str, FileState] | None = None) -> FileState:
    """Size, mtime and SHA-256 of ``path``. The digest is reused, not read again, from ``known``
    (the previous stamp) or the measurement cache's digests when the file's stat did not move:
    a rebuild after one edit hashes the edited clip and the new outputs, not the library."""
    text = os.fspath(path)
    try:
        info = os.stat(text)
    except OSError:
        return FileState(text, -2, 0, "")
    if stat.S_ISDIR(info.st_mode):
        return FileState(text, -1, info.st_mtime_ns, "")
    before = known.get(text) if known else None
    if before is not None and before.size == info.st_size and before.mtime_ns == info.st_mtime_ns:
        return before
    return FileState(text, info.st_size, info.st_mtime_ns, content_digest(Path(text)))


def _unchanged(state: FileState) -> bool:
    """Stat first; a file whose size matches but whose mtime moved is compared by content."""
    try:
        info = os.stat(state.path)
    except OSError:
        return state.size == -2
    if state.size == -1:
        return info.st_mtime_ns == state.mtime_ns
    if state.size < 0 or info.st_size != state.size:
        return False
    if info.st_mtime_ns == state.mtime_ns:
        return True
    try:
        return file_sha256(Path(state.path)) == state.sha256
    except OSError:
        return False


def replay(key: str) -> int | None:
    """When the stamp for ``key`` is up to date: print what the run printed, return its exit code."""
    path = _stamp_path(key)
    if path is None:
        return None
    try:
        # The standard parser: the no-op path must not import pydantic-core (55 ms).
        stamp: dict[str, Any] = json.loads(path.read_bytes())
        files = [FileState(**entry) for entry in stamp["inputs"] + stamp["outputs"]]
        printed, code = str(stamp["stdout"]), int(stamp["exit_code"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not all(_unchanged(state) for state in files):
        return None
    sys.stdout.write(printed)
    return code


def record(key: str, inputs: Iterable[Path], outputs: Iterable[Path], printed: str, exit_code: int) -> None:
    """Write the stamp of a finished run (atomically; a cache folder that refuses is ignored)."""
    path = _stamp_path(key)
    if path is None:
        return
    # As text once spelled by Path (`absolute`: no `..` resolved, a symlinked folder stays one):
    # sorting and hashing a thousand Path objects was half of this function's time.
    input_paths = sorted({_absolute(p) for p in inputs})
    folders = sorted({os.path.dirname(p) for p in input_paths})
    known = _previous_states(path)
    stamp = {
        "version": __version__,
        "inputs": [_as_dict(file_state(p, known)) for p in [*input_paths, *folders]],
        "outputs": [_as_dict(file_state(p, known)) for p in sorted({_absolute(p) for p in outputs})],
        "stdout": printed,
        "exit_code": exit_code,
    }
    write_atomic(path, dumps(stamp))


def _absolute(path: str | Path) -> str:
    """``str(Path(path).absolute())``, without a Path for a path that already is one, absolute."""
    if isinstance(path, Path) and path.is_absolute():
        return str(path)
    return str(Path(path).absolute())


def _as_dict(state: FileState) -> dict[str, object]:
    """`dataclasses.asdict` of a FileState (same keys, same order) without its deep copy: a
    1,000-clip stamp spent a third of its time there."""
    return {"path": state.path, "size": state.size, "mtime_ns": state.mtime_ns, "sha256": state.sha256}


def _previous_states(path: Path) -> dict[str, FileState]:
    """The files of the stamp ``path`` holds now (the previous run's), by path; {} when none."""
    try:
        stamp: dict[str, Any] = loads(path.read_bytes())
        return {entry["path"]: FileState(**entry) for entry in stamp["inputs"] + stamp["outputs"]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


class Capture:
    """Tee of stdout while a command runs, so its stamp can replay exactly what it printed."""

    def __init__(self) -> None:
        self.parts: list[str] = []
        self._stream = sys.stdout

    def write(self, text: str) -> int:
        self.parts.append(text)
        return self._stream.write(text)

    def flush(self) -> None:
        self._stream.flush()

    def __enter__(self) -> Capture:
        sys.stdout = self
        return self

    def __exit__(self, *exc: object) -> None:
        sys.stdout = self._stream

    @property
    def text(self) -> str:
        return "".join(self.parts)


def rule_files(space: object) -> list[Path]:
    """The source files of the rules a space ran (built-ins and plugins): editing a plugin must
    rebuild. ``space`` is a `space.model.BlendSpace`; its layers' rules are included."""
    from blendspace_pipeline.checks.rule_engine import loaded_rules_of
    from blendspace_pipeline.space.model import BetaSpace, BlendSpace

    assert isinstance(space, BlendSpace)
    files: list[Path] = []
    for rule in loaded_rules_of(space).rules.values():
        module = sys.modules.get(rule.__module__)
        source = getattr(module, "__file__", None)
        if source:
            files.append(Path(source))
    for layer in space.layer_spaces:
        if isinstance(layer, BetaSpace):
            files += rule_files(layer.space)
    return files


def watched_paths(space: object) -> list[Path]:
    """What a rerun must notice besides the files the run read (``space``: a
    `space.model.BlendSpace`, its beta layers included): every `plugins:` file, also one that
    failed to load or did not exist (fixing or adding it must rebuild, not replay the
    plugin-error), the `BLENDSPACE_RULE_PATH` folders, and every folder a glob of `clips:` looks
    in (a clip added to a sub-folder that held none had replayed the old build)."""
    from blendspace_pipeline.checks.rule_engine import RULE_PATH_VARIABLE, plugin_file
    from blendspace_pipeline.manifest.models import StyleLayer
    from blendspace_pipeline.manifest.paths import searched_folders
    from blendspace_pipeline.space.model import BetaSpace, BlendSpace

    assert isinstance(space, BlendSpace)
    loaded = space.manifest
    paths = searched_folders(loaded)
    for declared in loaded.model.layers:  # a style layer's clips are globs of this manifest too
        if isinstance(declared, StyleLayer):
            paths += searched_folders(loaded, declared.entries())
    paths += [f for f in (plugin_file(p, loaded.directory) for p in loaded.model.plugins) if f is not None]
    for folder in [Path(f) for f in os.environ.get(RULE_PATH_VARIABLE, "").split(os.pathsep) if f]:
        paths.append(folder)  # a file added or removed
        paths += sorted(folder.glob("*.py")) if folder.is_dir() else []  # one fixed in place
    for layer in space.layer_spaces:
        if isinstance(layer, BetaSpace):
            paths += watched_paths(layer.space)
    return paths
