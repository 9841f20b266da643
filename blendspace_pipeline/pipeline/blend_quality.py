"""The document's `blend_quality`: the blend as the engine plays it, over the hull.

Trajectory error and drift come from the document (`space.runtime_blend`); foot skate needs the
poses, so every sample's clip is read again (generated clips come from the fix loop) and the
blend is played at each grid point inside the hull (`motion.blend_model.play`). Foot skate is
computed on every other grid point and the grid filled from its nearest computed neighbour:
the blend changes smoothly inside a triangle, and it keeps a build's cost to a second or two.

Each computed grid point is remembered in the cache folder (`pipeline.cache`, `skate/`) under a
key of everything the number depends on: per blended sample its file's content digest, name,
animation, trim range and the measured contacts and units (a generated clip: a digest of its
arrays), the weights and playback rates, the rig settings, the sync mode, the tool version and
the revisions. A rebuild after one clip was edited reads and plays only the points whose blend
involves that clip (or whose weights moved); every other point comes from the cache unchanged,
so the document is byte-identical to a cold build's.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from blendspace_pipeline import __version__
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
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.up_axis import y_up
from blendspace_pipeline.motion.contacts import FootContacts
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import trim
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.pipeline import cache
from blendspace_pipeline.pipeline.cache import write_atomic
from blendspace_pipeline.pipeline.forked import explained_worker_loss, guided_chunks
from blendspace_pipeline.pipeline.measure_stage import clip_settings
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.space.document import BlendQualityDoc, BlendSpaceDocument, Grid
from blendspace_pipeline.space.model import BlendSpace, Sample
from blendspace_pipeline.space.runtime_blend import DEFAULT_GRID, RuntimeGrid, runtime_grid, sample_period

SKATE_STEP = 2  # foot skate on every other grid point
SKATE_FPS = 20.0  # ticks per second of the played blend
# Bumped whenever the same blend would give another foot skate (play, prepare, the rest-frame
# cut), so a cache never serves numbers of older code under an unchanged version.
SKATE_REVISION = 2


def _grid(values: FloatArray) -> Grid:
    return [[None if not np.isfinite(v) else round(float(v), 5) for v in row] for row in values]


def _stats(name: str, values: FloatArray) -> dict[str, float]:
    finite = values[np.isfinite(values)]
    if not finite.size:
        return {}
    return {f"{name}_max": round(float(finite.max()), 5), f"{name}_mean": round(float(finite.mean()), 5)}


def _source_clip(sample: Sample, generated: Mapping[str, Clip], project: Path | None) -> Clip | None:
    """The frames of the sample's animation that it was measured on (`Measurement.range_used`:
    its `range:`, or what `range: auto` chose, less a rest frame and held keys): the foot contacts
    the blend plays are of exactly these frames. Read from the measurement, not decided again
    (that was a sixth of a cold 1,000-clip map's time)."""
    used = sample.clip.measurement.range_used
    if sample.generated:
        found = generated.get(sample.name)
        return trim(found, used) if found is not None else None
    animation = str(sample.clip.extra.get("animation", sample.name))
    try:
        clips = read_clips(sample.clip.source, project=project)
    except (InputError, OSError):
        return None
    for clip in clips:
        if clip.name == animation:
            return trim(clip, used)
    return None


class PreparedSamples:
    """Samples' clips ready to play, read on first use: the skate grid touches only the clips of
    triangles it samples, a few dozen in a thousand-clip space."""

    def __init__(self, space: BlendSpace, generated: Mapping[str, Clip]) -> None:
        self.space = space
        self.generated = generated
        self.cache: dict[int, PreparedClip | None] = {}
        self.keys: dict[int, str] = {}
        self.settings: dict[int, RigSettings] = {}

    def settings_of(self, index: int) -> RigSettings:
        """How sample ``index``'s clip is read: its entry's `skeleton:` keys over the top-level
        ones (a generated clip's entry carries its sources' keys), as it was measured."""
        if index not in self.settings:
            top = self.space.manifest.model.skeleton
            self.settings[index] = clip_settings(top, self.space.samples[index].clip.entry)
        return self.settings[index]

    def played_as(self, index: int) -> RigSettings:
        """`settings_of`, for the clip as it is played: a Z-up take is turned Y up beside Y-up ones,
        as an engine imports it (`_prepare`)."""
        settings = self.settings_of(index)
        return (
            replace(settings, up="y")
            if self.space.samples[index].clip.measurement.up_axis == "z"
            else settings
        )

    def __getitem__(self, index: int) -> PreparedClip | None:
        if index not in self.cache:
            self.cache[index] = self._prepare(self.space.samples[index], self.played_as(index))
        return self.cache[index]

    def key(self, index: int) -> str:
        """What sample ``index`` brings to a blend, without reading its clip (see the module)."""
        if index not in self.keys:
            self.keys[index] = self._key(self.space.samples[index], self.settings_of(index))
        return self.keys[index]

    def _key(self, sample: Sample, settings: RigSettings) -> str:
        m = sample.clip.measurement
        digest = hashlib.sha256()
        described = [m.contacts, repr(m.meters_per_unit), settings.cache_key()]
        digest.update(json.dumps(described, sort_keys=True).encode())
        if sample.generated:
            clip = self.generated.get(sample.name)
            if clip is None:
                digest.update(b"|missing generated clip")
            else:
                digest.update(f"|{clip.name}|{clip.fps!r}|{clip.meters_per_unit!r}|{clip.up_axis}|".encode())
                digest.update(repr(clip.skeleton).encode())
                digest.update(np.ascontiguousarray(clip.rotations, dtype=np.float64).tobytes())
                digest.update(np.ascontiguousarray(clip.translations, dtype=np.float64).tobytes())
            return digest.hexdigest()
        source = sample.clip.source
        try:
            content = cache.content_digest(source)
        except OSError:
            content = "unreadable"
        animation = str(sample.clip.extra.get("animation", sample.name))
        played = sample.clip.measurement.range_used  # the frames `_source_clip` plays
        digest.update(f"|{content}|{source.name}|{animation}|{played!r}".encode())
        return digest.hexdigest()

    def _prepare(self, sample: Sample, settings: RigSettings) -> PreparedClip | None:
        m = sample.clip.measurement
        if m.contacts is None:
            return None
        clip = _source_clip(sample, self.generated, self.space.manifest.directory)
        if clip is None or clip.frame_count < 4:
            return None
        contacts = FootContacts.from_json(m.contacts, clip.duration)
        if m.up_axis == "z":  # see `played_as`
            clip = y_up(clip)
        try:
            return prepare(clip, settings, m.meters_per_unit, contacts)
        except IncompatibleClips:  # an X-up take: measured, but not played (as an unreadable one)
            return None


def _play_point(
    prepared: PreparedSamples,
    indices: Sequence[int],
    weights: Sequence[float],
    rates: Sequence[float],
) -> float | None:
    """The foot skate of one blend, or None when it cannot be played (a clip unreadable or
    without feet, clips of different skeletons) or has no planted foot. Each clip is prepared
    with its own settings; the blended pose has the first clip's skeleton, and its settings."""
    clips = [prepared[i] for i in indices]
    ready = [c for c in clips if c is not None]
    if len(ready) < len(clips) or not all(ready[0].clip.skeleton.same_layout(c.clip.skeleton) for c in ready):
        return None  # other joint names or hierarchy: no engine blends them (see `inconsistent-skeleton`)
    played = play(ready, weights, rates, prepared.played_as(indices[0]), fps=SKATE_FPS)
    return played.foot_sliding


def _base_key(space: BlendSpace, sync: SyncMode) -> str:
    """What every point of ``space`` shares: code, sync, where references may be read from (each
    sample's rig settings are in its own key)."""
    return json.dumps(
        [
            __version__,
            cache.MEASUREMENT_REVISION,
            SKATE_REVISION,
            SKATE_FPS,
            sync,
            str(space.manifest.directory),
            os.environ.get("BLENDSPACE_MAX_FRAMES", ""),
        ]
    )


def _point_key(base: str, samples: Sequence[str], weights: Sequence[float], rates: Sequence[float]) -> str:
    # repr: exact floats, so a weight that moved in its last bit is another blend.
    described = json.dumps([base, list(samples), [repr(w) for w in weights], [repr(r) for r in rates]])
    return hashlib.sha256(described.encode()).hexdigest()


def _entry(key: str) -> Path | None:
    folder = cache.cache_dir()
    return None if folder is None else folder / "skate" / key[:2] / f"{key}.json"


def _load(key: str | None) -> tuple[bool, float | None]:
    entry = _entry(key) if key else None
    if entry is None:
        return False, None
    try:
        value = json.loads(entry.read_text(encoding="utf-8"))["foot_sliding"]
    except (OSError, ValueError, KeyError, TypeError):
        return False, None
    if value is None or isinstance(value, float):
        return True, value
    return False, None  # not what we write: computed again and rewritten


def _store(key: str | None, value: float | None) -> None:
    entry = _entry(key) if key else None
    if entry is not None:
        # json writes a float's repr, which reads back to the same float.
        write_atomic(entry, json.dumps({"foot_sliding": None if value is None else float(value)}))


# A grid point to play: row, column, its samples, their weights and rates, and its cache key.
Point = tuple[int, int, list[int], list[float], list[float], str | None]

# What forked workers play from: set just before the pool forks, so the prepared clips and the
# space are inherited by the workers' memory instead of being pickled to them.
_FORKED: PreparedSamples | None = None
# Below this many blends to play, starting worker processes costs more than it saves.
PARALLEL_MIN_POINTS = 8
# How long blends are played here before deciding on workers, and how much playing left (at the
# pace of those first blends) makes them worth it. Forking two workers from a command with the
# pipeline loaded and their own clip reads cost ~0.1 s (sample project, 2 vCPUs), so the rest
# must take at least twice that here; the first blends' pace includes reading their clips, which
# later blends mostly find read, and overstates the rest about twofold (test spaces: 17 ms a blend
# at first, 4.5 ms on average).
SERIAL_FIRST_SECONDS = 0.05
POOL_WORTH_SECONDS = 0.5


def foot_skate_grid(
    space: BlendSpace,
    doc: BlendSpaceDocument,
    grid: RuntimeGrid,
    prepared: PreparedSamples,
    jobs: int = 1,
    meanwhile: Callable[[], None] | None = None,
) -> FloatArray:
    base = _base_key(space, grid.sync) if cache.cache_dir() is not None else ""
    ny, nx = grid.distance.shape
    skate = np.full((ny, nx), np.nan)
    computed = np.zeros((ny, nx), dtype=bool)
    to_play: list[Point] = []
    for row in range(0, ny, SKATE_STEP):
        for col in range(0, nx, SKATE_STEP):
            pairs = grid.weights[row * nx + col]
            if not pairs:
                continue
            weights = [w for _, w in pairs]
            samples = [doc.samples[i] for i, _ in pairs]
            rates = playback_rates(
                weights,
                [s.features.get("duration", 1.0) for s in samples],
                [sample_period(s) for s in samples],
                grid.sync,
            )
            key = _point_key(base, [prepared.key(i) for i, _ in pairs], weights, rates) if base else None
            found, value = _load(key)
            if not found:
                to_play.append((row, col, [i for i, _ in pairs], weights, rates, key))
            elif value is not None:
                skate[row, col] = value
                computed[row, col] = True
    played = _play_all(prepared, to_play, jobs, meanwhile)
    for (row, col, *_, key), value in zip(to_play, played, strict=True):
        _store(key, value)
        if value is not None:
            skate[row, col] = value
            computed[row, col] = True
    if computed.any():
        from scipy.ndimage import distance_transform_edt

        _, (rows, cols) = distance_transform_edt(~computed, return_indices=True)
        filled = skate[rows, cols]
        skate = np.where(grid.inside, filled, np.nan)
    return skate


def _play_all(
    prepared: PreparedSamples,
    points: list[Point],
    jobs: int,
    meanwhile: Callable[[], None] | None = None,
) -> list[float | None]:
    """Every point's foot skate, in ``jobs`` forked processes when there is enough to play (a cold
    build: each point reads and prepares the clips of its triangle). The points are dealt out in
    chunks of consecutive points of one triangle, mostly, so a clip is read about once; the values
    are the same as played here.
    ``meanwhile`` runs in this process while the workers play (only then: the caller runs it
    itself when it was not called).

    The first points are played here for `SERIAL_FIRST_SECONDS`: the rest goes to workers only
    when, at that pace, it would take `POOL_WORTH_SECONDS` or more. A small space's map is done
    before a pool would have started (the sample project: 25 blends, 0.1 s here and 0.2 s through
    a pool), and a big one's workers inherit the clips read so far."""

    def here(index: int) -> float | None:
        point = points[index]
        return _play_point(prepared, point[2], point[3], point[4])

    fork = "fork" in multiprocessing.get_all_start_methods()
    if jobs < 2 or len(points) < PARALLEL_MIN_POINTS or not fork:
        return [here(index) for index in range(len(points))]
    order = sorted(range(len(points)), key=lambda i: sorted(points[i][2]))
    values: list[float | None] = [None] * len(points)
    start, done = time.perf_counter(), 0
    while done < len(order) and time.perf_counter() - start < SERIAL_FIRST_SECONDS:
        values[order[done]] = here(order[done])
        done += 1
    rest = order[done:]
    pace = (time.perf_counter() - start) / max(done, 1)
    if len(rest) < 2 or pace * len(rest) < POOL_WORTH_SECONDS:
        for index in rest:
            values[index] = here(index)
        return values
    # Chunks of consecutive points (of one triangle, mostly): a worker prepares a chunk's clips once
    # (a triangle split between chunks is read by both workers: 1-2 % more reads on 1,000 clips).
    chunks = [
        [points[i][2:5] for i in rest[first:last]] for first, last in guided_chunks(len(rest), jobs, 16)
    ]
    global _FORKED
    _FORKED = prepared
    try:
        with ProcessPoolExecutor(
            min(jobs, len(chunks)), mp_context=multiprocessing.get_context("fork")
        ) as pool:
            results = pool.map(_play_chunk, chunks)  # submitted: the workers start now
            if meanwhile is not None:
                meanwhile()
            with explained_worker_loss("foot-skate"):
                played = [value for chunk in results for value in chunk]
    finally:
        _FORKED = None
    for index, value in zip(rest, played, strict=True):
        values[index] = value
    return values


def _play_chunk(chunk: list[tuple[list[int], list[float], list[float]]]) -> list[float | None]:
    """Worker: play the chunk's blends with the prepared clips inherited from the parent."""
    assert _FORKED is not None, "runs only in a worker forked by _play_all"
    return [_play_point(_FORKED, indices, weights, rates) for indices, weights, rates in chunk]


def blend_quality(
    space: BlendSpace,
    doc: BlendSpaceDocument,
    generated: Mapping[str, Clip] | None = None,
    *,
    sync: SyncMode = DEFAULT_SYNC,
    resolution: int = DEFAULT_GRID,
    jobs: int = 1,
    meanwhile: Callable[[], None] | None = None,
) -> BlendQualityDoc:
    """The blend quality maps of ``doc``. ``meanwhile``: work for this process while forked
    workers play the foot-skate map (see `_play_all`); it may not be called at all."""
    grid = runtime_grid(doc, sync, resolution)
    has_feet = any(s.clip.measurement.contacts is not None for s in space.samples)
    prepared = PreparedSamples(space, generated or {})
    skate = foot_skate_grid(space, doc, grid, prepared, jobs, meanwhile) if has_feet else None
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
