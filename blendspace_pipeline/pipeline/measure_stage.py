"""Read and measure every clip file of a manifest, in parallel when asked, through the cache."""

from __future__ import annotations

import importlib
import multiprocessing
import os
import pickle
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

from blendspace_pipeline.errors import ClipReadError, InputError, ManifestError
from blendspace_pipeline.manifest import LoadedManifest
from blendspace_pipeline.manifest.models import ClipEntry, SkeletonSettings
from blendspace_pipeline.manifest.paths import ResolvedClipFile
from blendspace_pipeline.memory import keep_freed_memory
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import Measurement, TimeRange, measure
from blendspace_pipeline.pipeline import cache
from blendspace_pipeline.pipeline.forked import explained_worker_loss, guided_chunks
from blendspace_pipeline.pipeline.progress import Progress
from blendspace_pipeline.readers import adapter_for, read_clips
from blendspace_pipeline.readers.dependencies import file_dependencies, may_have_dependencies
from blendspace_pipeline.readers.limits import check_regular
from blendspace_pipeline.readers.provenance import read_provenance
from blendspace_pipeline.space.model import MeasuredClip


class Job(NamedTuple):
    """One file to measure (see measure_file); small, so it pickles cheaply to a worker."""

    path: Path
    settings: RigSettings
    time_range: TimeRange
    project: Path | None
    library: str | None = None


Measured = list[tuple[str, Measurement]]
Result = Measured | InputError
# What a worker sends back: the file's content digest and cache key with its measurements (a few
# kilobytes), never the clip; input errors travel as values (their fields survive pickling).
Keyed = tuple[str, str, Measured, list[list[str]]] | InputError


def rig_settings(settings: SkeletonSettings) -> RigSettings:
    units = settings.units
    return RigSettings(
        units=float(units) if not isinstance(units, str) else units,
        up=settings.up,
        root=settings.root,
        left_hip=settings.left_hip,
        right_hip=settings.right_hip,
        forward=settings.forward,
        tpose=settings.tpose,
    )


def entry_settings(top: SkeletonSettings, entry: ClipEntry) -> SkeletonSettings:
    """The top-level `skeleton:` with the keys the clip's own entry sets replacing it."""
    if entry.skeleton is None:
        return top
    return top.model_copy(
        update={key: getattr(entry.skeleton, key) for key in entry.skeleton.model_fields_set}
    )


MADE_EARLIER_NOTE = (
    "made by an earlier build (its file says so): `tpose: drop` not applied, its first frame is motion"
)


def as_made(settings: RigSettings, made_earlier: bool) -> RigSettings:
    """``settings`` for a clip file an earlier build made (``made_earlier``: its provenance says
    so): it starts on motion, its sources' rest frames cut once, so `tpose: drop` does not apply
    (fed back as a source, it lost a real frame)."""
    return replace(settings, tpose="keep") if made_earlier and settings.tpose == "drop" else settings


def clip_settings(top: SkeletonSettings, entry: ClipEntry) -> RigSettings:
    """How the clips of ``entry`` are read, measured and remade (fixes, the foot-skate map)."""
    return rig_settings(entry_settings(top, entry))


def measure_file(
    path: Path, settings: RigSettings, time_range: TimeRange, project: Path | None = None
) -> Measured:
    """Measurements of every animation in ``path``, from the cache when the file is unchanged.

    ``project`` (the manifest's folder) is where the clip's references (glTF buffers, USD layers)
    may lie besides the clip's own folder."""
    return _measure_keyed(Job(path, settings, time_range, project))[2]


