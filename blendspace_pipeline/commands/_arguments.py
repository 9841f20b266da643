"""argparse types the commands share, in a module that imports nothing heavy (`eval` and
`export` start fast)."""

from __future__ import annotations

import argparse
from pathlib import Path


def given(text: str) -> str:
    """argparse type for a path or store location: an empty one (a script's unset variable,
    `--out "$OUT"`) is refused, exit 2, instead of meaning the working folder (an index written
    into the project, outputs beside the manifest)."""
    if text == "":
        raise argparse.ArgumentTypeError(
            "is empty (an unset variable?): give a path, or '.' for the working folder"
        )
    return text


def given_path(text: str) -> Path:
    """`given`, as a Path."""
    return Path(given(text))
