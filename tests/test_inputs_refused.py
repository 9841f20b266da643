"""Hostile inputs found by a second pass over the manifest, the plugins and the documents: each
was read silently (or wrongly) before; each is refused, or read right, now."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.manifest import load_manifest
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip

SPECS = [
    GaitSpec("idle", duration=1.0),
    GaitSpec("walk", speed=1.4, duration=1.0),
    GaitSpec("run_fwd", speed=4.0, duration=1.0, stride_length=2.6),
    GaitSpec("run_bwd", speed=2.6, direction=180.0, duration=1.0, stride_length=2.0),
]


def _project(folder: Path, extra: str = "", clips: str = "  - path: clips/*.bvh\n") -> Path:
    (folder / "clips").mkdir(parents=True, exist_ok=True)
    for spec in SPECS:
        write_bvh_clip(generate(spec), folder / "clips" / f"{spec.name}.bvh")
    manifest = folder / "manifest.yaml"
    manifest.write_text(f"schema_version: 1\nname: t\nclips:\n{clips}{extra}", encoding="utf-8")
    return manifest


def _with_rule(folder: Path, slug: str, check_body: str, preamble: str = "") -> Path:
    """A project whose plugin rules/studio.py holds one rule ``slug`` whose check runs
    ``check_body``, after module-level ``preamble``."""
    (folder / "rules").mkdir()
    (folder / "rules" / "studio.py").write_text(
        f"from blendspace_pipeline.api import Rule\n{preamble}\n\n\nclass Studio(Rule):\n"
        f"    slug = {slug!r}\n    code = 'ST300'\n    severity = 'warning'\n    summary = 'a test rule'\n\n"
        f"    def check(self, space):\n        {check_body}\n",
        encoding="utf-8",
    )
    return _project(folder, extra="plugins: [rules/studio.py]\n")


def test_a_position_on_a_glob_of_several_clips_is_refused(tmp_path: Path) -> None:
    """Every clip the glob matched was put at the hand position (a backward run at +4 m/s)."""
    manifest = _project(
        tmp_path, clips="  - path: clips/run_*.bvh\n    position: [0, 4]\n  - path: clips/walk.bvh\n"
    )
    from blendspace_pipeline.manifest.paths import resolve_clip_files

    with pytest.raises(InputError) as error:
        resolve_clip_files(load_manifest(manifest))
    assert error.value.line == 4 and "a position belongs to one clip" in (error.value.hint or "")


@pytest.mark.parametrize(
    "tokens", ["{left: Left, right: Left}", "{left: '', right: Right}", "{left: ' ', right: ' '}"]
)
def test_mirror_tokens_that_swap_nothing_are_refused(tmp_path: Path, tokens: str) -> None:
    """Equal or empty tokens pair every joint with itself: the "mirror" swapped nothing."""
    manifest = _project(tmp_path, extra=f"skeleton: {{mirror: {tokens}}}\n")
    with pytest.raises(InputError) as error:
        load_manifest(manifest)
    assert error.value.line is not None and "mirror" in str(error.value.render())


def test_a_plugin_that_prints_leaves_the_json_output_whole(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _with_rule(
        tmp_path,
        "studio-noisy",
        "print('debug: checking', len(space.samples))\n        return iter(())",
        preamble="print('loading noisy')",
    )
    assert main(["check", str(manifest), "--format", "json"]) in (0, 1)
    out = capsys.readouterr()
    json.loads(out.out)  # whole JSON
    assert "loading noisy" in out.err and "debug: checking" in out.err


def test_a_plugin_module_name_is_not_imported_from_the_working_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`python -m blendspace_pipeline` puts the working folder on `sys.path`: `plugins: [helper]`
    ran ./helper.py from outside the project (a path plugin there is refused), and the
    `blendspace` script did not find it: one command, two behaviours."""
    outside = tmp_path / "ci"
    project = outside / "proj"
    project.mkdir(parents=True)
    marker = tmp_path / "ran"
    (outside / "helper_outside.py").write_text(f"open({str(marker)!r}, 'w').write('ran')\n", encoding="utf-8")
    manifest = _project(project, extra="plugins: [helper_outside]\n")
    monkeypatch.chdir(outside)
    monkeypatch.syspath_prepend("")  # as `python -m` starts
    assert main(["check", str(manifest)]) in (0, 1)
    assert "plugin-error" in capsys.readouterr().out
    assert not marker.exists()


def test_a_document_with_a_position_that_is_not_finite_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """eval blended with a NaN sample and export wrote `Vector2(nan, 1)`."""
    manifest = _project(tmp_path)
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    doc = json.loads((out / "t.blendspace.json").read_text(encoding="utf-8"))
    doc["samples"][0]["position"][0] = float("nan")
    bad = tmp_path / "nan.json"
    bad.write_text(json.dumps(doc), encoding="utf-8")  # Python writes NaN, as a hand edit might
    capsys.readouterr()
    assert main(["eval", str(bad), "--at", "x=0,y=1"]) == 2
    assert "not a finite position" in capsys.readouterr().err
    assert main(["export", str(bad), "--engine", "godot", "--out", os.fspath(tmp_path / "x.tres")]) == 2


def test_a_beta_layer_pointing_at_a_clip_says_so(tmp_path: Path) -> None:
    """`manifest: clips/walk.bvh` reported "invalid YAML: mapping values are not allowed here" at
    the clip's own line, not that a clip is no manifest."""
    manifest = _project(
        tmp_path, extra="layers:\n  - {name: lateral, kind: beta, manifest: clips/walk.bvh}\n"
    )
    from blendspace_pipeline.pipeline.analysis import analyse

    with pytest.raises(InputError) as error:
        analyse(manifest)
    assert "is a clip file, not a manifest" in error.value.message and error.value.line == 6