def _measure_keyed(job: Job) -> tuple[str, str, Measured, list[list[str]]]:
    """(the file's digest, its cache key, its measurements, its dependencies' state)."""
    path, settings, time_range, project, library = job
    check_regular(path, what="clip file")  # hashing a FIFO for the cache key would hang
    digest = cache.content_digest(path)
    opened: list[object] = []  # held until the clip is read: its USD layers are parsed once
    dependencies = (
        cache.known_dependencies(path, digest, project, lambda: file_dependencies(path, project, opened))
        if may_have_dependencies(path)
        else []
    )
    key = cache.cache_key(
        path, cache.dependency_settings(settings.cache_key(), dependencies), time_range, digest
    )
    cached = cache.load(key)
    if cached is None and library and time_range is None and not dependencies:
        from blendspace_pipeline.pipeline.library import lookup

        cached = lookup(library, digest, path, settings)
    if cached is not None:
        return digest, key, _with_dependencies(cached, dependencies), dependencies
    clips = read_clips(path, project=project)
    made = settings.tpose == "drop" and read_provenance(path) is not None
    settings = as_made(settings, made)
    # A file of several animations may hold a pose among them (Blender's one-key "TPose" action):
    # no motion to measure, and no entry can leave one animation of a file out, so it is left
    # out here and said on the others. Alone in its file it is the clip, and its error stands.
    poses = [clip.name for clip in clips if clip.frame_count < 2] if len(clips) > 1 else []
    if len(poses) == len(clips):
        poses = []
    measured = [(clip.name, measure(clip, settings, time_range)) for clip in clips if clip.name not in poses]
    if made:
        for _name, measurement in measured:
            measurement.notes.append(MADE_EARLIER_NOTE)
    for _name, measurement in measured:
        measurement.notes += [
            f"animation {pose!r} of this file is a single frame (a pose): left out" for pose in poses
        ]
    measured = _with_dependencies(measured, dependencies)
    cache.store(key, measured)
    return digest, key, measured, dependencies


def _with_dependencies(measured: Measured, dependencies: list[list[str]]) -> Measured:
    """``measured`` carrying the files the clip was read with (the build stamp watches them)."""
    files = [path for path, _, _ in dependencies]
    for _name, measurement in measured:
        measurement.dependencies = files
    return measured


def _measure_job(job: Job) -> Keyed:
    """Worker entry: reads and measures one file; the parent gathers the small results."""
    try:
        return _measure_keyed(job)
    except InputError as error:
        return _sendable(error)


def _sendable(error: InputError) -> InputError:
    """``error`` as a value that pickles back to the parent whatever this process has installed.

    It goes without its chain: once tblib's reducers are installed (`import distributed` does:
    a farm script using Dask, this project's `index`) the library exception it was raised from
    is pickled too, and usd-core's `Tf.ErrorException` holds `Tf.Error`s, which do not pickle,
    so the worker's whole answer failed as an internal error. The message, location and hint
    are all the parent reports."""
    error.__cause__ = error.__context__ = None
    error.__traceback__ = None
    try:
        pickle.loads(pickle.dumps(error))  # both ways: a subclass with its own __init__ may not load
    except Exception:  # a studio reader's error with an odd field: its text still gets through
        return InputError(
            error.message, path=error.path, line=error.line, column=error.column, hint=error.hint
        )
    return error


def library_store(explicit: str | None = None) -> str | None:
    """The shared library store builds read measurements from (`--library` or the variable)."""
    return explicit or os.environ.get(cache.LIBRARY_VARIABLE) or None


