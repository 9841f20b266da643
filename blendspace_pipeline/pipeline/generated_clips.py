"""Writing the clips the fixes made: always UsdSkel, and BVH too when the sources are BVH.

A generated clip is written with the units and up axis its measurement established (BVH files do
not say theirs), so it opens at the right size in any USD tool. When every source of the set is
BVH, the clip is also written as BVH with the source's own hierarchy header and channel layout,
so it drops into the same pipeline as the clips it came from.
"""

from __future__ import annotations

from pathlib import Path

from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.pipeline.fix_loop import GeneratedClip
from blendspace_pipeline.space.model import BlendSpace
from blendspace_pipeline.writers.usd_clip import write_usd_clip


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


def write_generated_clip(space: BlendSpace, generated: GeneratedClip, folder: Path) -> list[Path]:
    """Write ``generated`` into ``folder``; returns the files written."""
    folder.mkdir(parents=True, exist_ok=True)
    clip = generated.clip
    measured = generated.measured
    units = measured.measurement.meters_per_unit if measured else clip.meters_per_unit
    up = measured.measurement.up_axis if measured else clip.up_axis
    written = [folder / f"{safe_file_stem(clip.name)}.usda"]
    write_usd_clip(clip, written[0], meters_per_unit=units, up_axis=up)
    template = bvh_template(space, generated)
    if template is not None:
        from blendspace_pipeline.writers.bvh import write_bvh_clip

        written.append(folder / f"{safe_file_stem(clip.name)}.bvh")
        write_bvh_clip(clip, written[1], template=template)
    return written
