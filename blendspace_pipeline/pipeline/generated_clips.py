"""Writing the clips the fixes made: UsdSkel, GLB for engines, and BVH when the sources are BVH.

A generated clip is written with the units and up axis its measurement established (BVH files do
not say theirs), so it opens at the right size in any USD tool. The GLB (metres, +Y up, one
animation named after the clip) is what Godot imports natively, Unreal through Interchange and
Unity through glTFast. When every source of the set is BVH, the clip is also written as BVH with
the source's own hierarchy header and channel layout, so it drops into the same pipeline as the
clips it came from (in its own layout where that one cannot hold its motion: a joint that moves
with no position channels there). The manifest's ``output.clip_formats`` narrows the list. Every file carries
the clip's provenance (`readers.provenance`): how the next build knows it for a generated clip.
"""

from __future__ import annotations

from pathlib import Path

from blendspace_pipeline import __version__
from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.pipeline.fix_loop import GeneratedClip
from blendspace_pipeline.readers.provenance import Provenance
from blendspace_pipeline.space.model import BlendSpace

# The suffix of each clip format, in the order a generated sample's `source` prefers them.
CLIP_SUFFIXES = {"usd": ".usda", "glb": ".glb", "bvh": ".bvh"}


def clip_formats(space: BlendSpace) -> list[str]:
    """The formats ``space``'s manifest asks for (`output.clip_formats`), in preference order."""
    wanted = set(space.manifest.model.output.clip_formats)
    return [name for name in CLIP_SUFFIXES if name in wanted]


def source_suffix(space: BlendSpace) -> str:
    """The file a generated sample's ``source`` names: the first written of USD, GLB, BVH.

    BVH is written in the sources' layout for BVH sources (in its own for others, when
    `clip_formats` names it); a manifest asking for BVH alone on other sources still gets the USD,
    so a generated sample names a file its set's readers share.
    """
    formats = clip_formats(space)
    if formats == ["bvh"] and not _all_bvh(space):
        return CLIP_SUFFIXES["usd"]
    return CLIP_SUFFIXES[formats[0]]


def _all_bvh(space: BlendSpace) -> bool:
    sources = [s.clip.source for s in space.samples if not s.generated]
    return bool(sources) and all(p.suffix.lower() == ".bvh" for p in sources)


def bvh_template(space: BlendSpace, generated: GeneratedClip) -> Path | None:
    """The source BVH whose layout the generated clip copies, or None when the set is not all BVH."""
    sources = [s.clip.source for s in space.samples if not s.generated]
    if not sources or any(p.suffix.lower() != ".bvh" for p in sources):
        return None
    by_name = {s.name: s.clip.source for s in space.samples if not s.generated}
    for name in generated.sources:
        if name in by_name:
            return by_name[name]
    return sources[0]


def provenance_of(generated: GeneratedClip) -> Provenance:
    """The record written into every file of ``generated``: rule, sources, weights, tool version."""
    return Provenance(
        rule=generated.rule,
        sources=generated.sources,
        weights=generated.weights,
        tool="blendspace-pipeline",
        version=__version__,
        note=generated.note,
    )


def write_generated_clip(
    space: BlendSpace, generated: GeneratedClip, folder: Path, stem: str | None = None
) -> list[Path]:
    """Write ``generated`` into ``folder`` as ``stem`` (default: `safe_file_stem` of its name; the
    build gives `unique_stems` of the space's generated clips); returns the files written."""
    # The writers load USD (pxr) and scipy: imported here, so a build without fixes does not pay.
    from blendspace_pipeline.writers.gltf import write_gltf_clip
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    folder.mkdir(parents=True, exist_ok=True)
    clip = generated.clip
    measured = generated.measured
    units = measured.measurement.meters_per_unit if measured else clip.meters_per_unit
    up = measured.measurement.up_axis if measured else clip.up_axis
    formats = clip_formats(space)
    record = provenance_of(generated)
    stem = stem or safe_file_stem(clip.name)
    written: list[Path] = []
    if "usd" in formats or source_suffix(space) == CLIP_SUFFIXES["usd"]:
        written.append(folder / f"{stem}.usda")
        write_usd_clip(clip, written[-1], meters_per_unit=units, up_axis=up, provenance=record)
    if "glb" in formats:
        written.append(folder / f"{stem}.glb")
        write_gltf_clip(clip, written[-1], meters_per_unit=units, up_axis=up, provenance=record)
    template = bvh_template(space, generated) if "bvh" in formats else None
    # BVH beside other sources only when the manifest asks for it by name (its default lists every
    # format): `clip_formats: [bvh]` on USD sources had written USD alone, without a word.
    asked = "clip_formats" in space.manifest.model.output.model_fields_set
    if template is not None or ("bvh" in formats and asked):
        from blendspace_pipeline.writers.bvh import LayoutCannotHold, write_bvh_clip

        written.append(folder / f"{stem}.bvh")
        try:
            write_bvh_clip(clip, written[-1], template=template, provenance=record)
        except LayoutCannotHold:
            # The source's layout cannot hold the motion (a merge or a straightened clip moves a
            # joint that has no position channels there, the root motion being on a `Root`):
            # written in its own layout, position channels where joints move.
            write_bvh_clip(clip, written[-1], provenance=record)
    return written