def test_a_rule_reporting_one_clip_name_as_a_string_names_that_clip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`self.report(..., clips="walk")` was read letter by letter ("clips not in the space: a, k,
    l, w", a rule-crashed finding)."""
    manifest = _with_rule(tmp_path, "studio-one", "yield self.report('walk is named', clips='walk')")
    assert main(["check", str(manifest), "--format", "json"]) in (0, 1)
    found = json.loads(capsys.readouterr().out)
    [finding] = [d for d in found["diagnostics"] if d["rule"] == "studio-one"]
    assert finding["clips"] == ["walk"]


def test_mirror_tokens_that_pair_no_joints_skip_the_mirror_and_say_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`skeleton.mirror: {left: Foo, right: Bar}` matched no joint, and the mirror was made by the
    automatic pairing instead, with no word: the tokens the manifest states are never replaced."""
    manifest = _project(
        tmp_path, extra="skeleton: {mirror: {left: Foo, right: Bar}}\noutput: {formats: [json]}\n"
    )
    write_bvh_clip(
        generate(GaitSpec("walk_left", speed=1.4, turn_rate=60.0, duration=1.0)),
        tmp_path / "clips" / "walk_left.bvh",
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json"]) in (0, 1)
    capsys.readouterr()
    doc = json.loads((out / "t.blendspace.json").read_text(encoding="utf-8"))
    assert not [s for s in doc["samples"] if s["fix"] == "missing-opposite"]
    skipped = [d["message"] for d in doc["diagnostics"] if d["rule"] == "fix-skipped"]
    assert any("skeleton.mirror {left: Foo, right: Bar} pairs no joints of walk_left" in m for m in skipped)


@pytest.mark.parametrize(
    "args",
    [
        ["build", ""],
        ["check", ""],
        ["build", "{m}", "--out", ""],
        ["build", "{m}", "--library", ""],
        ["eval", "", "--at", "0,0"],
        ["eval", "{d}", "--points", ""],
        ["export", "{d}", "--engine", "godot", "--out", ""],
        ["index", "{c}", "--store", ""],
        ["index", "", "--store", "{s}"],
        ["suggest", "{m}", "--library", ""],
    ],
)
def test_an_empty_path_argument_is_refused_not_taken_for_the_working_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], args: list[str]
) -> None:
    """`--out "$OUT"` with OUT unset: before, the outputs (or a library index) went into the
    working folder, the project's own. Now exit 2 naming the argument, and nothing is written."""
    manifest = _project(tmp_path / "p")
    monkeypatch.chdir(tmp_path / "p")
    before = sorted(p.name for p in (tmp_path / "p").iterdir())
    names = {"m": str(manifest), "d": "t.blendspace.json", "c": "clips", "s": str(tmp_path / "store")}
    assert main([a.format(**names) for a in args]) == 2
    assert "is empty (an unset variable?)" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "p").iterdir()) == before


def test_a_folder_given_as_a_document_or_clip_is_called_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["eval", str(tmp_path), "--at", "0,0"]) == 2
    assert "not a regular file (a folder)" in capsys.readouterr().err
    from blendspace_pipeline.readers.limits import check_regular

    with pytest.raises(InputError, match=r"not a regular file \(a folder\)"):
        check_regular(tmp_path, what="clip")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_eval_points_from_a_device_or_a_fifo_are_refused_without_reading_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--points /dev/zero` was read until memory ran out, and a FIFO with no writer waited forever."""
    manifest = _project(tmp_path / "p")
    assert main(["build", str(manifest), "--no-fix", "--out", str(tmp_path / "out")]) in (0, 1)
    fifo = tmp_path / "points.csv"
    os.mkfifo(fifo)
    for points in (fifo, Path("/dev/zero")):
        if not points.exists():
            continue
        capsys.readouterr()
        assert main(["eval", str(tmp_path / "out" / "t.blendspace.json"), "--points", str(points)]) == 2
        err = capsys.readouterr().err
        assert "not a regular file (a device, FIFO or socket)" in err and "give a CSV file" in err


def test_a_plugin_module_keeps_the_folder_it_adds_to_the_path_for_its_rules(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A studio plugin that puts its vendored folder on `sys.path` at import and imports from it
    in `check`: the loader put back the whole path it had saved, dropping the plugin's folder, so
    the rule crashed. The working folder is still left out while the plugin imports."""
    site = tmp_path / "site"
    (site / "_vendor").mkdir(parents=True)
    (site / "_vendor" / "studio_vendored_helper.py").write_text("WORD = 'vendored'\n", encoding="utf-8")
    (site / "studio_vendoring_rules.py").write_text(
        "import os, sys\n"
        "sys.path.insert(0, os.path.join(os.path.dirname(__file__), '_vendor'))\n"
        "from blendspace_pipeline.api import Diagnostic, Rule\n\n\n"
        "class Vendoring(Rule):\n    slug = 'studio-vendoring'\n    code = 'ST900'\n    severity = 'info'\n    summary = 'vendored'\n\n"
        "    def check(self, space):\n"
        "        import studio_vendored_helper\n\n"
        "        yield self.report(f'helper says {studio_vendored_helper.WORD}')\n",
        encoding="utf-8",
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.syspath_prepend("")  # as `python -m` starts: taken out for the import, put back
    manifest = _project(tmp_path / "p", extra="plugins: [studio_vendoring_rules]\n")
    assert main(["check", str(manifest)]) in (0, 1)
    out = capsys.readouterr().out
    assert "helper says vendored" in out and "rule-crashed" not in out
    assert sys.path[0] == "" and str(site / "_vendor") in sys.path