def measure_files(
    loaded: LoadedManifest,
    files: list[ResolvedClipFile],
    *,
    jobs: int = 1,
    progress: Progress | None = None,
    library: str | None = None,
    part: str = "clips",
) -> list[MeasuredClip]:
    """The measured clips of ``files``. ``part`` names which of the manifest's clip lists they
    are (its `clips:` or a style layer's): each keeps its own pack, so they do not evict each other."""
    top = loaded.model.skeleton
    store = library_store(library)
    if store:
        _check_store(loaded, store, warn=part == "clips")
    settings_of: dict[int, RigSettings] = {}  # one per manifest entry, not per file
    job_list: list[Job] = []
    for f in files:
        if id(f.entry) not in settings_of:
            settings_of[id(f.entry)] = clip_settings(top, f.entry)
        job_list.append(Job(f.path, settings_of[id(f.entry)], _range(f.entry), loaded.directory, store))
    results = _measure_all(job_list, cache.Pack(loaded.path, part), jobs, progress)
    results = _one_answer_per_skeleton(job_list, results)
    clips: list[MeasuredClip] = []
    failed: list[InputError] = []
    for resolved, result in zip(files, results, strict=True):
        if isinstance(result, InputError):
            failed.append(_at_entry(loaded, resolved, result))
        else:
            clips += _named(resolved, result)
    if failed:  # every unreadable clip at once: a studio fixing ten files does not run ten builds
        failed[0].more = failed[1:]
        raise failed[0]
    _reject_duplicate_names(loaded, clips)
    return clips


def _check_store(loaded: LoadedManifest, store: str, warn: bool) -> None:
    """A store the build cannot open is bad input (exit 2), said once, not a crash per clip. A
    store that is not there is not (a farm's first night, before `blendspace index` ran): the
    build measures every clip itself, and says so when ``warn`` (once a manifest: for its main clip
    list), since a typo in the path reads the same."""
    from blendspace_pipeline.pipeline.library import store_exists, store_problem

    found = store_problem(store)
    if found is not None:
        problem, hint = found
        raise InputError(
            f"the library store {store!r} {problem}",
            path=loaded.path,
            hint=f"{hint}, or drop --library / {cache.LIBRARY_VARIABLE}",
        )
    if warn and not store_exists(store):
        sys.stderr.write(
            f"blendspace: warning: the library store {store!r} does not exist: every clip is "
            f"measured here (check the path, or make the store with `blendspace index LIBRARY_DIR "
            f"--store {store}`)\n"
        )


def _measure_all(job_list: list[Job], pack: cache.Pack, jobs: int, progress: Progress | None) -> list[Result]:
    """Every job's measurements: from the manifest's pack with one `stat` per unchanged file, the
    rest read and measured (by ``jobs`` worker processes when there is more than one to do)."""
    results: list[Result | None] = [None] * len(job_list)
    stats: dict[int, os.stat_result] = {}
    todo: list[int] = []
    for index, job in enumerate(job_list):
        try:
            info = os.stat(job.path)
        except OSError:
            todo.append(index)  # the worker raises the error with the entry's line
            continue
        stats[index] = info
        digest = pack.digest(job.path, info)
        dependencies = pack.dependencies_of(job.path, info) if digest is not None else None
        if digest is not None and dependencies is not None:
            settings_key = cache.dependency_settings(job.settings.cache_key(), dependencies)
            key = cache.cache_key(job.path, settings_key, job.time_range, digest)
            measured = pack.load(key)
            if measured is not None:
                pack.remember(job.path, info, digest, key, measured, dependencies)
                results[index] = measured
                continue
        todo.append(index)
    done = len(job_list) - len(todo)
    if progress and done:
        progress(done, len(job_list), "cached")
    if jobs > 1 and _small_batch([stats[i].st_size if i in stats else 0 for i in todo]):
        jobs = 1
    for index, keyed in zip(todo, _run(jobs, [job_list[i] for i in todo]), strict=True):
        done += 1
        if progress:
            progress(done, len(job_list), job_list[index].path.name)
        if isinstance(keyed, InputError):
            results[index] = keyed
            continue
        digest, key, measured, dependencies = keyed
        if index in stats:
            pack.remember(job_list[index].path, stats[index], digest, key, measured, dependencies)
        results[index] = measured
    pack.save()
    return [r for r in results if r is not None]


# What the stages after measuring import first (triangulation): imported while the workers
# measure, so the build does not wait for it afterwards with a core idle (~0.3 s).
WARM_MODULES = ("scipy.spatial",)


