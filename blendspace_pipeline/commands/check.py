"""`blendspace check MANIFEST...`: the same analysis and rules as build; writes nothing."""

from __future__ import annotations

import argparse

from blendspace_pipeline.commands._shared import add_common, emit, exit_code
from blendspace_pipeline.pipeline import analyse
from blendspace_pipeline.progress import terminal_progress

HELP = "analyse manifest(s) and run the rules without writing anything (for CI and pre-commit)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common(parser)


def run(args: argparse.Namespace) -> int:
    worst = 0
    everything = []
    for manifest in args.manifests:
        space = analyse(manifest, jobs=args.jobs, progress=terminal_progress())
        found = space.all_diagnostics()
        everything += found
        worst = max(worst, exit_code(found, args.strict))
    emit(args.format, everything, f"checked {len(args.manifests)} manifest(s): ")
    return worst
