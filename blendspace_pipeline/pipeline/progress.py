"""A one-line progress bar on stderr, shown only when stderr is a terminal."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

# Called as progress(done, total, name) after each clip is measured.
Progress = Callable[[int, int, str], None]


def terminal_progress(label: str = "measuring") -> Progress | None:
    if not sys.stderr.isatty():
        return None
    started = time.monotonic()

    def show(done: int, total: int, name: str) -> None:
        if total < 8 and done < total:
            return  # small sets finish before a bar would help
        width = 28
        filled = int(width * done / max(total, 1))
        elapsed = time.monotonic() - started
        sys.stderr.write(
            f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total} {elapsed:5.1f}s {name[:30]:<30}"
        )
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return show
