"""`build`: analyse, then write every output atomically.

Outputs are written into a staging folder next to the output folder and moved into place only
when all of them succeeded, so a failed build leaves nothing behind (and a folder the build
created is removed again).
"""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.pipeline.fix_loop import FixState, apply_fixes
from blendspace_pipeline.pipeline.generated_clips import write_generated_clip
from blendspace_pipeline.pipeline.progress import Progress
from blendspace_pipeline.pipeline.to_document import to_document
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.model import BetaSpace, BlendSpace


@dataclass
class BuildResult:
    space: BlendSpace
    document: BlendSpaceDocument
    out_dir: Path
    written: list[Path]
    fixes: FixState
    layer_fixes: dict[str, FixState] = field(default_factory=dict)  # beta layer name -> its fixes

    def generated_names(self) -> list[str]:
        """Every clip the fixes made: the main space's, then each beta layer's as `layer/clip`."""
        names = sorted(self.fixes.generated)
        for layer, state in self.layer_fixes.items():
            names += [f"{layer}/{name}" for name in sorted(state.generated)]
        return names


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
    space: BlendSpace,
    out_dir: Path,
    formats: Sequence[str],
    fixes: FixState | None = None,
    layer_fixes: dict[str, FixState] | None = None,
) -> tuple[BlendSpaceDocument, list[Path]]:
    """Write every output, or none: a file system refusal (the folder is a file, no permission,
    disk full) is bad input, exit 2, and leaves nothing behind."""
    try:
        return _write_outputs(space, out_dir, formats, fixes or FixState(), layer_fixes or {})
    except OSError as error:
        where = error.filename or out_dir
        raise InputError(
            f"cannot write the outputs: {error.strerror or error} ({where})",
            path=space.manifest.path,
            hint="point --out (or output.dir in the manifest) at a folder you can write to",
        ) from None


def _write_outputs(
    space: BlendSpace,
    out_dir: Path,
    formats: Sequence[str],
    fixes: FixState,
    layer_fixes: dict[str, FixState],
) -> tuple[BlendSpaceDocument, list[Path]]:
    created = not out_dir.exists()
    out_dir.mkdir(parents=True, exist_ok=True)
    # Generated clips: the main space's under clips/, a beta layer's under clips/<layer>/ (a layer
    # may mirror a clip of the same name as the main space does).
    made = [(space, fixes, "clips")] + [
        (layer.space, layer_fixes[layer.name], f"clips/{_folder_name(layer.name)}")
        for layer in space.layer_spaces
        if isinstance(layer, BetaSpace) and layer.name in layer_fixes
    ]
    for sub, _, folder in made:
        for sample in sub.samples:
            if sample.generated:
                sample.clip.source = out_dir / folder / f"{safe_file_stem(sample.name)}.usda"
    document = to_document(space, out_dir)
    staging = Path(tempfile.mkdtemp(prefix=".blendspace-staging-", dir=out_dir))
    try:
        staged: list[tuple[Path, Path]] = []
        for sub, state, folder in made:
            in_space = {s.name for s in sub.samples}
            for name in sorted(state.generated):
                if name in in_space:
                    for path in write_generated_clip(sub, state.generated[name], staging / folder):
                        staged.append((path, out_dir / folder / path.name))
        writers = _writers(space)
        for name in formats:
            suffix, writer = writers[name]
            target = out_dir / f"{space.name}{suffix}"
            writer(document, staging / target.name)
            staged.append((staging / target.name, target))
        for source, target in staged:
            target.parent.mkdir(parents=True, exist_ok=True)
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
    layer_fixes: dict[str, FixState] = {}
    if fix:
        space, fixes = apply_fixes(space)
        for layer in space.layer_spaces:  # a beta layer is a blend space: its own `fixes:` apply
            if isinstance(layer, BetaSpace):
                layer.space, layer_fixes[layer.name] = apply_fixes(layer.space)
    out_dir = output_dir(space, out)
    formats = list(dict.fromkeys(space.manifest.model.output.formats))
    document, written = write_outputs(space, out_dir, formats, fixes, layer_fixes)
    return BuildResult(space, document, out_dir, written, fixes, layer_fixes)


def _folder_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)
