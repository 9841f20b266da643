"""The document's `blend_quality`: the blend as the engine plays it, over the hull.

Trajectory error and drift come from the document (`space.runtime_blend`); foot skate needs the
poses, so every sample's clip is read again (generated clips come from the fix loop) and the
blend is played at each grid point inside the hull (`motion.blend_model.play`). Foot skate is
computed on every other grid point and the grid filled from its nearest computed neighbour:
the blend changes smoothly inside a triangle, and it keeps a build's cost to a second or two.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.blend_model import (
    DEFAULT_SYNC,
    PreparedClip,
    SyncMode,
    play,
    playback_rates,
    prepare,
)
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops.blend import without_rest_frame
from blendspace_pipeline.motion.contacts import FootContacts
from blendspace_pipeline.motion.measure import trim
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.pipeline.measure_stage import rig_settings
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.space.document import BlendQualityDoc, BlendSpaceDocument, Grid
from blendspace_pipeline.space.model import BlendSpace, Sample
from blendspace_pipeline.space.runtime_blend import DEFAULT_GRID, RuntimeGrid, runtime_grid, sample_period

SKATE_STEP = 2  # foot skate on every other grid point


def _grid(values: FloatArray) -> Grid:
    return [[None if not np.isfinite(v) else round(float(v), 5) for v in row] for row in values]


def _stats(name: str, values: FloatArray) -> dict[str, float]:
    finite = values[np.isfinite(values)]
    if not finite.size:
        return {}
    return {f"{name}_max": round(float(finite.max()), 5), f"{name}_mean": round(float(finite.mean()), 5)}


def _source_clip(sample: Sample, generated: Mapping[str, Clip], project: Path | None) -> Clip | None:
    if sample.generated:
        return generated.get(sample.name)
    animation = str(sample.clip.extra.get("animation", sample.name))
    try:
        clips = read_clips(sample.clip.source, project=project)
    except (InputError, OSError):
        return None
    for clip in clips:
        if clip.name == animation:
            return trim(clip, sample.clip.time_range)
    return None


class PreparedSamples:
    """Samples' clips ready to play, read on first use: the skate grid touches only the clips of
    triangles it samples, a few dozen in a thousand-clip space."""

    def __init__(self, space: BlendSpace, generated: Mapping[str, Clip]) -> None:
        self.space = space
        self.generated = generated
        self.settings = rig_settings(space.manifest.model.skeleton)
        self.cache: dict[int, PreparedClip | None] = {}

    def __getitem__(self, index: int) -> PreparedClip | None:
        if index not in self.cache:
            self.cache[index] = self._prepare(self.space.samples[index])
        return self.cache[index]

    def _prepare(self, sample: Sample) -> PreparedClip | None:
        m = sample.clip.measurement
        if m.contacts is None:
            return None
        clip = _source_clip(sample, self.generated, self.space.manifest.directory)
        if clip is None or clip.frame_count < 4:
            return None
        clip = without_rest_frame(clip, self.settings)
        contacts = FootContacts.from_json(m.contacts, clip.duration)
        return prepare(clip, self.settings, m.meters_per_unit, contacts)


def foot_skate_grid(
    space: BlendSpace, doc: BlendSpaceDocument, grid: RuntimeGrid, prepared: PreparedSamples
) -> FloatArray:
    settings = rig_settings(space.manifest.model.skeleton)
    ny, nx = grid.distance.shape
    skate = np.full((ny, nx), np.nan)
    computed = np.zeros((ny, nx), dtype=bool)
    for row in range(0, ny, SKATE_STEP):
        for col in range(0, nx, SKATE_STEP):
            pairs = grid.weights[row * nx + col]
            if not pairs:
                continue
            clips = [prepared[i] for i, _ in pairs]
            if any(c is None for c in clips):
                continue
            weights = [w for _, w in pairs]
            samples = [doc.samples[i] for i, _ in pairs]
            rates = playback_rates(
                weights,
                [s.features.get("duration", 1.0) for s in samples],
                [sample_period(s) for s in samples],
                grid.sync,
            )
            played = play([c for c in clips if c is not None], weights, rates, settings, fps=20.0)
            if played.foot_sliding is not None:
                skate[row, col] = played.foot_sliding
                computed[row, col] = True
    if computed.any():
        from scipy.ndimage import distance_transform_edt

        _, (rows, cols) = distance_transform_edt(~computed, return_indices=True)
        filled = skate[rows, cols]
        skate = np.where(grid.inside, filled, np.nan)
    return skate


def blend_quality(
    space: BlendSpace,
    doc: BlendSpaceDocument,
    generated: Mapping[str, Clip] | None = None,
    *,
    sync: SyncMode = DEFAULT_SYNC,
    resolution: int = DEFAULT_GRID,
) -> BlendQualityDoc:
    grid = runtime_grid(doc, sync, resolution)
    has_feet = any(s.clip.measurement.contacts is not None for s in space.samples)
    skate = foot_skate_grid(space, doc, grid, PreparedSamples(space, generated or {})) if has_feet else None
    if skate is not None and not np.isfinite(skate).any():
        skate = None  # no blend could be played (clips unreadable or without feet)
    summary = {
        **_stats("trajectory_error", grid.distance),
        **_stats("drift", grid.drift),
        **_stats("drift_turn", grid.drift_turn),
        **(_stats("foot_skate", skate) if skate is not None else {}),
    }
    return BlendQualityDoc(
        sync=sync,
        horizon=grid.horizon,
        xs=[round(float(v), 6) for v in grid.xs],
        ys=[round(float(v), 6) for v in grid.ys],
        trajectory_error=_grid(grid.distance),
        drift=_grid(grid.drift),
        drift_turn=_grid(grid.drift_turn),
        foot_skate=_grid(skate) if skate is not None else None,
        summary=summary,
    )