# A pool forks its workers from a command with the pipeline loaded (~30 ms each) and they start
# cold: two small files to measure (a style layer's pair, an edit of two clips) are done here
# sooner (sample project at `--jobs 2`: 26 ms here against 85 ms through a pool per such list).
# Two long takes still go to workers: each measures for a second or more.
SMALL_BATCH_FILES = 2
SMALL_BATCH_BYTES = 4 * 1024 * 1024


def _small_batch(sizes: list[int]) -> bool:
    return len(sizes) <= SMALL_BATCH_FILES and sum(sizes) < SMALL_BATCH_BYTES


def _run(jobs: int, job_list: list[Job]) -> Iterator[Keyed]:
    if jobs > 1 and len(job_list) > 1:
        _import_readers(job_list)
        workers = min(jobs, len(job_list))
        # At most 16 clips (~0.1 s) a round trip through the pool's queues, the last ones single.
        chunks = [job_list[first:last] for first, last in guided_chunks(len(job_list), workers, 16)]
        with ProcessPoolExecutor(workers, _pool_context(), initializer=keep_freed_memory) as pool:
            results = pool.map(_measure_chunk, chunks)  # the workers are forked now
            # Joined before the pool closes: nothing forks later while the thread may hold an import lock.
            warming = _warm_imports()
            try:
                with explained_worker_loss("measuring"):
                    for chunk in results:
                        yield from chunk
            finally:
                if warming is not None:
                    warming.join()
    else:
        yield from map(_measure_job, job_list)


def _measure_chunk(jobs: list[Job]) -> list[Keyed]:
    """Worker entry: one chunk's jobs, in order (see `_measure_job`)."""
    return [_measure_job(job) for job in jobs]


def _import_readers(job_list: list[Job]) -> None:
    """The readers of the jobs' formats, imported here before the workers fork, so they inherit
    them. Otherwise every worker of every pool imports its own: the USD reader (usd-core and
    scipy) is ~0.5 s of CPU per worker, and a build with style layers starts a pool per clip list
    (the sample project's `--jobs 2` build took 0.7 s longer than `--jobs 1`). The parent needs
    them anyway: its USD writer imports usd-core, and re-measuring a clip runs here."""
    for suffix in sorted({job.path.suffix.lower() for job in job_list}):
        try:
            adapter_for(Path(f"clip{suffix}"))
        except (ClipReadError, ImportError):
            continue  # the worker meets the same error and reports it against the clip


def _pool_context() -> multiprocessing.context.BaseContext | None:
    """Forked workers on Linux, whatever Python's default (3.14 starts them from a fork server,
    which would not inherit the readers imported here); elsewhere Python's default (spawn on
    macOS and Windows, where `--jobs auto` is 1)."""
    if sys.platform.startswith("linux"):
        return multiprocessing.get_context("fork")
    return None


def _warm_imports() -> threading.Thread | None:
    missing = [name for name in WARM_MODULES if name not in sys.modules]
    if not missing:
        return None

    def load() -> None:
        for name in missing:
            try:
                importlib.import_module(name)
            except Exception:  # the stage that needs it imports it again and says why
                continue

    thread = threading.Thread(target=load, name="blendspace-warm-imports", daemon=True)
    thread.start()
    return thread


