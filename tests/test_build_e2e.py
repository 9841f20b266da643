"""End to end: the sample project, the CLI's error contract and atomic outputs.

These run the real command line (`python -m blendspace_pipeline`) where the contract is about
what a user sees (exit codes, no traceback) and `cli.main` in-process elsewhere.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from pxr import Usd

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import MORE_SHOWN
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sample_project"


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        check=False,
    )


def _tree(folder: Path) -> dict[str, str]:
    """Relative path -> sha256 of every file under ``folder``."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def sample_copy(tmp_path: Path) -> Path:
    """The sample project copied to a temporary folder (without any build output)."""
    target = tmp_path / "sample"
    shutil.copytree(SAMPLE, target, ignore=shutil.ignore_patterns("build", "__pycache__"))
    return target


def _write_clip(folder: Path, spec: GaitSpec) -> Path:
    path = folder / f"{spec.name}.usda"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_usd_clip(generate(spec), path, meters_per_unit=1.0, up_axis="y")
    return path


def test_committed_sample_clips_are_what_the_generator_makes(tmp_path: Path) -> None:
    sys.path.insert(0, str(SAMPLE))
    try:
        import make_clips
    finally:
        sys.path.remove(str(SAMPLE))
    fresh = {p.relative_to(tmp_path).as_posix() for p in make_clips.write_clips(tmp_path)}
    for relative in sorted(fresh):
        committed = SAMPLE / relative
        assert committed.is_file(), f"{relative} is not committed: run python sample_project/make_clips.py"
        assert committed.read_bytes() == (tmp_path / relative).read_bytes(), (
            f"{relative} drifted from make_clips.py: run python sample_project/make_clips.py"
        )


def test_sample_project_builds_every_output(sample_copy: Path) -> None:
    sources_before = _tree(sample_copy)
    out = sample_copy / "out"
    code = main(["build", str(sample_copy / "manifest.yaml"), "--out", str(out), "--format", "json"])
    assert code in (0, 1)
    names = {p.name for p in out.iterdir()}
    assert {
        "locomotion.blendspace.json",
        "locomotion.blendspace.usda",
        "locomotion.report.html",
        "locomotion.png",
    } <= names
    # Source clips and the manifest are untouched.
    after = {k: v for k, v in _tree(sample_copy).items() if not k.startswith("out")}
    assert after == sources_before

    doc = json.loads((out / "locomotion.blendspace.json").read_text())
    assert doc["schema_version"] == 1 and doc["name"] == "locomotion"
    assert [a["name"] for a in doc["axes"]] == ["x", "y"]
    assert (doc["axes"][0]["feature"], doc["axes"][0]["unit"]) == ("turn_rate", "deg/s")
    by_name = {s["name"]: s for s in doc["samples"]}
    # Ground truth from make_clips.py: speeds in m/s, turn rates in deg/s, snapped to the grid.
    assert by_name["run_fwd"]["features"]["speed"] == pytest.approx(4.0, rel=0.01)
    assert by_name["walk_turn_left"]["features"]["turn_rate"] == pytest.approx(60.0, rel=0.01)
    assert by_name["walk_bwd"]["features"]["speed"] == pytest.approx(-1.1, rel=0.01)
    for sample in doc["samples"]:
        x, y = sample["position"]
        assert (x + 180) / 3.6 == pytest.approx(round((x + 180) / 3.6), abs=1e-6)
        assert (y + 3) / 0.1 == pytest.approx(round((y + 3) / 0.1), abs=1e-6)
        assert set(sample) >= {"name", "source", "features", "position", "generated", "fix"}
    for triangle in doc["triangles"]:
        assert all(0 <= i < len(doc["samples"]) for i in triangle)
    rules = {d["rule"] for d in doc["diagnostics"]}
    assert "studio-min-cycle-length" in rules  # the sample's worked studio rule fires
    assert "misalignment" in rules

    stage = Usd.Stage.Open(str(out / "locomotion.blendspace.usda"))
    root = stage.GetDefaultPrim()
    prims = list(root.GetChild("Samples").GetChildren())
    assert len(prims) == len(doc["samples"])
    run = root.GetChild("Samples").GetChild("run_fwd")
    assert tuple(run.GetAttribute("blendspace:position").Get()) == tuple(by_name["run_fwd"]["position"])
    source = run.GetAttribute("blendspace:source").Get()
    assert (out / source.path).resolve().is_file()


