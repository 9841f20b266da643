"""The measure stage's shortcuts: the manifest's pack of measurements, the shared library store,
and worker processes. Each must give exactly what measuring the files here gives."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import asdict, replace
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.manifest import load_manifest
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.motion.detect import DetectionGuess, RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import cache, forked, measure_stage
from blendspace_pipeline.pipeline.measure_stage import measure_files
from blendspace_pipeline.space.model import MeasuredClip
from blendspace_pipeline.writers.bvh import write_bvh_clip

SPECS = [
    GaitSpec("idle", duration=1.0),
    GaitSpec("walk", speed=1.4, duration=1.0),
    GaitSpec("run_left", speed=4.0, turn_rate=90.0, duration=1.0),
]


def _project(root: Path, *, settled: bool = True) -> Path:
    clips = root / "clips"
    clips.mkdir(parents=True)
    for spec in SPECS:
        write_bvh_clip(generate(spec), clips / f"{spec.name}.bvh")
        if settled:  # as if written a minute ago: digests of racy files are not remembered
            os.utime(clips / f"{spec.name}.bvh", ns=(1_700_000_000_000_000_000,) * 2)
    manifest = root / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    return manifest


def _measured(manifest: Path, **options: object) -> list[MeasuredClip]:
    loaded = load_manifest(manifest)
    return measure_files(loaded, resolve_clip_files(loaded), **options)  # type: ignore[arg-type]


def _summary(clips: list[MeasuredClip]) -> list[tuple[str, dict[str, object]]]:
    return [(c.name, asdict(c.measurement)) for c in clips]


class Counter:
    """Counts real measurements (the reader + measure), delegating to the real code."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.calls = 0
        real = measure_stage.measure

        def counted(*args: object, **kwargs: object) -> object:
            self.calls += 1
            return real(*args, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr(measure_stage, "measure", counted)


def test_the_pack_serves_a_warm_run_without_the_per_clip_entries(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    counter = Counter(monkeypatch)
    cold = _measured(manifest)
    assert counter.calls == 3
    packs = list((tmp_path / "cache" / "packs").glob("*.json"))
    assert len(packs) == 1
    # Without the per-clip entries and digest memos, only the pack can answer.
    for entry in (tmp_path / "cache").glob("*.json"):
        entry.unlink()
    shutil.rmtree(tmp_path / "cache" / "digests", ignore_errors=True)
    assert _summary(_measured(manifest)) == _summary(cold)
    assert counter.calls == 3

    # An edited clip is measured again (and only it); the pack then holds the new reading.
    write_bvh_clip(generate(GaitSpec("walk", speed=2.0, duration=1.0)), tmp_path / "p" / "clips" / "walk.bvh")
    edited = _measured(manifest)
    assert counter.calls == 4
    assert {c.name: round(c.measurement.features["speed"], 1) for c in edited}["walk"] == 2.0
    assert _summary(_measured(manifest)) == _summary(edited)
    assert counter.calls == 4  # a racy file is hashed again, and the per-clip entry answers


def test_a_damaged_pack_is_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    cold = _measured(manifest)
    for pack in (tmp_path / "cache" / "packs").glob("*.json"):
        pack.write_text('{"digests": {"x": 1}, "entries": [', encoding="utf-8")
    assert _summary(_measured(manifest)) == _summary(cold)
    for pack in (tmp_path / "cache" / "packs").glob("*.json"):
        # Wrong shapes inside a readable pack: measured again, not a crash.
        pack.write_text('{"digests": {}, "entries": {"k": [{"name": 3}]}}', encoding="utf-8")
    assert _summary(_measured(manifest)) == _summary(cold)


def test_worker_processes_measure_what_one_process_measures(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    manifest = _project(tmp_path / "p")
    assert _summary(_measured(manifest, jobs=2)) == _summary(_measured(manifest, jobs=1))


@pytest.mark.parametrize("count", [1, 2, 3, 7, 31, 128, 1000, 10_007])
@pytest.mark.parametrize("workers", [2, 3, 8])
def test_pool_chunks_cover_every_item_once_and_shrink_to_single_items(count: int, workers: int) -> None:
    chunks = forked.guided_chunks(count, workers, 16)
    assert [first for first, _ in chunks] == [0] + [last for _, last in chunks[:-1]]
    assert chunks[-1][1] == count
    sizes = [last - first for first, last in chunks]
    assert all(1 <= size <= 16 for size in sizes)
    assert sizes == sorted(sizes, reverse=True)  # the small ones last: the workers end together
    assert sizes[-1] == 1
    if count >= 1000:
        assert max(sizes) == 16 and len(chunks) < count / 5  # few round trips
        assert sum(size == 1 for size in sizes) >= workers  # each worker's last pick is one clip


def test_workers_measuring_is_when_the_parent_imports_triangulation(tmp_path: Path) -> None:
    """With --jobs 2 the parent imports what the next stage needs (`WARM_MODULES`) while the
    workers measure, and is done with it when the stage returns (nothing forks mid-import);
    with --jobs 1 nothing is imported ahead."""
    manifest = _project(tmp_path / "p")
    code = (
        "import sys, threading\n"
        "from pathlib import Path\n"
        "from blendspace_pipeline.manifest import load_manifest\n"
        "from blendspace_pipeline.manifest.paths import resolve_clip_files\n"
        "from blendspace_pipeline.pipeline.measure_stage import WARM_MODULES, measure_files\n"
        "assert not any(name in sys.modules for name in WARM_MODULES)\n"
        f"loaded = load_manifest(Path({str(manifest)!r}))\n"
        "measure_files(loaded, resolve_clip_files(loaded), jobs=int(sys.argv[1]))\n"
        "warm = all(name in sys.modules for name in WARM_MODULES)\n"
        "assert warm == (sys.argv[1] == '2'), (sys.argv[1], warm)\n"
        "assert all(t.name != 'blendspace-warm-imports' for t in threading.enumerate())\n"
    )
    env = {**os.environ, "BLENDSPACE_CACHE_DIR": "off"}
    for jobs in ("1", "2"):
        subprocess.run([sys.executable, "-c", code, jobs], check=True, env=env, timeout=120)


def test_workers_inherit_the_readers_of_their_formats(tmp_path: Path) -> None:
    """With --jobs 2 the parent imports the readers the files need before the workers fork:
    every worker of every pool (one per clip list) importing usd-core and scipy itself made the
    sample project's `--jobs 2` build 0.7 s slower than `--jobs 1`."""
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    clips = tmp_path / "clips"
    clips.mkdir()
    for spec in SPECS:
        write_usd_clip(generate(spec), clips / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.usda\n", encoding="utf-8")
    seen = tmp_path / "seen.txt"
    code = (
        "import sys\n"
        "from pathlib import Path\n"
        "from blendspace_pipeline.manifest import load_manifest\n"
        "from blendspace_pipeline.manifest.paths import resolve_clip_files\n"
        "from blendspace_pipeline.pipeline import measure_stage\n"
        "READER = 'blendspace_pipeline.readers.usd'\n"
        "assert READER not in sys.modules\n"
        "original = measure_stage._measure_keyed\n"
        "def noting(job):\n"
        f"    with open({str(seen)!r}, 'a') as log:\n"
        "        log.write(f'{READER in sys.modules}\\n')\n"
        "    return original(job)\n"
        "measure_stage._measure_keyed = noting\n"
        f"loaded = load_manifest(Path({str(manifest)!r}))\n"
        "clips = measure_stage.measure_files(loaded, resolve_clip_files(loaded), jobs=2)\n"
        "assert len(clips) == 3, clips\n"
    )
    env = {**os.environ, "BLENDSPACE_CACHE_DIR": "off"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)
    assert seen.read_text(encoding="utf-8").split() == ["True"] * len(SPECS)


def test_a_worker_killed_mid_measure_is_one_line_that_says_what_to_do(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The out-of-memory killer ending a worker: exit 3 with a line naming the cause and `--jobs 1`
    (not `BrokenProcessPool`), no traceback, nothing written."""
    if not hasattr(os, "fork"):
        pytest.skip("forked workers inherit the patch")
    import signal

    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    manifest = _project(tmp_path / "p")
    original = measure_stage._measure_keyed

    def dies_on_walk(job: measure_stage.Job) -> tuple[str, str, list[tuple[str, object]]]:
        if job.path.stem == "walk" and os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return original(job)  # type: ignore[return-value]

    parent = os.getpid()
    monkeypatch.setattr(measure_stage, "_measure_keyed", dies_on_walk)
    with pytest.raises(forked.WorkerLost, match="--jobs 1"):
        _measured(manifest, jobs=2)
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--jobs", "2"]) == 3
    err = capsys.readouterr().err
    assert "a measuring process ended without an answer" in err and "--jobs 1" in err
    assert "Traceback" not in err and len(err.splitlines()) == 1
    assert not out.exists()
    assert _summary(_measured(manifest, jobs=1)) != []  # in this process the patch does not kill


def test_a_clip_error_from_a_worker_pickles_with_tblib_installed(tmp_path: Path) -> None:
    """`import distributed` (a farm script using Dask) installs tblib's exception reducers, which
    pickle an error's whole chain: an unreadable USD clip's error, raised from usd-core's
    `Tf.ErrorException`, then failed to come back from a worker (exit 3, `Pickling of
    "pxr.Tf.Error"`). It must be the clip's own error with its location, as in one process."""
    pytest.importorskip("tblib")
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    clips = tmp_path / "clips"
    clips.mkdir()
    for spec in SPECS:
        write_usd_clip(generate(spec), clips / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")
    (clips / "walk.usda").write_bytes(b"")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.usda\n", encoding="utf-8")
    code = (
        "import sys\n"
        "import blendspace_pipeline.errors\n"
        "from tblib import pickling_support\n"
        "pickling_support.install()\n"  # after our error classes exist, as in a long-lived process
        "from blendspace_pipeline.cli import main\n"
        f"sys.exit(main(['check', {str(manifest)!r}, '--jobs', sys.argv[1]]))\n"
    )
    env = {**os.environ, "BLENDSPACE_CACHE_DIR": "off"}
    for jobs in ("1", "2"):
        done = subprocess.run(
            [sys.executable, "-c", code, jobs], env=env, capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 2, (jobs, done.stderr)
        assert f"{clips / 'walk.usda'}" in done.stderr and "not a readable USD file" in done.stderr, (
            done.stderr
        )
        assert "internal error" not in done.stderr and "Traceback" not in done.stderr


def test_an_error_that_does_not_pickle_still_reaches_the_parent() -> None:
    class Odd(measure_stage.InputError):
        pass

    error = Odd("bad take", path=Path("a.bvh"), line=3, column=None, hint="re-export it")
    error.handle = lambda: None  # type: ignore[attr-defined]  # a lambda does not pickle
    sent = measure_stage._sendable(error)
    assert type(sent) is measure_stage.InputError
    assert (sent.message, sent.path, sent.line, sent.hint) == ("bad take", Path("a.bvh"), 3, "re-export it")


class TakeError(measure_stage.InputError):
    """A studio reader's error with an __init__ of its own: it pickles, and fails to load."""

    def __init__(self, path: Path, take: str) -> None:
        super().__init__(f"take {take} is empty", path=path, hint="re-export the take")


def test_an_error_that_pickles_but_does_not_load_still_reaches_the_parent() -> None:
    import pickle

    error = TakeError(Path("t.bvh"), "walk")
    with pytest.raises(TypeError):
        pickle.loads(pickle.dumps(error))
    sent = measure_stage._sendable(error)
    assert pickle.loads(pickle.dumps(sent)).render() == error.render()


def test_two_small_files_are_measured_here_and_more_or_bigger_ones_by_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A pool costs a fork per worker: at --jobs 2 two small files (a style layer's pair) are
    measured in this process; a third file, or two files past `SMALL_BATCH_BYTES`, go to workers."""
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    pools: list[int] = []
    real = measure_stage.ProcessPoolExecutor

    def counted(*args: object, **kwargs: object) -> object:
        pools.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(measure_stage, "ProcessPoolExecutor", counted)
    manifest = _project(tmp_path / "p")
    assert len(_measured(manifest, jobs=2)) == 3 and pools == [1]
    (tmp_path / "p" / "clips" / "idle.bvh").unlink()
    pair = _summary(_measured(manifest, jobs=2))
    assert len(pair) == 2 and pools == [1]  # measured here
    monkeypatch.setattr(measure_stage, "SMALL_BATCH_BYTES", 1000)  # as if two long takes
    assert _summary(_measured(manifest, jobs=2)) == pair and pools == [1, 1]


def test_builds_read_the_library_store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("fsspec")
    from blendspace_pipeline.pipeline.library import measure_into_store

    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    expected = _summary(_measured(manifest))
    shutil.rmtree(tmp_path / "cache")

    # The library holds the same bytes under other names (a mocap archive's own naming).
    store = str(tmp_path / "store")
    library = tmp_path / "library"
    library.mkdir()
    for spec in SPECS:
        copy = library / f"session3_take_{spec.name}.bvh"
        shutil.copyfile(tmp_path / "p" / "clips" / f"{spec.name}.bvh", copy)
        rows = measure_into_store(str(copy), store, RigSettings())
        assert rows and "error" not in rows[0]

    counter = Counter(monkeypatch)
    from_store = _measured(manifest, library=store)
    assert counter.calls == 0
    assert _summary(from_store) == expected  # names follow the build's files, not the library's

    # A store measured with other rig settings does not answer; the build measures itself.
    shutil.rmtree(tmp_path / "cache")
    (tmp_path / "p" / "manifest.yaml").write_text(
        "schema_version: 1\nname: gait\nskeleton: {up: y}\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8"
    )
    _measured(manifest, library=store)
    assert counter.calls == 3


def test_build_and_check_take_the_library_option(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("fsspec")
    from blendspace_pipeline.pipeline.library import measure_into_store

    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv(cache.LIBRARY_VARIABLE, raising=False)
    manifest = _project(tmp_path / "p")
    store = str(tmp_path / "store")
    for spec in SPECS:
        measure_into_store(str(tmp_path / "p" / "clips" / f"{spec.name}.bvh"), store, RigSettings())
    counter = Counter(monkeypatch)
    assert main(["check", str(manifest), "--library", store]) in (0, 1)
    assert counter.calls == 0
    assert cache.LIBRARY_VARIABLE not in os.environ  # restored after the command
    assert "warning" not in capsys.readouterr().err


def test_a_library_store_that_is_not_there_is_said_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A typo in --library read as an empty store: every clip measured without a word. The build
    still runs (a farm's first night comes before its index), and says why it measures."""
    pytest.importorskip("fsspec")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    styles = tmp_path / "p" / "styles"
    styles.mkdir()
    write_bvh_clip(generate(GaitSpec("limp_walk", speed=1.0, duration=1.0)), styles / "limp_walk.bvh")
    manifest.write_text(
        manifest.read_text(encoding="utf-8")
        + "layers:\n  - name: limp\n    kind: style\n    clips: [styles/*.bvh]\n",
        encoding="utf-8",
    )
    store = str(tmp_path / "stroe")
    counter = Counter(monkeypatch)
    assert main(["check", str(manifest), "--library", store, "--jobs", "1"]) in (0, 1)
    assert counter.calls == 4  # measured here
    err = capsys.readouterr().err
    assert err.count("warning: the library store") == 1, err  # not again for the style layer
    assert f"{store!r} does not exist: every clip is measured here" in err
    assert f"blendspace index LIBRARY_DIR --store {store}" in err


def test_stored_measurements_serialise_like_asdict() -> None:
    """The cache's shallow serialisation writes what `dataclasses.asdict` would, nested guesses,
    contacts and ranges included, and reads back equal."""

    clip = generate(GaitSpec("walk", speed=1.4, duration=1.0))

    m = measure(clip, RigSettings(), None)
    m = replace(
        m,
        guesses=[DetectionGuess("up axis", "y", "one frame only", "skeleton: {up: y}")],
        range_used=(0.1, 0.9),
        notes=["a note"],
    )
    assert m.contacts  # the nested lists are there to compare
    stored = cache.to_json([("walk", m)])
    assert json.dumps(stored) == json.dumps([{"name": "walk", "measurement": asdict(m)}])
    back = cache.from_json(json.loads(json.dumps(stored)))
    assert back == [("walk", m)]


def test_a_style_layer_keeps_its_own_pack(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The manifest's clips and a style layer's clips are measured in two calls: one shared pack
    would be rewritten twice per run and hold only the last list."""
    from blendspace_pipeline.pipeline.analysis import analyse

    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    styles = tmp_path / "p" / "styles"
    styles.mkdir()
    for spec in (
        GaitSpec("limp_walk", speed=1.0, duration=1.0),
        GaitSpec("limp_run", speed=3.0, duration=1.0),
    ):
        write_bvh_clip(generate(spec), styles / f"{spec.name}.bvh")
        os.utime(styles / f"{spec.name}.bvh", ns=(1_700_000_000_000_000_000,) * 2)
    manifest.write_text(
        manifest.read_text(encoding="utf-8")
        + "layers:\n  - name: limp\n    kind: style\n    clips: [styles/*.bvh]\n",
        encoding="utf-8",
    )
    analyse(manifest)
    packs = {p: p.stat().st_mtime_ns for p in (tmp_path / "cache" / "packs").glob("*.json")}
    assert len(packs) == 2
    counter = Counter(monkeypatch)
    analyse(manifest)
    assert counter.calls == 0
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cache" / "packs").glob("*.json")} == packs


def test_a_store_that_cannot_be_opened_is_bad_input(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("fsspec")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "p")
    assert main(["check", str(manifest), "--library", "nosuchprotocol://bucket/store"]) == 2
    err = capsys.readouterr().err
    assert "library store 'nosuchprotocol://bucket/store' cannot be opened" in err
    assert "Traceback" not in err
