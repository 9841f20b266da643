"""Incremental rebuilds: what an edit does not touch comes from the cache, and the result is
the same, byte for byte, as a cold build of the edited set."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from blendspace_pipeline import report
from blendspace_pipeline.checks import rule_engine
from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import SAMPLE_SET, GaitSpec, generate_planted
from blendspace_pipeline.pipeline import analysis, blend_quality, outputs, stamp
from blendspace_pipeline.writers import usd_blendspace
from blendspace_pipeline.writers.usd_clip import write_usd_clip

MANIFEST = (
    "schema_version: 1\nname: planted\nclips:\n  - path: clips/*.usda\n"
    "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
    "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"
    "output: {formats: [json, usd, html, png]}\n"
)
DOCUMENTS = ("planted.blendspace.json", "planted.blendspace.usda", "planted.report.html")


def _write(folder: Path, spec: GaitSpec) -> None:
    path = folder / "clips" / f"{spec.name}.usda"
    write_usd_clip(generate_planted(spec), path, meters_per_unit=1.0, up_axis="y")


def _project(folder: Path) -> Path:
    for spec in SAMPLE_SET:
        _write(folder, spec)
    manifest = folder / "manifest.yaml"
    manifest.write_text(MANIFEST, encoding="utf-8")
    return manifest


class Plays:
    """Counts the grid points whose blend is really played (cache misses), in this process."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setenv("BLENDSPACE_JOBS", "1")  # counted here: no forked foot-skate workers
        self.count = 0
        play = blend_quality.play

        def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
            self.count += 1
            return play(*args, **kwargs)

        monkeypatch.setattr(blend_quality, "play", counting)


def _build(manifest: Path, out: Path, cache: Path | str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(cache))
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)


def _skate(out: Path) -> object:
    return json.loads((out / "planted.blendspace.json").read_text(encoding="utf-8"))["blend_quality"]


def _same_outputs(a: Path, b: Path) -> None:
    for name in DOCUMENTS:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    oiio = pytest.importorskip("OpenImageIO")
    pixels = [oiio.ImageBuf(str(folder / "planted.png")).get_pixels() for folder in (a, b)]
    assert np.array_equal(pixels[0], pixels[1])


def test_foot_skate_from_the_cache_equals_a_cold_computation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    manifest = _project(tmp_path / "project")
    cache = tmp_path / "cache"
    plays = Plays(monkeypatch)
    _build(manifest, tmp_path / "project" / "first", cache, monkeypatch)
    played = plays.count
    assert played > 3  # the set's grid has points to play
    assert list((cache / "skate").rglob("*.json"))
    _build(manifest, tmp_path / "project" / "warm", cache, monkeypatch)
    assert plays.count == played  # every point came from the cache
    _build(manifest, tmp_path / "project" / "cold", "off", monkeypatch)
    assert plays.count == 2 * played  # no cache: every point played again
    assert _skate(tmp_path / "project" / "warm") == _skate(tmp_path / "project" / "cold")
    skate = [v for row in _skate(tmp_path / "project" / "cold")["foot_skate"] for v in row]  # type: ignore[index]
    assert any(v is not None for v in skate)