def test_manifest_typo_is_exit_2_with_location_and_no_outputs(tmp_path: Path) -> None:
    _write_clip(tmp_path / "clips", GaitSpec("walk", speed=1.4))
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\naxis:\n  x: {}\n")
    result = _cli("build", str(manifest))
    assert result.returncode == 2
    assert "Traceback" not in result.stderr + result.stdout
    assert f"{manifest}:5:1" in result.stderr
    assert "axes" in result.stderr  # the close match is suggested
    assert not (tmp_path / "build").exists()


def test_garbage_clip_is_exit_2_naming_the_file(tmp_path: Path) -> None:
    (tmp_path / "clips").mkdir()
    bad = tmp_path / "clips" / "broken.usda"
    bad.write_text("#usda 1.0\n(\n  this is not usd\n")
    before = bad.read_bytes()
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\n")
    result = _cli("build", str(manifest))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert str(bad) in result.stderr
    assert bad.read_bytes() == before
    assert not (tmp_path / "build").exists()


def test_every_unreadable_clip_is_named_at_once(tmp_path: Path) -> None:
    """Only the first unreadable file was named: a studio fixing ten files ran ten builds. Each is
    its own `path:line: message`, a hint shared by several is said once, and past `MORE_SHOWN`
    the rest are counted."""
    _write_clip(tmp_path / "clips", GaitSpec("walk", speed=1.4))
    for index in range(MORE_SHOWN + 3):
        (tmp_path / "clips" / f"bad{index:02d}.bvh").write_text("HIERARCHY\nROOT x\n{\n")
    (tmp_path / "broken.glb").write_bytes(b"glTF garbage")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n  - path: broken.glb\n")
    result = _cli("build", str(manifest))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.splitlines()
    bvh = [line for line in lines if "truncated BVH" in line]
    assert len(bvh) == MORE_SHOWN + 1 and bvh[0].startswith(str(tmp_path / "clips" / "bad00.bvh") + ":3: ")
    assert sum("hint: re-export the clip as BVH" in line for line in lines) == 1
    assert lines[-1] == "... and 3 more"  # broken.glb, the 24th error, among them
    assert not (tmp_path / "build").exists()
    # Machine formats carry every one of them, as findings.
    for command in ("build", "check"):
        result = _cli(command, str(manifest), "--format", "json")
        assert result.returncode == 2, result.stderr
        found = json.loads(result.stdout)["diagnostics"]
        assert len(found) == MORE_SHOWN + 4
        assert {d["rule"] for d in found} == {"invalid-input"}
        assert any("broken.glb" in d["message"] for d in found)


def test_every_clip_path_that_finds_nothing_is_named_at_once(tmp_path: Path) -> None:
    """Three entries that find no file: the first stopped the build, and the next run found the
    next. Each is said at its own manifest line, before anything is measured."""
    _write_clip(tmp_path / "clips", GaitSpec("walk", speed=1.4))
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\n  - path: nowhere/a.bvh\n"
        "  - path: gone/*.bvh\n  - path: also_missing.bvh\n"
    )
    result = _cli("check", str(manifest))
    assert result.returncode == 2, result.stderr
    located = [line for line in result.stderr.splitlines() if line.startswith(f"{manifest}:")]
    assert [line.split(": ")[0] for line in located] == [f"{manifest}:{n}:5" for n in (5, 6, 7)]
    assert "Traceback" not in result.stderr