def _one_answer_per_skeleton(jobs: list[Job], results: list[Result]) -> list[Result]:
    """Clips of one skeleton (same joint names, hierarchy and rest offsets: one rig, one export)
    get one up axis and one unit.

    Where detection read them differently, the reading most of the confident clips share (else
    most of all clips) wins and the others are measured again with it, saying so in their notes.
    Only detected values are pooled: clips whose entry sets `skeleton.units` / `skeleton.up` keep
    them, and so do clips whose file states them (an FBX exported Z up beside the same rig's Y-up
    export: the file's axis had been replaced by the other's, and a walk read 100 deg/s of turn).
    A set that still disagrees is the `units-doubt` error naming the odd ones.
    """
    groups: dict[str, list[tuple[int, int]]] = {}
    for index, (job, result) in enumerate(zip(jobs, results, strict=True)):
        settings = job.settings
        if isinstance(result, InputError) or settings.units != "auto" or settings.up != "auto":
            continue
        for position, (_, measurement) in enumerate(result):
            stated = measurement.up_source != "detected" or measurement.units_source == "file"
            if measurement.skeleton_key and not stated:
                groups.setdefault(measurement.skeleton_key, []).append((index, position))
    redo: dict[int, tuple[str, float]] = {}
    for members in groups.values():
        readings = [_reading(results, member) for member in members]
        if len(set(readings)) < 2:
            continue
        confident = [
            reading
            for reading, member in zip(readings, members, strict=True)
            if not _guessed(results, member)
        ]
        pool = confident or readings
        consensus = max(sorted(set(pool)), key=pool.count)
        for reading, (index, _) in zip(readings, members, strict=True):
            if reading != consensus:
                redo[index] = consensus
    if not redo:
        return results
    pooled = list(results)
    for index, (up, units) in redo.items():
        agreed = replace(jobs[index].settings, up=up, units=units)
        again = _measure_job(jobs[index]._replace(settings=agreed))
        if isinstance(again, InputError):
            continue  # the reading of its own stands; units-doubt names it
        note = (
            f"up axis {up.upper()} and {units:.4g} m per unit taken from the other clips of the same "
            "skeleton (one rig, one answer)"
        )
        pooled[index] = [(name, replace(m, notes=[*m.notes, note])) for name, m in again[2]]
    return pooled


def _reading(results: list[Result], member: tuple[int, int]) -> tuple[str, float]:
    measurement = results[member[0]][member[1]][1]  # type: ignore[index]
    return measurement.up_axis, round(measurement.meters_per_unit, 9)


def _guessed(results: list[Result], member: tuple[int, int]) -> bool:
    measurement = results[member[0]][member[1]][1]  # type: ignore[index]
    return any(g.what in ("up axis", "units") for g in measurement.guesses)


def _at_entry(loaded: LoadedManifest, resolved: ResolvedClipFile, error: InputError) -> InputError:
    """An error without a line in the clip file (an unsupported format, a `range:` past the end,
    an unknown `skeleton.root`) points at the manifest entry that pulled the file in."""
    if error.line is not None:
        return error
    return InputError(
        f"{resolved.path}: {error.message}",
        path=loaded.path,
        line=resolved.line,
        column=resolved.column,
        hint=error.hint,
    )


def _range(entry: ClipEntry) -> TimeRange:
    if entry.range is None or entry.range == "auto":
        return entry.range
    return (float(entry.range[0]), float(entry.range[1]))


def _named(resolved: ResolvedClipFile, measured: list[tuple[str, Measurement]]) -> list[MeasuredClip]:
    clips = []
    for reader_name, measurement in measured:
        name = reader_name
        if resolved.entry.name:
            # "<name>/<animation>" keeps multi-animation files apart under a chosen name.
            name = (
                resolved.entry.name
                if len(measured) == 1
                else f"{resolved.entry.name}/{reader_name.split('/')[-1]}"
            )
        clips.append(
            MeasuredClip(
                name,
                resolved.path,
                resolved.entry,
                resolved.line,
                resolved.column,
                measurement,
                extra={"animation": reader_name},
            )
        )
    return clips


def _reject_duplicate_names(loaded: LoadedManifest, clips: list[MeasuredClip]) -> None:
    seen: dict[str, MeasuredClip] = {}
    for clip in clips:
        if clip.name in seen:
            first = seen[clip.name]
            raise ManifestError(
                f"two clips are named {clip.name!r}: {first.source} (line {first.line}) and {clip.source}",
                path=loaded.path,
                line=clip.line,
                column=clip.column,
                hint="give one of the entries its own `name:`; clip names must be unique in a blend space",
            )
        seen[clip.name] = clip
