"""Build stamps: an unchanged `build`/`check` replays at once, anything that moved runs again,
and an edit re-measures only the clip it touched."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import analysis, measure_stage, outputs
from blendspace_pipeline.writers.bvh import write_bvh_clip

SPECS = [
    GaitSpec("idle", duration=1.0),
    GaitSpec("walk", speed=1.4, duration=1.0),
    GaitSpec("run", speed=4.0, duration=1.0),
    GaitSpec("turn", speed=1.4, turn_rate=60.0, duration=1.0),
]


def _project(folder: Path) -> Path:
    (folder / "clips").mkdir(parents=True)
    for spec in SPECS:
        write_bvh_clip(generate(spec), folder / "clips" / f"{spec.name}.bvh")
    manifest = folder / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\noutput: {formats: [json, png]}\n",
        encoding="utf-8",
    )
    return manifest


class Counter:
    """Counts real measurements (cache misses) and analyses while a test runs, in this process."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setenv("BLENDSPACE_JOBS", "1")  # counted here: no measuring workers
        self.measured: list[str] = []
        self.analyses = 0
        measure, analyse = measure_stage.measure, analysis.analyse

        def counting_measure(clip, settings, time_range=None):  # type: ignore[no-untyped-def]
            self.measured.append(clip.name)
            return measure(clip, settings, time_range)

        def counting_analyse(*args, **kwargs):  # type: ignore[no-untyped-def]
            self.analyses += 1
            return analyse(*args, **kwargs)

        monkeypatch.setattr(measure_stage, "measure", counting_measure)
        monkeypatch.setattr(analysis, "analyse", counting_analyse)
        monkeypatch.setattr(outputs, "analyse", counting_analyse)  # `build` holds its own reference


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(argv)
    return code, capsys.readouterr().out


def test_an_unchanged_build_replays_and_anything_that_moved_rebuilds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path)
    out = tmp_path / "out"
    argv = ["build", str(manifest), "--out", str(out), "--no-fix"]
    counter = Counter(monkeypatch)
    first_code, first = _run(argv, capsys)
    assert first_code in (0, 1) and "built 4 samples" in first
    assert sorted(counter.measured) == ["idle", "run", "turn", "walk"] and counter.analyses == 1
    # Nothing moved: the same text and exit code, no analysis at all.
    assert _run(argv, capsys) == (first_code, first)
    assert counter.analyses == 1
    # A touch (same bytes, new mtime) is still up to date: the content hash says so.
    clip = tmp_path / "clips" / "walk.bvh"
    os.utime(clip, ns=(clip.stat().st_atime_ns, clip.stat().st_mtime_ns + 5_000_000_000))
    assert _run(argv, capsys) == (first_code, first)
    assert counter.analyses == 1
    # An edit rebuilds, and re-measures that clip only (the others come from the cache).
    write_bvh_clip(generate(GaitSpec("walk", speed=1.0, duration=1.0)), clip)
    counter.measured.clear()
    _, text = _run(argv, capsys)
    assert counter.analyses == 2 and counter.measured == ["walk"]
    assert "built 4 samples" in text
    # A deleted output rebuilds (and measures nothing).
    (out / "gait.png").unlink()
    counter.measured.clear()
    _run(argv, capsys)
    assert counter.analyses == 3 and counter.measured == [] and (out / "gait.png").exists()
    # A new clip in the globbed folder rebuilds with it.
    write_bvh_clip(
        generate(GaitSpec("back", speed=1.5, direction=180.0, duration=1.0)), tmp_path / "clips" / "back.bvh"
    )
    _, text = _run(argv, capsys)
    assert counter.analyses == 4 and counter.measured == ["back"] and "built 5 samples" in text
    # Other options are another invocation: no replay of the text-format stamp.
    _run([*argv, "--format", "json"], capsys)
    assert counter.analyses == 5


def test_an_unchanged_check_replays_and_an_edited_manifest_runs_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path)
    counter = Counter(monkeypatch)
    first = _run(["check", str(manifest)], capsys)
    assert _run(["check", str(manifest)], capsys) == first
    assert counter.analyses == 1
    manifest.write_text(
        manifest.read_text(encoding="utf-8") + "thresholds: {too_close: 30}\n", encoding="utf-8"
    )
    _, text = _run(["check", str(manifest)], capsys)
    assert counter.analyses == 2 and "too-close" in text and counter.measured.count("walk") == 1


