"""`blendspace build MANIFEST... [--out DIR]`: measure, place, check, fix and write the assets."""

from __future__ import annotations

import argparse
from pathlib import Path

from blendspace_pipeline.build import build
from blendspace_pipeline.commands._shared import add_common, emit, exit_code
from blendspace_pipeline.errors import UsageError
from blendspace_pipeline.progress import terminal_progress

HELP = "build blend-space assets (JSON, USD, HTML report, PNG) from manifest(s)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common(parser)
    parser.add_argument("--out", type=Path, help="output folder (default: the manifest's output.dir)")
    parser.add_argument("--no-fix", action="store_true", help="do not apply automatic fixes")


def run(args: argparse.Namespace) -> int:
    if args.out is not None and len(args.manifests) > 1:
        raise UsageError(
            "--out takes one manifest; several manifests write to their own output.dir",
            hint="build one manifest per --out, or drop --out",
        )
    worst = 0
    for manifest in args.manifests:
        result = build(manifest, args.out, jobs=args.jobs, progress=terminal_progress(), fix=not args.no_fix)
        diagnostics = result.space.all_diagnostics()
        written = ", ".join(str(p) for p in result.written if p.parent == result.out_dir)
        made = result.generated_names()
        generated = f", {len(made)} generated ({', '.join(made)})" if made else ""
        emit(
            args.format,
            diagnostics,
            f"{manifest}: built {len(result.space.samples)} samples, "
            f"{len(result.space.triangles)} triangles{generated} -> {written}\n",
            extra={"manifest": str(manifest), "outputs": [str(p) for p in result.written]},
        )
        worst = max(worst, exit_code(diagnostics, args.strict))
    return worst