def test_one_clip_edited_replays_only_its_blends_and_equals_a_cold_build(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    project = tmp_path / "project"
    manifest = _project(project)
    cache = tmp_path / "cache"
    plays = Plays(monkeypatch)
    _build(manifest, project / "out", cache, monkeypatch)
    full = plays.count
    # A faster strafe: the clip moves on the grid, the blends that involve it change.
    _write(project, GaitSpec("strafe_left", speed=1.5, direction=90.0, duration=1.0, stride_length=1.2))
    plays.count = 0
    _build(manifest, project / "out", cache, monkeypatch)
    assert 0 < plays.count < full  # only the points whose blend involves the edited clip
    # A cold build of the edited set (empty cache) into a folder of the same depth.
    _build(manifest, project / "cold", tmp_path / "fresh-cache", monkeypatch)
    _same_outputs(project / "out", project / "cold")


def test_a_corrupt_cache_entry_is_computed_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    manifest = _project(tmp_path / "project")
    cache = tmp_path / "cache"
    _build(manifest, tmp_path / "project" / "first", cache, monkeypatch)
    entries = sorted((cache / "skate").rglob("*.json"))
    for entry in entries:
        entry.write_text('{"foot_sliding": "fast"}' if entries.index(entry) % 2 else "{", encoding="utf-8")
    plays = Plays(monkeypatch)
    _build(manifest, tmp_path / "project" / "again", cache, monkeypatch)
    assert plays.count > 0
    assert _skate(tmp_path / "project" / "again") == _skate(tmp_path / "project" / "first")
    assert os.path.getsize(entries[0]) > 5  # rewritten


def test_the_build_pipeline_imports_no_heavy_module_before_a_stage_needs_it() -> None:
    # USD (pxr), scipy.spatial and OpenImageIO cost a second of start-up together: a build that
    # writes no generated clip, or a `check`, must not pay for them at import.
    code = (
        "import sys, blendspace_pipeline.pipeline.outputs, blendspace_pipeline.commands.check\n"
        "print(sorted(m for m in ('pxr', 'scipy.spatial', 'OpenImageIO') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_stamp_rehashes_only_the_files_whose_stat_moved(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    files = [tmp_path / f"clip_{i}.bvh" for i in range(20)]
    for i, path in enumerate(files):
        path.write_text(f"clip {i}\n", encoding="utf-8")
    hashed: list[Path] = []
    digest = stamp.content_digest

    def counting(path: Path) -> str:
        hashed.append(path)
        return digest(path)

    monkeypatch.setattr(stamp, "content_digest", counting)
    key = stamp.invocation_key("build", [tmp_path / "manifest.yaml"], {})
    stamp.record(key, files, [], "", 0)
    assert len(hashed) == len(files)
    hashed.clear()
    files[3].write_text("clip 3, edited\n", encoding="utf-8")
    os.utime(files[3], ns=(1, 10**18))  # a stat that surely moved
    stamp.record(key, files, [], "", 0)
    assert hashed == [files[3]]
    recorded = json.loads((tmp_path / "cache" / "stamps" / f"{key}.json").read_text(encoding="utf-8"))
    by_path = {entry["path"]: entry["sha256"] for entry in recorded["inputs"]}
    for path in files:
        assert by_path[str(path)] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert stamp.replay(key) == 0


class Writes:
    """Counts the document writers really called (their outputs not taken from the last build)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.names: list[str] = []
        for module, name in (
            (report, "write_png"),
            (report, "write_html_report"),
            (usd_blendspace, "write_usd_blendspace"),
        ):
            monkeypatch.setattr(module, name, self._counting(name, getattr(module, name)))

    def _counting(self, name: str, writer):  # type: ignore[no-untyped-def]
        def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
            self.names.append(name)
            return writer(*args, **kwargs)

        return counting

    def take(self) -> list[str]:
        names, self.names = sorted(self.names), []
        return names


ALL_WRITERS = ["write_html_report", "write_png", "write_usd_blendspace"]


def test_outputs_are_written_only_when_what_they_are_made_of_changed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    # The report's date is otherwise the newest input's mtime: editing the manifest below would
    # (rightly) write the report again for its new date.
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    project = tmp_path / "project"
    manifest = _project(project)
    out = project / "out"
    writes = Writes(monkeypatch)
    outputs.build(manifest, out, fix=False)  # `build` without the stamp: every stage runs
    assert writes.take() == ALL_WRITERS
    first = {name: (out / name).read_bytes() for name in (*DOCUMENTS, "planted.png")}
    outputs.build(manifest, out, fix=False)
    assert writes.take() == []  # nothing they depend on moved
    # A deleted output (its link) and a hand-edited one (through its link) are written again.
    (out / "planted.png").unlink()
    with (out / "planted.blendspace.usda").open("a", encoding="utf-8") as stream:
        stream.write("# edited by hand\n")
    outputs.build(manifest, out, fix=False)
    assert writes.take() == ["write_usd_blendspace"]
    assert {name: (out / name).read_bytes() for name in first} == first
    # The published file itself deleted (not just its link): written again, into the same set.
    (out / ".blendspace" / "planted" / "current" / "planted.report.html").unlink()
    outputs.build(manifest, out, fix=False)
    assert writes.take() == ["write_html_report"]
    assert {name: (out / name).read_bytes() for name in first} == first
    # The formats list: dropping PNG writes nothing and removes it; adding it back writes PNG only.
    manifest.write_text(MANIFEST.replace("json, usd, html, png", "json, usd, html"), encoding="utf-8")
    outputs.build(manifest, out, fix=False)
    assert writes.take() == []
    assert not (out / "planted.png").exists()
    manifest.write_text(MANIFEST, encoding="utf-8")
    outputs.build(manifest, out, fix=False)
    assert writes.take() == ["write_png"]
    assert {name: (out / name).read_bytes() for name in first} == first
    # An edited clip changes the document: every output is written again, equal to a cold build.
    _write(project, GaitSpec("walk_fwd", speed=1.6, duration=1.0))
    outputs.build(manifest, out, fix=False)
    assert writes.take() == ALL_WRITERS
    outputs.build(manifest, project / "cold", fix=False)
    _same_outputs(out, project / "cold")


def test_rule_runs_share_sample_views_of_the_same_clips_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    manifest = _project(tmp_path / "project")
    space = analysis.analyse(manifest, converge=False)
    first = rule_engine.space_view(space)
    again = rule_engine.space_view(space)
    assert all(a is b for a, b in zip(first.samples, again.samples, strict=True))
    # A measurement replaced (not edited in place: measurements are values) gets a new view.
    clip = space.samples[0].clip
    clip.measurement = replace(clip.measurement, features={**clip.measurement.features, "speed": 9.5})
    changed = rule_engine.space_view(space)
    assert changed.samples[0] is not again.samples[0]
    assert changed.samples[0].features["speed"] == 9.5
    assert all(a is b for a, b in zip(changed.samples[1:], again.samples[1:], strict=True))
    # Placeholder simulations with shared views find exactly what fresh views find.
    shared = analysis.analyse(manifest)
    monkeypatch.setattr(rule_engine, "_same", lambda a, b: False)
    fresh = analysis.analyse(manifest)
    assert shared.diagnostics == fresh.diagnostics
    assert shared.placeholders == fresh.placeholders


class _BlendClock:
    """`blend_quality`'s clock, moved on by a set time per blend played in this process, so
    the decision does not depend on how busy the machine is."""

    def __init__(self, play: Callable[..., float | None]) -> None:
        self.now, self.per_blend, self.play = 0.0, 0.0, play

    def perf_counter(self) -> float:
        return self.now

    def played(self, *args: object) -> float | None:
        self.now += self.per_blend
        return self.play(*args)


def _every_point_to_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    """A pool however little there is to play (a test space's map takes a fraction of a second)."""
    monkeypatch.setattr(blend_quality, "PARALLEL_MIN_POINTS", 2)
    monkeypatch.setattr(blend_quality, "SERIAL_FIRST_SECONDS", 0.0)
    monkeypatch.setattr(blend_quality, "POOL_WORTH_SECONDS", 0.0)


def _pools(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    pools: list[int] = []
    pool = blend_quality.ProcessPoolExecutor

    def counted_pool(*args, **kwargs):  # type: ignore[no-untyped-def]
        pools.append(1)
        return pool(*args, **kwargs)

    monkeypatch.setattr(blend_quality, "ProcessPoolExecutor", counted_pool)
    return pools


def test_a_map_quicker_to_play_than_a_pool_is_played_in_process_and_a_slow_one_is_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`--jobs 2`: the first blends are played here; the rest go to workers only when, at that
    pace, they would take `POOL_WORTH_SECONDS`. Either way the map is the one played here."""
    if "fork" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("workers are forked; this platform plays every blend in process")
    manifest = _project(tmp_path / "project")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    monkeypatch.setattr(blend_quality, "PARALLEL_MIN_POINTS", 2)
    monkeypatch.setattr(outputs, "EarlyQuality", lambda *args: None)  # the maps in this process
    pools = _pools(monkeypatch)
    clock = _BlendClock(blend_quality._play_point)
    monkeypatch.setattr(blend_quality, "time", clock)
    monkeypatch.setattr(blend_quality, "_play_point", clock.played)
    maps = {}
    for name in ("one", "quick", "slow"):
        # 1 ms a blend: the test space's 29 are played here before the first 0.05 s are over;
        # 40 ms: two are, and the rest would take about a second, worth a pool.
        clock.per_blend = 0.04 if name == "slow" else 0.001
        out = tmp_path / "project" / name
        jobs = "1" if name == "one" else "2"
        assert main(["build", str(manifest), "--out", str(out), "--no-fix", "--jobs", jobs]) in (0, 1)
        maps[name] = _skate(out)
        if name == "quick":
            assert pools == []
    assert pools == [1]
    assert maps["one"] == maps["quick"] == maps["slow"]


def test_foot_skate_played_in_worker_processes_equals_one_process(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`build --jobs 2` plays a cold foot-skate map's blends in forked workers: same document."""
    if "fork" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("workers are forked; this platform plays every blend in process")
    manifest = _project(tmp_path / "project")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    _every_point_to_workers(monkeypatch)
    calls: list[int] = []
    beside: list[bool] = []  # whether this process wrote outputs while the workers played
    real = blend_quality._play_all

    def recorded(prepared, points, jobs, meanwhile=None):  # type: ignore[no-untyped-def]
        calls.append(len(points))
        ran: list[bool] = []

        def spied() -> None:
            ran.append(True)
            meanwhile()

        result = real(prepared, points, jobs, spied if meanwhile else None)
        beside.append(bool(ran))
        return result

    monkeypatch.setattr(blend_quality, "_play_all", recorded)
    pools = _pools(monkeypatch)
    # The maps in this process (as builds with fixes make them): without fixes they are made in an
    # early child instead (tests/test_early_quality.py).
    monkeypatch.setattr(outputs, "EarlyQuality", lambda *args: None)
    for jobs in ("1", "2"):
        out = tmp_path / "project" / f"jobs{jobs}"
        assert main(["build", str(manifest), "--out", str(out), "--no-fix", "--jobs", jobs]) in (0, 1)
    assert calls and calls[0] >= 2  # there were blends to play, enough to fork for
    assert pools == [1]  # --jobs 1 played in process, --jobs 2 in a pool
    assert beside == [False, True]  # with the pool, the USD was written while it played
    assert _skate(tmp_path / "project" / "jobs1") == _skate(tmp_path / "project" / "jobs2")
    skate = [v for row in _skate(tmp_path / "project" / "jobs2")["foot_skate"] for v in row]  # type: ignore[index]
    assert any(v is not None for v in skate)


def test_a_foot_skate_worker_killed_is_one_line_that_says_what_to_do(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The out-of-memory killer ending a foot-skate worker: exit 3, one line naming the work and
    `--jobs 1` (not `BrokenProcessPool`), nothing written."""
    if "fork" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("workers are forked; this platform plays every blend in process")
    import signal

    manifest = _project(tmp_path / "project")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    _every_point_to_workers(monkeypatch)
    monkeypatch.setattr(outputs, "EarlyQuality", lambda *args: None)  # the pool in this process
    parent = os.getpid()
    real = blend_quality._play_point

    def dies(*args):  # type: ignore[no-untyped-def]  # what a worker's chunk calls per point
        if os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return real(*args)

    monkeypatch.setattr(blend_quality, "_play_point", dies)
    out = tmp_path / "project" / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix", "--jobs", "2"]) == 3
    err = capsys.readouterr().err
    assert "a foot-skate process ended without an answer" in err and "--jobs 1" in err, err
    assert "Traceback" not in err and len(err.splitlines()) == 1
    assert not out.exists()
