"""Generated clips for engines: the build writes a GLB beside the UsdSkel (and BVH) of every clip
the fixes made, `output.clip_formats` narrows the list, and the engine exports point at them
(Godot `res://` paths, Unity `.meta` GUIDs, the Unreal script's imports)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from test_fixes import _build, _project

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.readers import read_clips


def _world(path: Path) -> np.ndarray:
    clip = read_clips(path)[0]
    units = clip.meters_per_unit or 1.0
    return np.asarray(forward_kinematics(clip)[1]) * units


def test_every_generated_clip_is_also_a_glb_with_the_same_motion(tmp_path: Path) -> None:
    doc = _build(_project(tmp_path), tmp_path / "out")
    made = [s for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made
    for sample in made:
        usd = tmp_path / "out" / "clips" / f"{sample['name']}.usda"
        glb = usd.with_suffix(".glb")
        assert sample["source"] == f"clips/{sample['name']}.usda"
        assert glb.read_bytes()[:4] == b"glTF"
        (animation,) = json.loads(
            glb.read_bytes()[20 : 20 + int.from_bytes(glb.read_bytes()[12:16], "little")]
        )["animations"]
        assert animation["name"] == sample["name"]  # what Godot, Unreal and glTFast call the clip
        # Both files are metres and +Y up here: joint world positions agree to float32 precision.
        assert np.abs(_world(usd) - _world(glb)).max() < 1e-4


@pytest.mark.parametrize(("formats", "suffixes"), [("[glb]", {".glb"}), ("[usd]", {".usda"})])
def test_clip_formats_narrows_what_is_written(tmp_path: Path, formats: str, suffixes: set[str]) -> None:
    manifest = _project(tmp_path, extra=f"output: {{clip_formats: {formats}}}\n")
    doc = _build(manifest, tmp_path / "out")
    made = [s for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made
    assert {p.suffix for p in (tmp_path / "out" / "clips").iterdir()} == suffixes
    for sample in made:
        source = tmp_path / "out" / sample["source"]
        assert source.suffix in suffixes and source.is_file()
        assert read_clips(source)[0].frame_count > 0


def test_clip_formats_rejects_unknown_formats(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _project(tmp_path, extra="output: {clip_formats: [fbx]}\n")
    assert main(["build", str(manifest), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "clip_formats" in err and "Traceback" not in err


def test_exports_reference_the_generated_glbs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A Godot project around the build: the export writes res:// paths into it.
    (tmp_path / "project.godot").write_text("config_version=5\n", encoding="utf-8")
    doc = _build(_project(tmp_path), tmp_path / "out")
    made = [s["name"] for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    json_path = tmp_path / "out" / "loco.blendspace.json"
    assert main(["export", str(json_path), "--engine", "godot"]) == 0
    tres = (tmp_path / "out" / "loco.tres").read_text(encoding="utf-8")
    for name in made:
        assert f"; {name}: res://out/clips/{name}.glb imported as Animation Library" in tres
        assert f'animation = &"{name}/{name}"' in tres
    # Unity: a .meta with a stable GUID beside each GLB, identical on the next export.
    assert main(["export", str(json_path), "--engine", "unity"]) == 0
    metas = {name: (tmp_path / "out" / "clips" / f"{name}.glb.meta").read_text() for name in made}
    assert all(re.fullmatch(r"fileFormatVersion: 2\nguid: [0-9a-f]{32}\n", text) for text in metas.values())
    assert len({text for text in metas.values()}) == len(made)
    assert main(["export", str(json_path), "--engine", "unity"]) == 0
    assert metas == {name: (tmp_path / "out" / "clips" / f"{name}.glb.meta").read_text() for name in made}
    # Unreal: the script imports each GLB.
    assert main(["export", str(json_path), "--engine", "unreal"]) == 0
    script = (tmp_path / "out" / "loco_unreal.py").read_text(encoding="utf-8")
    for name in made:
        assert repr(str((tmp_path / "out" / "clips" / f"{name}.glb").resolve())) in script
