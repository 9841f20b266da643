"""`build`: analyse, then write every output atomically.

Outputs are written into a staging folder next to the output folder and moved into place only
when all of them succeeded, so a failed build leaves nothing behind (and a folder the build
created is removed again).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from blendspace_pipeline.document import BlendSpaceDocument
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.fix_loop import FixState, apply_fixes
from blendspace_pipeline.generated_clips import write_generated_clip
from blendspace_pipeline.layers import BetaSpace
from blendspace_pipeline.pipeline import BlendSpace, Progress, analyse
from blendspace_pipeline.to_document import to_document


@dataclass
class BuildResult:
    space: BlendSpace
    document: BlendSpaceDocument
    out_dir: Path
    written: list[Path]
    fixes: FixState


def output_dir(space: BlendSpace, out: Path | None) -> Path:
    if out is not None:
        return out
    configured = Path(space.manifest.model.output.dir.replace("\\", "/"))
    return configured if configured.is_absolute() else space.manifest.directory / configured


def _write_json(doc: BlendSpaceDocument, path: Path) -> None:
    path.write_text(doc.model_dump_json(indent=2) + "\n", encoding="utf-8")


def input_files(space: BlendSpace) -> list[Path]:
    """The files a build reads: its manifest, the clips, and those of its layers."""
    files = [space.manifest.path]
    files += [s.clip.source for s in space.samples if not s.generated]
    for layer in space.layer_spaces:
        if isinstance(layer, BetaSpace):
            files += input_files(layer.space)
        else:
            files += [clip.source for clip in layer.clips]
    return files


def _writers(space: BlendSpace) -> dict[str, tuple[str, Callable[[BlendSpaceDocument, Path], None]]]:
    """format -> (file suffix, writer). Heavy writers import only when used."""

    def usd(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.writers.usd_blendspace import write_usd_blendspace

        write_usd_blendspace(doc, path)

    def html(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.report import write_html_report

        write_html_report(doc, path, input_files(space))

    def png(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.report import write_png

        write_png(doc, path)

    return {
        "json": (".blendspace.json", _write_json),
        "usd": (".blendspace.usda", usd),
        "html": (".report.html", html),
        "png": (".png", png),
    }


def write_outputs(
    space: BlendSpace, out_dir: Path, formats: Sequence[str], fixes: FixState | None = None
) -> tuple[BlendSpaceDocument, list[Path]]:
    """Write every output, or none: a file system refusal (the folder is a file, no permission,
    disk full) is bad input, exit 2, and leaves nothing behind."""
    try:
        return _write_outputs(space, out_dir, formats, fixes)
    except OSError as error:
        where = error.filename or out_dir
        raise InputError(
            f"cannot write the outputs: {error.strerror or error} ({where})",
            path=space.manifest.path,
            hint="point --out (or output.dir in the manifest) at a folder you can write to",
        ) from None


def _write_outputs(
    space: BlendSpace, out_dir: Path, formats: Sequence[str], fixes: FixState | None
) -> tuple[BlendSpaceDocument, list[Path]]:
    created = not out_dir.exists()
    out_dir.mkdir(parents=True, exist_ok=True)
    generated = fixes.generated if fixes is not None else {}
    for sample in space.samples:
        if sample.generated:
            sample.clip.source = out_dir / "clips" / f"{sample.name}.usda"
    document = to_document(space, out_dir)
    staging = Path(tempfile.mkdtemp(prefix=".blendspace-staging-", dir=out_dir))
    try:
        staged: list[tuple[Path, Path]] = []
        in_space = {s.name for s in space.samples}
        for name in sorted(generated):
            if name in in_space:
                for path in write_generated_clip(space, generated[name], staging / "clips"):
                    staged.append((path, out_dir / "clips" / path.name))
        writers = _writers(space)
        for name in formats:
            suffix, writer = writers[name]
            target = out_dir / f"{space.name}{suffix}"
            writer(document, staging / target.name)
            staged.append((staging / target.name, target))
        for source, target in staged:
            target.parent.mkdir(exist_ok=True)
            source.replace(target)
        return document, [target for _, target in staged]
    except BaseException:
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def build(
    manifest: Path,
    out: Path | None = None,
    *,
    jobs: int = 1,
    progress: Progress | None = None,
    fix: bool = True,
) -> BuildResult:
    space = analyse(manifest, jobs=jobs, progress=progress)
    fixes = FixState()
    if fix:
        space, fixes = apply_fixes(space)
    out_dir = output_dir(space, out)
    formats = list(dict.fromkeys(space.manifest.model.output.formats))
    document, written = write_outputs(space, out_dir, formats, fixes)
    return BuildResult(space=space, document=document, out_dir=out_dir, written=written, fixes=fixes)
