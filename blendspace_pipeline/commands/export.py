"""`blendspace export BLENDSPACE.json --engine godot|unity|unreal [--out PATH]`.

Writes the blend space in the engine's own format and conventions (see
`blendspace_pipeline.exporters`) and prints, as notes on stderr, what the engine cannot express.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from blendspace_pipeline.errors import EXIT_OK, InputError
from blendspace_pipeline.exporters import ENGINES, Export, export, write_export
from blendspace_pipeline.layers_doc import read_document

HELP = "write the blend space for Godot (.tres), Unity (.controller) or Unreal (editor Python script)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("blendspace", type=Path, metavar="BLENDSPACE.json", help="a built N.blendspace.json")
    parser.add_argument("--engine", required=True, choices=ENGINES, help="target engine")
    parser.add_argument(
        "--out",
        type=Path,
        metavar="PATH",
        help="output file, or a folder for the default name (default: N.tres / N.controller / N_unreal.py "
        "beside the JSON)",
    )


def run(args: argparse.Namespace) -> int:
    path: Path = args.blendspace
    doc = read_document(path)
    try:
        result = export(doc, args.engine, source=path.name)
    except InputError as error:
        if error.path is None:
            error.path = path
        raise
    target = output_path(args.out, path.parent / f"{doc.name}{result.suffix}")
    write_export(result, target)
    _print_notes(result, target)
    return EXIT_OK


def output_path(out: Path | None, default: Path) -> Path:
    if out is None:
        return default
    if out.is_dir():
        return out / default.name
    if not out.parent.is_dir():
        raise InputError(
            f"the folder {out.parent} does not exist",
            path=out,
            hint="create it first, or pass an existing folder to --out to use the default file name",
        )
    return out


def _print_notes(result: Export, target: Path) -> None:
    sys.stdout.write(f"wrote {target} ({result.engine})\n")
    for note in result.notes:
        sys.stderr.write(f"note: {note}\n")
