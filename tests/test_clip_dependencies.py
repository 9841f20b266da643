"""A clip read with other files (a USD layer composing another, a `.gltf` with an external
`.bin`): editing the other file re-measures the clip. Both the build stamp and the measurement
cache had keyed the clip on its own file: the build kept the old numbers, even with the stamps
deleted, until the cache was switched off."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import analysis, outputs
from blendspace_pipeline.readers.dependencies import file_dependencies
from blendspace_pipeline.writers.gltf import write_gltf_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

OTHERS = [
    GaitSpec("idle", duration=2.0),
    GaitSpec("run", speed=4.0, duration=1.0, stride_length=2.6),
    GaitSpec("back", speed=1.1, direction=180.0, duration=1.0, stride_length=1.1),
]


def _usd_with_a_layer(folder: Path, speed: float) -> Path:
    """clips/walk.usda composes ../anim/walk_anim.usda (a sublayer) holding the animation."""
    (folder / "anim").mkdir(exist_ok=True)
    write_usd_clip(
        generate(GaitSpec("walk", speed=speed, duration=1.0)),
        folder / "anim" / "walk_anim.usda",
        meters_per_unit=1.0,
        up_axis="y",
    )
    shot = folder / "clips" / "walk.usda"
    shot.write_text("#usda 1.0\n(\n    subLayers = [@../anim/walk_anim.usda@]\n)\n", encoding="utf-8")
    return folder / "anim" / "walk_anim.usda"


def _gltf_with_a_buffer(folder: Path, speed: float) -> Path:
    """clips/walk.gltf with its buffer in ../bin/walk.bin (the GLB's JSON and BIN chunks apart)."""
    glb = folder / "walk.glb"
    write_gltf_clip(
        generate(GaitSpec("walk", speed=speed, duration=1.0)), glb, meters_per_unit=1.0, up_axis="y"
    )
    data = glb.read_bytes()
    (json_length,) = struct.unpack_from("<I", data, 12)
    document = json.loads(data[20 : 20 + json_length])
    (bin_length,) = struct.unpack_from("<I", data, 20 + json_length)
    document["buffers"][0]["uri"] = "../bin/walk.bin"
    (folder / "bin").mkdir(exist_ok=True)
    (folder / "clips" / "walk.gltf").write_text(json.dumps(document), encoding="utf-8")
    buffer = folder / "bin" / "walk.bin"
    buffer.write_bytes(data[28 + json_length : 28 + json_length + bin_length])
    glb.unlink()
    return buffer


def _glb_with_a_buffer(folder: Path, speed: float) -> Path:
    """clips/walk.glb whose buffer is ../bin/walk.bin (a JSON chunk only, as some exporters
    write a GLB with its data beside it)."""
    buffer = _gltf_with_a_buffer(folder, speed)
    gltf = folder / "clips" / "walk.gltf"
    text = gltf.read_bytes()
    text += b" " * (-len(text) % 4)
    gltf.unlink()
    header = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text)) + struct.pack("<I4s", len(text), b"JSON")
    (folder / "clips" / "walk.glb").write_bytes(header + text)
    return buffer


@pytest.mark.parametrize("kind", ["usd", "gltf", "glb"])
def test_editing_the_file_a_clip_is_read_with_re_measures_it(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "clips").mkdir()
    for spec in OTHERS:
        write_usd_clip(
            generate(spec), tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    make = {"usd": _usd_with_a_layer, "gltf": _gltf_with_a_buffer, "glb": _glb_with_a_buffer}[kind]
    other = make(tmp_path, 1.4)
    assert file_dependencies(tmp_path / "clips" / f"walk.{'usda' if kind == 'usd' else kind}", tmp_path) == [
        other
    ]
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*\noutput: {formats: [json]}\n", encoding="utf-8"
    )
    out = tmp_path / "out"
    argv = ["build", str(manifest), "--out", str(out), "--no-fix"]
    analyses = []
    analyse = analysis.analyse

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        analyses.append(1)
        return analyse(*args, **kwargs)

    monkeypatch.setattr(outputs, "analyse", counting)

    def speed() -> float:
        doc = json.loads((out / "t.blendspace.json").read_text(encoding="utf-8"))
        return next(s["features"]["speed"] for s in doc["samples"] if s["name"] == "walk")

    assert main(argv) in (0, 1)
    assert speed() == pytest.approx(1.4, abs=0.02)
    assert main(argv) in (0, 1) and len(analyses) == 1  # nothing moved: replayed
    make(tmp_path, 2.5)  # the other file changes; the clip's own file is the same bytes
    assert main(argv) in (0, 1) and len(analyses) == 2
    assert speed() == pytest.approx(2.5, abs=0.02)
    # The cache alone (no stamp: another output folder) reads the new layer or buffer too.
    assert main(["build", str(manifest), "--out", str(tmp_path / "other"), "--no-fix"]) in (0, 1)
    doc = json.loads((tmp_path / "other" / "t.blendspace.json").read_text(encoding="utf-8"))
    assert next(s["features"]["speed"] for s in doc["samples"] if s["name"] == "walk") == pytest.approx(
        2.5, abs=0.02
    )
    capsys.readouterr()
    assert other.exists()