def test_a_check_runs_again_when_the_code_that_runs_it_moved(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same version of the tool with other code (an edited checkout, a package installed on
    `sys.path`) does not replay what the old code printed."""
    manifest = _project(tmp_path)
    counter = Counter(monkeypatch)
    first = _run(["check", str(manifest)], capsys)
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 1
    packages = tmp_path / "site-packages"
    packages.mkdir()
    monkeypatch.setattr(sys, "path", [*sys.path, str(packages)])  # a package folder appears
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 2
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 2  # stamped again
    (packages / "studio_tool-1.0.dist-info").mkdir()  # a package installed there
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 3
    (packages / "studio_tool-1.0.dist-info").rename(packages / "studio_tool-1.1.dist-info")  # upgraded
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 4
    (packages / "notes.txt").write_text("", encoding="utf-8")  # anything else in the folder: no matter
    assert _run(["check", str(manifest)], capsys) == first and counter.analyses == 4


def test_a_project_folder_on_sys_path_that_the_build_writes_to_still_replays(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`PYTHONPATH=.` (rule plugins named by module) with `output.dir: .`: every build creates and
    removes its staging folder there, so the folder's mtime always moved and no build replayed."""
    manifest = _project(tmp_path)
    text = manifest.read_text(encoding="utf-8").replace(
        "output: {formats: [json, png]}", "output: {formats: [json, png], dir: .}"
    )
    manifest.write_text(text, encoding="utf-8")
    counter = Counter(monkeypatch)
    monkeypatch.setattr(sys, "path", [*sys.path, str(tmp_path)])
    first = _run(["build", str(manifest)], capsys)
    assert _run(["build", str(manifest)], capsys) == first and counter.analyses == 1


def test_bad_input_is_never_stamped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: x\nclips:\n  - path: missing.bvh\n", encoding="utf-8")
    counter = Counter(monkeypatch)
    assert main(["check", str(manifest)]) == 2
    assert main(["check", str(manifest)]) == 2
    assert counter.analyses == 2
    assert "missing.bvh" in capsys.readouterr().err


def test_the_fast_json_round_trips_every_float_and_name_and_the_standard_parser_reads_it() -> None:
    """Packs and stamps are written by pydantic-core; `stamp.replay` reads them with `json`."""
    import json
    import math

    from blendspace_pipeline.pipeline import cache

    floats = [0.1, -0.0, 1e16, 1e-7, 5e-324, 1.7976931348623157e308, 2.0 / 3.0, 123456789.123456789]
    value = {"names": ["walk_ü", "跑", 'quote " and \\ back', "tab\tnew\nline"], "floats": floats, "n": None}
    text = cache.dumps(value)
    for back in (cache.loads(text.encode()), json.loads(text)):
        assert back == value
        assert [math.copysign(1.0, f) for f in back["floats"]] == [math.copysign(1.0, f) for f in floats]
    odd = cache.loads(cache.dumps({"x": [math.nan, math.inf, -math.inf]}).encode())["x"]
    assert math.isnan(odd[0]) and odd[1:] == [math.inf, -math.inf]


@pytest.mark.parametrize("pattern", ["clips/**/*.bvh", "clips/*/*.bvh"])
def test_a_clip_added_to_a_globbed_folder_that_held_none_rebuilds(
    pattern: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The stamp watched only the folders that held a clip: a clip added to an empty sub-folder
    that a `**` (or `*/`) glob looks in replayed the old build (8 samples for 9)."""
    manifest = _project(tmp_path)
    (tmp_path / "clips" / "more").mkdir()
    (tmp_path / "clips" / "more" / "deeper").mkdir()
    for spec in SPECS:  # the clips one folder down, so both patterns find them
        (tmp_path / "clips" / f"{spec.name}.bvh").rename(tmp_path / "clips" / "more" / f"{spec.name}.bvh")
    manifest.write_text(
        f"schema_version: 1\nname: gait\nclips:\n  - path: '{pattern}'\noutput: {{formats: [json]}}\n",
        encoding="utf-8",
    )
    (tmp_path / "clips" / "empty").mkdir()
    argv = ["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]
    Counter(monkeypatch)
    assert "built 4 samples" in _run(argv, capsys)[1]
    assert "built 4 samples" in _run(argv, capsys)[1]  # replayed
    write_bvh_clip(
        generate(GaitSpec("jog", speed=2.5, duration=1.0)), tmp_path / "clips" / "empty" / "jog.bvh"
    )
    assert "built 5 samples" in _run(argv, capsys)[1]
    if "**" in pattern:  # and two levels down
        write_bvh_clip(
            generate(GaitSpec("dash", speed=5.0, duration=1.0)),
            tmp_path / "clips" / "more" / "deeper" / "dash.bvh",
        )
        assert "built 6 samples" in _run(argv, capsys)[1]


@pytest.mark.parametrize("broken", ["def broken(:\n", None])
def test_a_plugin_fixed_or_added_after_a_failed_build_rebuilds(
    broken: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A `plugins:` file that failed to import (or did not exist) was no input of the stamp: once
    fixed (or written), the build replayed the plugin-error."""
    manifest = _project(tmp_path)
    manifest.write_text(
        manifest.read_text(encoding="utf-8") + "plugins: [rules/studio.py]\n", encoding="utf-8"
    )
    plugin = tmp_path / "rules" / "studio.py"
    plugin.parent.mkdir()
    if broken is not None:
        plugin.write_text(broken, encoding="utf-8")
    argv = ["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]
    assert "plugin-error" in _run(argv, capsys)[1]
    assert "plugin-error" in _run(argv, capsys)[1]  # replayed: nothing moved
    plugin.write_text(
        "from blendspace_pipeline.api import Rule\n\n\nclass Studio(Rule):\n"
        "    slug = 'studio-nothing'\n    code = 'ST001'\n    severity = 'info'\n    summary = 'finds nothing'\n\n"
        "    def check(self, space):\n        return iter(())\n",
        encoding="utf-8",
    )
    assert "plugin-error" not in _run(argv, capsys)[1]


def test_a_clip_in_a_new_folder_two_levels_down_a_glob_rebuilds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`clips/*/*/*.bvh` with an empty `clips/e/`: a clip added in a new `clips/e/s1/` replayed the
    old build (only the glob's root and its last folder level were watched)."""
    manifest = _project(tmp_path)
    deep = tmp_path / "clips" / "a" / "b"
    deep.mkdir(parents=True)
    for spec in SPECS:
        (tmp_path / "clips" / f"{spec.name}.bvh").rename(deep / f"{spec.name}.bvh")
    (tmp_path / "clips" / "e").mkdir()
    manifest.write_text(
        "schema_version: 1\nname: gait\nclips:\n  - path: 'clips/*/*/*.bvh'\noutput: {formats: [json]}\n",
        encoding="utf-8",
    )
    argv = ["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]
    Counter(monkeypatch)
    assert "built 4 samples" in _run(argv, capsys)[1]
    (tmp_path / "clips" / "e" / "s1").mkdir()
    write_bvh_clip(
        generate(GaitSpec("jog", speed=2.5, duration=1.0)), tmp_path / "clips" / "e" / "s1" / "jog.bvh"
    )
    assert "built 5 samples" in _run(argv, capsys)[1]


def test_a_rule_path_file_fixed_in_place_rebuilds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A broken file in a `BLENDSPACE_RULE_PATH` folder, fixed in place (the folder's mtime does
    not move), replayed its plugin-error."""
    manifest = _project(tmp_path)
    folder = tmp_path / "rule_path"
    folder.mkdir()
    rule = folder / "studio_rule.py"
    rule.write_text("this is not python\n", encoding="utf-8")
    monkeypatch.setenv("BLENDSPACE_RULE_PATH", str(folder))
    argv = ["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]
    assert "plugin-error" in _run(argv, capsys)[1]
    rule.write_text("# fixed: no rules here yet\n", encoding="utf-8")
    assert "plugin-error" not in _run(argv, capsys)[1]