def test_unsupported_and_missing_clips_are_exit_2(tmp_path: Path) -> None:
    (tmp_path / "walk.fbx").write_bytes(b"Kaydara FBX Binary  \x00")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: walk.fbx\n")
    result = _cli("check", str(manifest))
    assert result.returncode == 2
    assert "FBX" in result.stderr and "glTF" in result.stderr and "Traceback" not in result.stderr
    assert result.stderr.startswith(f"{manifest}:4:5: ")  # the entry that pulled the file in

    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: nowhere/*.bvh\n")
    result = _cli("check", str(manifest))
    assert result.returncode == 2
    assert f"{manifest}:4" in result.stderr and "Traceback" not in result.stderr


def test_windows_style_paths_in_the_manifest(tmp_path: Path) -> None:
    for spec in (GaitSpec("idle"), GaitSpec("walk", speed=1.4), GaitSpec("turn", turn_rate=90.0)):
        _write_clip(tmp_path / "clips", spec)
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips\\*.usda\noutput: {dir: 'out\\sub'}\n"
    )
    assert main(["build", str(manifest), "--format", "json"]) in (0, 1)
    doc = json.loads((tmp_path / "out" / "sub" / "t.blendspace.json").read_text())
    assert sorted(s["name"] for s in doc["samples"] if not s["generated"]) == ["idle", "turn", "walk"]


def test_a_failing_writer_leaves_nothing_behind(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for spec in (GaitSpec("idle"), GaitSpec("walk", speed=1.4), GaitSpec("turn", turn_rate=90.0)):
        _write_clip(tmp_path / "clips", spec)
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\n")

    import blendspace_pipeline.report as report

    def broken_png(*_args: object, **_kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    def buggy_png(*_args: object, **_kwargs: object) -> None:
        raise RuntimeError("a bug in a writer")

    # The file system refusing is the user's to fix (exit 2); a bug in a writer is ours (exit 3).
    monkeypatch.setattr(report, "write_png", broken_png)
    assert main(["build", str(manifest)]) == 2
    assert not (tmp_path / "build").exists()
    monkeypatch.setattr(report, "write_png", buggy_png)
    assert main(["build", str(manifest)]) == 3
    assert not (tmp_path / "build").exists()

    # An existing output folder keeps its previous outputs untouched.
    monkeypatch.undo()
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["build", str(manifest)]) in (0, 1)
    previous = _tree(tmp_path / "build")
    monkeypatch.setattr(report, "write_png", broken_png)
    # An edited manifest that changes the document, so the build runs again and the PNG must be
    # written (an unchanged one replays its stamp; an unchanged document keeps its PNG).
    manifest.write_text(manifest.read_text() + "thresholds: {too_close: 2.5}\n")
    assert main(["build", str(manifest)]) == 2
    assert _tree(tmp_path / "build") == previous


def test_a_range_past_the_end_of_its_clip_is_exit_2_at_the_entry(tmp_path: Path) -> None:
    _write_clip(tmp_path / "clips", GaitSpec("walk", speed=1.4, duration=2.5))
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/walk.usda\n    range: [0.5, 25]\n"
    )
    result = _cli("check", str(manifest))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.startswith(f"{manifest}:4:5: ")
    assert "range ends at 25 s but the clip lasts 2.5 s" in result.stderr


def test_copies_of_one_take_keep_their_own_names_through_the_cache(tmp_path: Path) -> None:
    spec = GaitSpec("walk", speed=1.4)
    _write_clip(tmp_path / "clips", spec)
    copy = tmp_path / "clips" / "walk_copy.usda"
    copy.write_bytes((tmp_path / "clips" / "walk.usda").read_bytes())
    one = tmp_path / "one.yaml"
    one.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/walk.usda\n")
    both = tmp_path / "both.yaml"
    both.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\n")
    assert _cli("check", str(one)).returncode in (0, 1)  # fills the cache with walk.usda
    result = _cli("check", str(both), "--format", "json")
    assert result.returncode in (0, 1), result.stderr
    assert "walk_copy" in result.stdout
