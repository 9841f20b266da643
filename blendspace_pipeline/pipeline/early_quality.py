"""The blend quality maps, started while the rules still run (`build --no-fix` with ``--jobs`` > 1).

The maps (trajectory error, drift, foot skate: `blend_quality`) depend only on the placed samples,
the triangles and the axes, which are final once the space is assembled; the rules and the
placeholder search that follow only add findings. So a forked process computes them from the
moment the space is placed, on the core the single-threaded rules leave idle, and the writers
take its result later.

It is a shortcut, never a different answer: the child returns a digest of the samples,
triangles and axes it saw, and the maps are used only when the final document has the same;
otherwise (a studio rule that moved a sample, say) or when the child failed, the build computes
them again, as it would have, and fails there if it must.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from blendspace_pipeline.motion.blend_model import SyncMode
from blendspace_pipeline.pipeline.blend_quality import blend_quality
from blendspace_pipeline.pipeline.forked import Children
from blendspace_pipeline.pipeline.to_document import maps_document
from blendspace_pipeline.space.document import BlendQualityDoc, BlendSpaceDocument
from blendspace_pipeline.space.model import BlendSpace


class EarlyQuality:
    """The maps of ``space`` (placed, its document to be written to ``out_dir``), computed in a
    forked child with ``jobs`` foot-skate workers: the rules here take a fraction of the maps'
    time (0.3 s against 1 s of CPU on 1,000 clips), and one worker left the maps on the critical
    path (measured with benchmarks/bench_build.py)."""

    def __init__(self, space: BlendSpace, out_dir: Path, jobs: int) -> None:
        sync = space.manifest.model.blend.sync
        task = functools.partial(_maps, space, out_dir, sync, jobs)
        self.children = Children([task], 1)

    def result(self, document: BlendSpaceDocument) -> BlendQualityDoc | None:
        """The maps when the child made them for ``document``'s samples, triangles and axes;
        None when it failed or saw others (the caller computes them)."""
        errors = self.children.wait()
        found = self.children.results.get(0)
        if errors or found is None:
            return None
        digest, quality = found
        return quality if digest == quality_inputs(document) else None

    def ready(self) -> bool:
        """Whether the child is done (`result` would not wait)."""
        return self.children.ready()

    def stop(self) -> None:
        """Kill the child if it still runs (the build failed or was interrupted)."""
        self.children.kill()


def quality_inputs(document: BlendSpaceDocument) -> str:
    """Digest of what the maps are computed from (8 ms for 1,000 samples): the axes, the
    triangles and the samples but their contacts and markers, which `maps_document` leaves out
    (the maps play each clip's measured contacts, not the document's)."""
    text = document.model_dump_json(
        include={"axes", "samples", "triangles"}, exclude={"samples": {"__all__": {"contacts", "markers"}}}
    )
    return hashlib.sha256(text.encode()).hexdigest()


def _maps(space: BlendSpace, out_dir: Path, sync: SyncMode, jobs: int) -> tuple[str, BlendQualityDoc]:
    document = maps_document(space, out_dir)
    return quality_inputs(document), blend_quality(space, document, {}, sync=sync, jobs=jobs)
