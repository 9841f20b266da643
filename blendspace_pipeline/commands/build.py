"""`blendspace build MANIFEST... [--out DIR]`: measure, place, check, fix and write the assets."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.commands._arguments import given_path
from blendspace_pipeline.commands._shared import (
    add_common,
    command_environment,
    emit,
    exit_code,
    report_input_error,
)
from blendspace_pipeline.errors import EXIT_INPUT, InputError, UsageError
from blendspace_pipeline.memory import collector_paused
from blendspace_pipeline.pipeline import stamp

if TYPE_CHECKING:
    from blendspace_pipeline.diagnostics import Diagnostic
    from blendspace_pipeline.space.model import BlendSpace

HELP = "build blend-space assets (JSON, USD, HTML report, PNG) from manifest(s)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_common(parser)
    parser.add_argument("--out", type=given_path, help="output folder (default: the manifest's output.dir)")
    parser.add_argument("--no-fix", action="store_true", help="do not apply automatic fixes")


def run(args: argparse.Namespace) -> int:
    with command_environment(args), collector_paused():
        return _stamped(args)


def _stamped(args: argparse.Namespace) -> int:
    if args.out is not None and len(args.manifests) > 1:
        raise UsageError(
            "--out takes one manifest; several manifests write to their own output.dir",
            hint="build one manifest per --out, or drop --out",
        )
    # Nothing moved since the same build: print what it printed, without loading the pipeline.
    options = {"format": args.format, "strict": args.strict, "out": args.out, "fix": not args.no_fix}
    key = stamp.invocation_key("build", args.manifests, options)
    if args.format != "sarif" and (replayed := stamp.replay(key)) is not None:
        return replayed
    inputs: list[Path] = []
    outputs: list[Path] = []
    with stamp.Capture() as printed:
        worst = _run(args, inputs, outputs)
    if worst != EXIT_INPUT and args.format != "sarif":
        stamp.record(key, inputs, outputs, printed.text, worst)
    return worst


def _run(args: argparse.Namespace, inputs: list[Path], outputs: list[Path]) -> int:
    from blendspace_pipeline.pipeline.outputs import build, input_files
    from blendspace_pipeline.pipeline.progress import terminal_progress

    worst = 0
    # SARIF is one log per run (code scanning takes one file), so its results wait for the end;
    # the other formats print each manifest as it is built.
    sarif: list[Diagnostic] = []
    spaces: list[BlendSpace] = []
    claimed: dict[tuple[str, str], Path] = {}  # (output folder, space name) -> the manifest building it
    for manifest in args.manifests:
        # A manifest that cannot be built is reported and the others are still built.
        try:
            _claim_outputs(manifest, args.out, claimed)
            result = build(
                manifest, args.out, jobs=args.jobs, progress=terminal_progress(), fix=not args.no_fix
            )
        except InputError as error:
            worst = EXIT_INPUT
            reported = report_input_error(args.format, error, manifest)
            if not reported:
                continue
            if args.format == "sarif":
                sarif += reported
            else:
                emit(args.format, reported, "", extra={"manifest": str(manifest), "outputs": []})
            continue
        diagnostics = result.space.all_diagnostics()
        worst = max(worst, exit_code(diagnostics, args.strict))
        inputs += (
            input_files(result.space) + stamp.rule_files(result.space) + stamp.watched_paths(result.space)
        )
        outputs += result.written
        if args.format == "sarif":
            sarif += diagnostics
            spaces.append(result.space)
            continue
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
    if args.format == "sarif":
        emit(args.format, sarif, "", spaces=spaces)
    return worst


def _claim_outputs(manifest: Path, out: Path | None, claimed: dict[tuple[str, str], Path]) -> None:
    """Two manifests of one command that build the same space name into the same folder would
    replace each other's outputs (the second's build removed the first's generated clips): the
    second is bad input (exit 2), before it writes anything. A manifest that does not load is
    left to its build, which says why."""
    import os

    from blendspace_pipeline.manifest.loader import load_manifest
    from blendspace_pipeline.pipeline.own_outputs import output_folder

    try:
        loaded = load_manifest(manifest)
    except InputError:
        return
    folder = output_folder(loaded, out)
    key = (os.path.normcase(os.path.abspath(folder)), loaded.model.name.casefold())
    first = claimed.setdefault(key, manifest)
    if os.path.realpath(first) != os.path.realpath(manifest):  # the same file twice is one build
        raise InputError(
            f"builds {loaded.model.name!r} into {folder}, as {first} does: its outputs would replace those",
            path=manifest,
            hint="give one of the two manifests its own `name:` or `output.dir`",
        )
