"""`blendspace check MANIFEST...`: the same analysis and rules as build; writes nothing."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.commands._shared import (
    add_common,
    command_environment,
    emit,
    exit_code,
    report_input_error,
)
from blendspace_pipeline.errors import EXIT_INPUT, InputError
from blendspace_pipeline.memory import collector_paused
from blendspace_pipeline.pipeline import stamp

if TYPE_CHECKING:
    from blendspace_pipeline.diagnostics import Diagnostic
    from blendspace_pipeline.space.model import BlendSpace

HELP = "analyse manifest(s) and run the rules without writing anything (for CI and pre-commit)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common(parser)
    parser.add_argument(
        "--changed",
        action="store_true",
        help="the arguments are changed files (manifests, layer manifests, clips): check every "
        "manifest under the current folder that is or uses one of them (the pre-commit hook)",
    )


def run(args: argparse.Namespace) -> int:
    with command_environment(args), collector_paused():
        if args.changed:
            from blendspace_pipeline.commands._changed import manifests_for, relative_names

            root = Path.cwd()
            args.manifests = relative_names(manifests_for(args.manifests, root), root)
            if not args.manifests:
                if args.format == "text":
                    sys.stdout.write("no manifest uses the changed files: nothing to check\n")
                else:
                    emit(args.format, [], "checked 0 manifest(s): ")
                return 0
        # Nothing moved since the same check: print what it printed, without loading the pipeline.
        key = stamp.invocation_key("check", args.manifests, {"format": args.format, "strict": args.strict})
        if args.format != "sarif" and (replayed := stamp.replay(key)) is not None:
            return replayed
        inputs: list[Path] = []
        with stamp.Capture() as printed:
            worst = _run(args, inputs)
        if worst != EXIT_INPUT and args.format != "sarif":
            stamp.record(key, inputs, [], printed.text, worst)
        return worst


def _run(args: argparse.Namespace, inputs: list[Path]) -> int:
    from blendspace_pipeline.pipeline.analysis import analyse
    from blendspace_pipeline.pipeline.outputs import input_files
    from blendspace_pipeline.pipeline.progress import terminal_progress

    worst = 0
    everything: list[Diagnostic] = []
    spaces: list[BlendSpace] = []
    invalid = 0
    for manifest in args.manifests:
        # One invalid manifest must not hide the findings of the others (pre-commit passes many).
        try:
            space = analyse(manifest, jobs=args.jobs, progress=terminal_progress())
        except InputError as error:
            invalid += 1
            worst = EXIT_INPUT
            everything += report_input_error(args.format, error, manifest)
            continue
        spaces.append(space)
        inputs += input_files(space) + stamp.rule_files(space) + stamp.watched_paths(space)
        found = space.all_diagnostics()
        everything += found
        worst = max(worst, exit_code(found, args.strict))
    if args.format == "text" and not spaces:
        # Every manifest was invalid: stderr already says why, as it always has; no empty tally.
        return worst
    summary = f"checked {len(args.manifests)} manifest(s): "
    if invalid:
        summary = f"checked {len(args.manifests)} manifest(s), {invalid} invalid (see stderr): "
    emit(args.format, everything, summary, spaces=spaces)
    return worst
