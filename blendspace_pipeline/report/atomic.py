"""Atomic output files: write beside the target, then rename over it.

A reader (a CI artifact upload, a browser refreshing the report) never sees a half-written
file, and a failed write leaves the previous output untouched.
"""

from __future__ import annotations

import os
import struct
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: Path, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary path in ``path``'s folder that replaces ``path`` when the block succeeds.

    ``suffix`` lets writers that pick a format by extension (OpenImageIO) see the right one.
    """
    handle, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(handle)
    temporary = Path(name)
    try:
        yield temporary
        _fsync(temporary)  # a full disk surfaces here (delayed allocation), not after the rename
        # mkstemp makes the file private (0600); outputs get the permissions of any new file.
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _umask() -> int:
    current = os.umask(0)
    os.umask(current)
    return current


def _fsync(path: Path) -> None:
    handle = os.open(path, os.O_RDONLY)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


class IncompleteOutput(OSError):
    """A written file is shorter than its format says: a full disk a library did not report."""


def verify_written(path: Path) -> None:
    """Raise `IncompleteOutput` unless ``path`` is a complete file of its format.

    Libraries do not always report a failed write (OpenImageIO said yes to a truncated PNG on a
    full disk), so each output is synced and checked by its own structure before it is published:
    PNG ends with its IEND chunk, GLB's header length is the file size, JSON parses, HTML closes,
    text formats end with a newline. Every file must be non-empty.
    """
    _fsync(path)
    size = path.stat().st_size
    if size == 0:
        raise IncompleteOutput(0, "the written file is empty (disk full?)", str(path))
    suffix = path.suffix.lower()
    with open(path, "rb") as stream:
        head = stream.read(12)
        stream.seek(max(0, size - 64))
        tail = stream.read()
    complete = True
    if suffix == ".png":
        complete = head.startswith(b"\x89PNG") and tail.endswith(b"IEND\xaeB`\x82")
    elif suffix == ".glb":
        complete = len(head) == 12 and struct.unpack("<I", head[8:12])[0] == size
    elif suffix == ".json":
        from pydantic_core import from_json  # parses as strictly as `json`, twice as fast

        try:
            from_json(path.read_bytes())
        except ValueError:
            complete = False
    elif suffix == ".html":
        complete = b"</html>" in tail.lower()
    elif suffix in (".usda", ".bvh", ".tres", ".py"):
        complete = tail.endswith(b"\n")
    if not complete:
        raise IncompleteOutput(
            0, f"the written {suffix} file is incomplete ({size} bytes; disk full?)", str(path)
        )
