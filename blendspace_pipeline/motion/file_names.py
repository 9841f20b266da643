"""File names made from clip names.

A clip name comes from the manifest (`name:`) or from inside a clip file (an animation's name), so
it may hold `/`, `..`, control characters or hundreds of characters. Any file the tool writes for
a clip is named by `safe_file_stem`, so a name can never place a file outside its folder.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable

_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")
MAX_STEM_BYTES = 200  # under the 255-byte limit of common file systems, with room for suffixes


def safe_file_stem(name: str) -> str:
    """``name`` with every character but letters, digits, `_`, `.` and `-` replaced by `_`, no
    leading dot (no hidden files, no `..`), at most `MAX_STEM_BYTES` long; never empty."""
    stem = _UNSAFE.sub("_", name).lstrip(".")[:MAX_STEM_BYTES]
    return stem or "clip"


def unique_stems(names: Iterable[str]) -> dict[str, str]:
    """`safe_file_stem` of each of ``names``, made unique where two would name one file: names that
    differ only in a replaced character (`spin left`, `spin_left`) or in letter case (one file on
    Windows and macOS) each get `-` and 8 hex digits of their name's SHA-256. The others keep their
    plain stem, so a set without such a clash names its files as before."""
    stems = {name: safe_file_stem(name) for name in dict.fromkeys(names)}
    count: dict[str, int] = {}
    for stem in stems.values():
        count[stem.casefold()] = count.get(stem.casefold(), 0) + 1
    return {
        name: stem
        if count[stem.casefold()] == 1
        else f"{stem[: MAX_STEM_BYTES - 9]}-{hashlib.sha256(name.encode('utf-8', 'surrogatepass')).hexdigest()[:8]}"
        for name, stem in stems.items()
    }
