"""File names made from clip names.

A clip name comes from the manifest (`name:`) or from inside a clip file (an animation's name), so
it may hold `/`, `..`, control characters or hundreds of characters. Any file the tool writes for
a clip is named by `safe_file_stem`, so a name can never place a file outside its folder.
"""

from __future__ import annotations

import re

_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")
MAX_STEM_BYTES = 200  # under the 255-byte limit of common file systems, with room for suffixes


def safe_file_stem(name: str) -> str:
    """``name`` with every character but letters, digits, `_`, `.` and `-` replaced by `_`, no
    leading dot (no hidden files, no `..`), at most `MAX_STEM_BYTES` long; never empty."""
    stem = _UNSAFE.sub("_", name).lstrip(".")[:MAX_STEM_BYTES]
    return stem or "clip"