def test_formats_of_one_file_have_no_dependencies(tmp_path: Path) -> None:
    """A BVH or a GLB is read alone; a USD stage without composition arcs too."""
    write_usd_clip(generate(OTHERS[0]), tmp_path / "idle.usda", meters_per_unit=1.0, up_axis="y")
    write_gltf_clip(generate(OTHERS[0]), tmp_path / "idle.glb", meters_per_unit=1.0, up_axis="y")
    for name in ("idle.usda", "idle.glb", "walk.bvh"):
        assert file_dependencies(tmp_path / name) == []


@pytest.mark.parametrize("kind", ["usd", "gltf"])
def test_a_reference_that_is_a_symlink_loop_is_bad_input_not_a_crash(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A sublayer or buffer path that is a symlink pointing at itself: `Path.resolve` raises
    RuntimeError (Python 3.11), which escaped as an internal error (exit 3)."""
    (tmp_path / "clips").mkdir()
    for spec in OTHERS:
        write_usd_clip(
            generate(spec), tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    dependency = _usd_with_a_layer(tmp_path, 1.4) if kind == "usd" else _gltf_with_a_buffer(tmp_path, 1.4)
    dependency.unlink()
    dependency.symlink_to(dependency.name)  # points at itself
    (tmp_path / "manifest.yaml").write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*\n", encoding="utf-8"
    )
    assert main(["check", str(tmp_path / "manifest.yaml")]) == 2
    err = capsys.readouterr().err
    assert "walk." in err and "Traceback" not in err and "internal error" not in err.lower()


def test_a_cached_clips_dependencies_are_not_listed_by_parsing_it_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A clip the cache holds (another manifest over the same takes: the pack misses) was opened
    layer by layer only to list its dependencies. The list is remembered by the clip's content
    and holds while every listed file reads the same: a layer that names one more is walked again."""
    from blendspace_pipeline.pipeline import cache
    from blendspace_pipeline.readers import usd

    (tmp_path / "clips").mkdir()
    for spec in OTHERS:
        write_usd_clip(
            generate(spec), tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    layer = _usd_with_a_layer(tmp_path, 1.4)
    walks: list[Path] = []
    composed = usd.composed_layers

    def counted(path: Path, *args, **kwargs):  # type: ignore[no-untyped-def]
        walks.append(path)
        return composed(path, *args, **kwargs)

    monkeypatch.setattr(usd, "composed_layers", counted)
    for name in ("a", "b"):  # two manifests over the same clips: two packs, one per-clip cache
        (tmp_path / f"{name}.yaml").write_text(
            f"schema_version: 1\nname: {name}\nclips:\n  - path: clips/*\n", encoding="utf-8"
        )
        assert main(["check", str(tmp_path / f"{name}.yaml"), "--jobs", "1"]) in (0, 1)
    assert len(walks) == 4  # the four clips of the first manifest, none of the second's
    clip = tmp_path / "clips" / "walk.usda"
    digest = cache.content_digest(clip)

    def listed() -> list[str]:
        return [
            p
            for p, _, _ in cache.known_dependencies(
                clip, digest, tmp_path, lambda: file_dependencies(clip, tmp_path)
            )
        ]

    assert listed() == [str(layer)] and len(walks) == 4
    more = tmp_path / "anim" / "more.usda"
    more.write_text("#usda 1.0\n", encoding="utf-8")
    text = layer.read_text(encoding="utf-8")
    layer.write_text(
        text.replace("#usda 1.0\n(\n", "#usda 1.0\n(\n    subLayers = [@more.usda@]\n", 1), encoding="utf-8"
    )
    assert "subLayers = [@more.usda@]" in layer.read_text(encoding="utf-8")
    assert listed() == sorted([str(layer), str(more)]) and len(walks) == 5
    capsys.readouterr()
