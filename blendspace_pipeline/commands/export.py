"""`blendspace export BLENDSPACE.json --engine godot|unity|unreal [--out PATH]`.

Writes the blend space in the engine's own format and conventions (see
`blendspace_pipeline.exporters`) and prints, as notes on stderr, what the engine cannot express.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from types import ModuleType

from blendspace_pipeline.commands._arguments import given, given_path
from blendspace_pipeline.errors import EXIT_OK, InputError
from blendspace_pipeline.exporters import ENGINES, Export, ExportContext, adapter, export, write_export
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.layers_doc import read_document

# A generated clip's files: the build writes them side by side under clips/ (output.clip_formats).
_CLIP_SUFFIXES = (".usda", ".glb", ".bvh")

HELP = "write the blend space for Godot (.tres), Unity (.controller) or Unreal (editor Python script)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "blendspace", type=given_path, metavar="BLENDSPACE.json", help="a built N.blendspace.json"
    )
    parser.add_argument("--engine", required=True, choices=ENGINES, help="target engine")
    parser.add_argument(
        "--out",
        type=given,
        # A string, not a Path: Path("ex/") drops the trailing separator that says "a folder".
        metavar="PATH",
        help="output file, or a folder (an existing one, or any path ending in /) for the default name "
        "(default: N.tres / N.controller / N_unreal.py beside the JSON)",
    )
    parser.add_argument(
        "--unity-project",
        type=given_path,
        metavar="DIR",
        help="Unity project whose .meta files give the source clips' GUIDs (unity only)",
    )


def run(args: argparse.Namespace) -> int:
    path: Path = args.blendspace
    doc = read_document(path)
    project: Path | None = args.unity_project
    if project is not None and args.engine != "unity":
        raise InputError(
            f"--unity-project is for --engine unity, not {args.engine}", hint="drop --unity-project"
        )
    if project is not None and not project.is_dir():
        raise InputError(
            f"--unity-project {project} is not a folder",
            hint="pass the Unity project folder (the one with Assets/)",
        )
    module = adapter(args.engine)
    suffix: str = module.SUFFIX
    target = output_path(args.out, path.parent / f"{doc.name}{suffix}")
    replaced = target.exists()
    _check_target(target, args.engine, module, replaced)
    context = ExportContext(
        previous=_previous(target) if replaced else None,
        target=target,
        clip_files=clip_files(doc, path.parent),
        unity_project=project,
    )
    try:
        result = export(doc, args.engine, source=path.name, context=context)
    except InputError as error:
        if error.path is None:
            error.path = path
        raise
    try:
        write_export(result, target)
    except OSError as error:
        raise _cannot_write(target, error) from None
    _print_notes(result, target, replaced)
    return EXIT_OK


def _check_target(target: Path, engine: str, module: ModuleType, exists: bool) -> None:
    """An export never replaces a file that is not one (`--out manifest.yaml` turned the manifest
    into an Unreal script, exit 0), nor writes an engine's file under another engine's extension
    (a Godot resource in a `.controller`). Both are exit 2 before anything is written."""
    extension = "." + module.SUFFIX.rsplit(".", 1)[-1]  # ".tres"; Path(".tres").suffix is ""
    if target.suffix.lower() != extension:
        raise InputError(
            f"--out {target}: a {engine} export is a {extension} file",
            hint=f"give --out a name ending in {extension}, or a folder",
        )
    if not exists:
        return
    text = _previous(target)
    if text is None or not module.replaceable(text):
        raise InputError(
            f"--out {target} is an existing file that is not {module.REPLACES}: the export would replace it",
            hint="choose another --out, or move that file away first",
        )


def clip_files(doc: BlendSpaceDocument, folder: Path) -> dict[str, list[Path]]:
    """Each generated sample's files beside the JSON (its source, and the other formats written)."""
    files: dict[str, list[Path]] = {}
    for sample in doc.samples:
        if not sample.generated:
            continue
        source = (folder / sample.source).resolve()
        files[sample.name] = [p for p in (source.with_suffix(s) for s in _CLIP_SUFFIXES) if p.is_file()]
    return files


def _previous(target: Path) -> str | None:
    """The file being replaced, read to keep what the engine added to it (uids, assignments)."""
    try:
        return target.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None


def output_path(out: str | None, default: Path) -> Path:
    """Where to write: ``out`` as a file, or ``default``'s name inside ``out`` when it is a folder.

    A trailing separator, an existing directory, or a new path without a file extension makes
    ``out`` a folder, created when missing: `--out ex/` (or `--out Assets/Animators` for a folder
    not made yet) must not write a file called ``ex`` that no engine imports.
    """
    if out is None:
        return default
    folder = Path(out)
    if out.endswith(("/", os.sep)) or folder.is_dir() or (not folder.suffix and not folder.exists()):
        if folder.exists() and not folder.is_dir():
            raise InputError(
                f"cannot write into {out}: {folder} is a file, not a folder",
                hint="drop the trailing / to replace that file, or choose another folder",
            )
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise _cannot_write(folder, error) from None
        return folder / default.name
    if not folder.parent.exists():
        raise InputError(
            f"the folder {folder.parent} does not exist",
            path=folder,
            hint="create it first, end --out with / to have it created and get the default file name, "
            "or pass an existing folder",
        )
    return folder


def _cannot_write(path: Path, error: OSError) -> InputError:
    """A write that the system refuses is the user's to fix (permissions, a file in the way)."""
    return InputError(
        f"cannot write {path}: {error.strerror or error}",
        hint="choose an --out in a folder you can write to",
    )


def _print_notes(result: Export, target: Path, replaced: bool) -> None:
    sys.stdout.write(
        f"wrote {target} ({result.engine}{'; replaced the previous file' if replaced else ''})\n"
    )
    for note in result.notes:
        sys.stderr.write(f"note: {note}\n")
