"""Bad input through the real command line: exit 2, `path:line: message`, a hint, no traceback,
no output folder, and the source files untouched."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from pxr import Sdf, Usd, UsdGeom

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

GOOD_CLIPS = ("idle", "walk", "turn")


def _good_clips(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    specs = {
        "idle": GaitSpec("idle"),
        "walk": GaitSpec("walk", speed=1.4),
        "turn": GaitSpec("turn", turn_rate=90.0),
    }
    for name in GOOD_CLIPS:
        write_usd_clip(generate(specs[name]), folder / f"{name}.usda", meters_per_unit=1.0, up_axis="y")


def _manifest(tmp: Path, body: str) -> Path:
    path = tmp / "manifest.yaml"
    path.write_text(body)
    return path


HEADER = "schema_version: 1\nname: t\n"


def unknown_key(tmp: Path) -> tuple[Path, str]:
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/*.usda\nthreshold: {too_close: 8}\n"), ":5:1"


def wrong_type(tmp: Path) -> tuple[Path, str]:
    body = HEADER + "clips:\n  - path: clips/*.usda\naxes:\n  x: {feature: turn_rate, min: left, max: 180}\n"
    return _manifest(tmp, body), ":6:"


def missing_file(tmp: Path) -> tuple[Path, str]:
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/nothere.usda\n"), ":4:"


def glob_matching_nothing(tmp: Path) -> tuple[Path, str]:
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/*.bvh\n"), ":4:"


def empty_yaml(tmp: Path) -> tuple[Path, str]:
    return _manifest(tmp, ""), "manifest.yaml"


def alias_bomb(tmp: Path) -> tuple[Path, str]:
    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 12):
        lines.append(f"{chr(97 + i)}: &{chr(97 + i)} [" + ", ".join([f"*{chr(96 + i)}"] * 10) + "]")
    return _manifest(tmp, "\n".join(lines) + "\n"), "manifest.yaml"


def duplicate_names(tmp: Path) -> tuple[Path, str]:
    body = HEADER + "clips:\n  - path: clips/walk.usda\n  - path: clips/turn.usda\n    name: walk\n"
    return _manifest(tmp, body), ":5:"


def nan_values(tmp: Path) -> tuple[Path, str]:
    clip = generate(GaitSpec("nan", speed=1.0))
    clip.translations[3, 0, 1] = float("nan")
    write_usd_clip(clip, tmp / "clips" / "nan.usda", meters_per_unit=1.0, up_axis="y")
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/*.usda\n"), "nan.usda"


def huge_values(tmp: Path) -> tuple[Path, str]:
    clip = generate(GaitSpec("huge", speed=1.0))
    clip.translations[3, 0, 1] = 1e308  # finite, but no length: FK overflows
    write_bvh_clip(clip, tmp / "clips" / "huge.bvh")
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/*.usda\n  - path: clips/huge.bvh\n"), "huge.bvh"


def usd_without_skeleton(tmp: Path) -> tuple[Path, str]:
    stage = Usd.Stage.CreateNew(str(tmp / "clips" / "mesh.usda"))
    UsdGeom.Xform.Define(stage, Sdf.Path("/World"))
    stage.GetRootLayer().Save()
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/*.usda\n"), "mesh.usda"


def zero_frames_bvh(tmp: Path) -> tuple[Path, str]:
    (tmp / "clips" / "empty.bvh").write_text(
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition "
        "Zrotation Xrotation Yrotation\n  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\n"
        "MOTION\nFrames: 0\nFrame Time: 0.033333\n"
    )
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/empty.bvh\n"), "empty.bvh"


def garbage_bvh(tmp: Path) -> tuple[Path, str]:
    (tmp / "clips" / "junk.bvh").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00garbage")
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/junk.bvh\n"), "junk.bvh"


def truncated_bvh(tmp: Path) -> tuple[Path, str]:
    (tmp / "clips" / "cut.bvh").write_text(
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition "
        "Zrotation Xrotation Yrotation\n  JOINT Spine\n  {\n    OFFSET 0 10 0\n"
    )
    return _manifest(tmp, HEADER + "clips:\n  - path: clips/cut.bvh\n"), "cut.bvh"


def duplicate_layer_names(tmp: Path) -> tuple[Path, str]:
    body = (
        HEADER + "clips:\n  - path: clips/*.usda\nlayers:\n"
        "  - {name: limp, kind: style, clips: [clips/walk.usda]}\n"
        "  - {name: limp, kind: style, clips: [clips/turn.usda]}\n"
    )
    return _manifest(tmp, body), ":7:"


CASES: list[Callable[[Path], tuple[Path, str]]] = [
    unknown_key,
    wrong_type,
    missing_file,
    glob_matching_nothing,
    empty_yaml,
    alias_bomb,
    duplicate_names,
    nan_values,
    huge_values,
    usd_without_skeleton,
    zero_frames_bvh,
    garbage_bvh,
    truncated_bvh,
    duplicate_layer_names,
]


@pytest.mark.parametrize("case", CASES, ids=[c.__name__ for c in CASES])
@pytest.mark.parametrize("command", ["build", "check"])
def test_bad_input_exits_2_with_a_location_and_no_traceback(
    case: Callable[[Path], tuple[Path, str]], command: str, tmp_path: Path
) -> None:
    _good_clips(tmp_path / "clips")
    manifest, where = case(tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    result = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", command, str(manifest)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    first = result.stderr.splitlines()[0]
    assert where in first, first
    assert "hint:" in result.stderr
    assert not (tmp_path / "build").exists()
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_an_output_folder_that_is_a_file_exits_2_and_leaves_it_alone(tmp_path: Path) -> None:
    _good_clips(tmp_path / "clips")
    manifest = _manifest(tmp_path, HEADER + "clips:\n  - path: clips/*.usda\n")
    blocker = tmp_path / "out"
    blocker.write_text("not a folder")
    result = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "build", str(manifest), "--out", str(blocker)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    assert "cannot write the outputs" in result.stderr and "hint:" in result.stderr
    assert blocker.read_text() == "not a folder"
