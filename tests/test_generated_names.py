"""Generated clips whose names would share a file: each gets its own file, and each sample's
source is the file of its own clip (`motion.file_names.unique_stems`)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.file_names import safe_file_stem, unique_stems
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip

SPECS = [
    GaitSpec("idle", duration=2.0),
    GaitSpec("walk_fwd", speed=1.4, duration=1.0),
    GaitSpec("run_fwd", speed=4.0, duration=1.0, stride_length=2.6),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, duration=1.0, stride_length=1.1),
    GaitSpec("walk_turn_left", speed=1.4, turn_rate=60.0, duration=1.5),
    GaitSpec("walk_turn_right", speed=1.4, turn_rate=-60.0, duration=1.5),
    # Mirrored to "spin right" and "spin_right": one file name, safe_file_stem's `spin_right`.
    GaitSpec("spin left", turn_rate=90.0, duration=2.0),
    GaitSpec("spin_left", turn_rate=45.0, duration=2.0),
]


def _project(folder: Path, specs: list[GaitSpec], suffix: str, clips: str, output: str = "") -> Path:
    """``specs`` written under folder/clips as BVH or USD (``suffix``) and a manifest globbing
    ``clips``, with ``output`` settings; returns the manifest."""
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    (folder / "clips").mkdir()
    for spec in specs:
        path = folder / "clips" / f"{spec.name}{suffix}"
        if suffix == ".bvh":
            write_bvh_clip(generate(spec), path)
        else:
            write_usd_clip(generate(spec), path, meters_per_unit=1.0, up_axis="y")
    manifest = folder / "manifest.yaml"
    extra = f"output: {{{output}}}\n" if output else ""
    manifest.write_text(
        f"schema_version: 1\nname: loco\nclips:\n  - path: '{clips}'\n{extra}", encoding="utf-8"
    )
    return manifest


def test_unique_stems_keep_plain_stems_and_part_only_the_names_that_clash() -> None:
    names = ("spin left", "spin_left", "Run", "run")
    stems = unique_stems(["walk", *names, "jog"])
    assert stems["walk"] == "walk" and stems["jog"] == "jog"
    clashing = [stems[n] for n in names]
    assert len({s.casefold() for s in clashing}) == 4  # one file each, also without letter case
    assert all(s.startswith(safe_file_stem(n) + "-") for n, s in zip(names, clashing, strict=True))
    # The same name gets the same stem in any set it clashes in (rebuilds keep their file names).
    assert unique_stems(["spin_left", "spin left"])["spin left"] == stems["spin left"]


def test_generated_clips_whose_names_share_a_file_name_each_get_their_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two mirrors, `spin right` (-90 deg/s) and `spin_right` (-45 deg/s), were both written to
    clips/spin_right.*: the second overwrote the first, and one sample's clip was the other's."""
    manifest = _project(tmp_path, SPECS, ".bvh", "clips/*.bvh", "formats: [json], clip_formats: [bvh]")
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json"]) in (0, 1)
    capsys.readouterr()
    doc = json.loads((out / "loco.blendspace.json").read_text(encoding="utf-8"))
    generated = {s["name"]: s for s in doc["samples"] if s["generated"]}
    assert {"spin right", "spin_right"} <= set(generated)
    sources = {name: generated[name]["source"] for name in ("spin right", "spin_right")}
    assert sources["spin right"] != sources["spin_right"]
    for name, turn in (("spin right", -90.0), ("spin_right", -45.0)):
        file = out / Path(sources[name]).with_suffix(".bvh")
        [clip] = read_clips(file)
        assert measure(clip, RigSettings()).features["turn_rate"] == pytest.approx(turn, abs=1.0), name


def test_a_glob_does_not_read_a_blend_space_asset_as_a_take(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`build --out .` puts `N.blendspace.usda` beside the manifest; a later `check` (which looks
    for outputs in `output.dir`) globbed `**/*.usda` onto it and failed: "no UsdSkel Skeleton"."""
    manifest = _project(tmp_path, SPECS[:6], ".usda", "**/*.usda")
    assert main(["build", str(manifest), "--out", str(tmp_path), "--no-fix"]) in (0, 1)
    assert (tmp_path / "loco.blendspace.usda").exists()
    capsys.readouterr()
    assert main(["check", str(manifest)]) in (0, 1)
    out = capsys.readouterr()
    assert "UsdSkel" not in out.err + out.out


def test_a_clip_a_build_placed_beside_the_sources_is_no_take_for_a_later_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`build --out .` places its mirror in ./clips/, beside the sources. A later `check` (or a
    build to `output.dir`) looked for the placement record in `output.dir`, did not find it, and
    read the mirror as a take: 14 samples and no generated clip, where the first build had 13 + 1."""
    manifest = _project(tmp_path, SPECS[:7], ".bvh", "clips/*.bvh", "formats: [json], clip_formats: [bvh]")
    assert main(["build", str(manifest), "--out", str(tmp_path)]) in (0, 1)
    first = capsys.readouterr().out
    assert "1 generated (spin right)" in first and (tmp_path / "clips" / "spin_right.bvh").exists()
    assert main(["build", str(manifest)]) in (0, 1)  # to output.dir (build/)
    again = capsys.readouterr().out
    assert "built 8 samples" in first and "built 8 samples" in again and "1 generated (spin right)" in again


def test_bvh_asked_by_name_is_written_for_clips_made_from_other_formats(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`clip_formats: [bvh]` on USD sources wrote the USD alone, with no word: the BVH is written
    too now (in its own layout), and reads back as the clip the fix made."""
    manifest = _project(tmp_path, SPECS[:7], ".usda", "clips/*.usda", "formats: [json], clip_formats: [bvh]")
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out)]) in (0, 1)
    capsys.readouterr()
    [clip] = read_clips(out / "clips" / "spin_right.bvh")
    assert measure(clip, RigSettings()).features["turn_rate"] == pytest.approx(-90.0, abs=1.0)
    assert (out / "clips" / "spin_right.usda").exists()  # the sample's source, readable beside its set


def test_a_style_layers_glob_does_not_read_a_blend_space_asset_as_a_take(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The asset filter sat in the clip list's own step: a style layer's `styles/*.usda` still read
    a blend space's `N.blendspace.usda` lying there as a take."""
    project = tmp_path / "p"
    shutil.copytree(Path(__file__).resolve().parents[1] / "sample_project", project)
    manifest = project / "manifest.yaml"
    text = manifest.read_text(encoding="utf-8")
    assert "clips: [styles/limp_fwd.usda, styles/limp_bwd.usda]" in text
    manifest.write_text(
        text.replace("clips: [styles/limp_fwd.usda, styles/limp_bwd.usda]", "clips: [styles/limp_*.usda]"),
        encoding="utf-8",
    )
    assert main(["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]) in (0, 1)
    shutil.copy(
        tmp_path / "out" / "locomotion.blendspace.usda", project / "styles" / "limp_space.blendspace.usda"
    )
    capsys.readouterr()
    assert main(["check", str(manifest)]) in (0, 1)
    out = capsys.readouterr()
    assert "limp_space" not in out.err + out.out and "UsdSkel" not in out.err + out.out
