"""Arguments and exit-code logic shared by `build` and `check`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.errors import EXIT_DIAGNOSTICS, EXIT_OK
from blendspace_pipeline.output_formats import FORMATS, render


def add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("manifests", nargs="+", type=Path, metavar="MANIFEST", help="manifest YAML file(s)")
    parser.add_argument(
        "--format", choices=FORMATS, default="text", help="how to print diagnostics (default: text)"
    )
    parser.add_argument("--strict", action="store_true", help="exit 1 on warnings too")
    parser.add_argument(
        "--jobs", type=int, default=1, metavar="N", help="measure clips in N processes (default 1)"
    )


def exit_code(diagnostics: Sequence[Diagnostic], strict: bool) -> int:
    failing = {"error", "warning"} if strict else {"error"}
    return EXIT_DIAGNOSTICS if any(d.severity in failing for d in diagnostics) else EXIT_OK


def emit(
    fmt: str, diagnostics: Sequence[Diagnostic], summary: str, extra: dict[str, object] | None = None
) -> None:
    sys.stdout.write(render(fmt, diagnostics, summary=summary, extra=extra))
