"""Beta and style layers in the build: analysed, checked, written to JSON and USD."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pxr import Usd

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.space.evaluate import evaluate
from blendspace_pipeline.space.layers_doc import read_document
from blendspace_pipeline.writers.usd_clip import write_usd_clip

MAIN = (
    GaitSpec("idle"),
    GaitSpec("walk", speed=1.4),
    GaitSpec("back", speed=1.0, direction=180.0),
    GaitSpec("tip_left", turn_rate=90.0, duration=2.0),
    GaitSpec("tip_right", turn_rate=-90.0, duration=2.0),
)
LATERAL = (GaitSpec("strafe", speed=1.2, direction=90.0), GaitSpec("strafe_run", speed=3.0, direction=90.0))
STYLE = (GaitSpec("limp_fwd", speed=0.9, sway=0.08), GaitSpec("limp_bwd", speed=0.6, direction=180.0))

AXES = "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"


def _clips(folder: Path, specs: tuple[GaitSpec, ...]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for spec in specs:
        write_usd_clip(generate(spec), folder / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")


def _project(
    tmp_path: Path, *, style_clips: str = "[styles/*.usda]", mask: str = "", lateral_axes: str = AXES
) -> Path:
    _clips(tmp_path / "clips", MAIN)
    _clips(tmp_path / "lateral", LATERAL)
    _clips(tmp_path / "styles", STYLE)
    (tmp_path / "lateral.yaml").write_text(
        "schema_version: 1\nname: lateral\nclips:\n  - path: clips/idle.usda\n  - path: clips/tip_left.usda\n"
        "  - path: lateral/*.usda\n" + lateral_axes
    )
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: loco\nclips:\n  - path: clips/*.usda\n"
        + AXES
        + "layers:\n  - {name: lateral, kind: beta, manifest: lateral.yaml}\n"
        + f"  - name: limp\n    kind: style\n    clips: {style_clips}\n"
        + (f"    mask: {mask}\n" if mask else "")
    )
    return manifest


def test_layers_are_measured_placed_and_written(tmp_path: Path) -> None:
    manifest = _project(tmp_path, mask="{joints: {Hips: 1.0, LeftUpLeg: 1.0}, default: 0.25}")
    assert main(["build", str(manifest), "--out", str(tmp_path / "out")]) in (0, 1)
    doc = json.loads((tmp_path / "out" / "loco.blendspace.json").read_text())
    beta, style = doc["layers"]
    assert (beta["name"], beta["kind"], beta["source"]) == ("lateral", "beta", "../lateral.yaml")
    positions = {s["name"]: s["position"] for s in beta["samples"]}
    assert positions["strafe"] == [0.0, pytest.approx(1.2)] and positions["strafe_run"] == [0.0, 3.0]
    assert beta["triangles"] == [] or all(len(t) == 3 for t in beta["triangles"])
    assert style["kind"] == "style" and style["axis"]["feature"] == "speed"
    assert {s["name"]: s["position"] for s in style["samples"]} == {
        "limp_fwd": [pytest.approx(0.9)],
        "limp_bwd": [pytest.approx(-0.6)],
    }
    assert style["mask"] == {"joints": {"Hips": 1.0, "LeftUpLeg": 1.0}, "default": 0.25}

    stage = Usd.Stage.Open(str(tmp_path / "out" / "loco.blendspace.usda"))
    layers = stage.GetDefaultPrim().GetChild("Layers")
    assert [p.GetName() for p in layers.GetChildren()] == ["lateral", "limp"]
    assert layers.GetChild("limp").GetAttribute("blendspace:mask:default").Get() == 0.25
    # The beta layer's own `fixes:` ran: its missing tip_right was mirrored into clips/lateral/.
    assert len(layers.GetChild("lateral").GetChild("Samples").GetChildren()) == 5
    made = next(s for s in beta["samples"] if s["generated"])
    assert (made["name"], made["fix"], made["source"]) == (
        "tip_right",
        "missing-opposite",
        "clips/lateral/tip_right.usda",
    )
    assert made["position"] == [-90.0, 0.0]
    assert (tmp_path / "out" / "clips" / "lateral" / "tip_right.usda").is_file()

    # The evaluator reads the layers back: weights sum to 1 and the style share is its intensity.
    loaded = read_document(tmp_path / "out" / "loco.blendspace.json")
    result = evaluate(loaded, 0.0, 1.0, layers={"limp": 0.4})
    assert sum(w.weight for w in result.weights) == pytest.approx(1.0)
    assert sum(w.weight for w in result.weights if w.layer == "limp") == pytest.approx(0.4)


def test_beta_layer_on_other_axes_is_an_error(tmp_path: Path) -> None:
    other = AXES.replace("max: 6,", "max: 8,")
    space = analyse(_project(tmp_path, lateral_axes=other))
    found = [d for d in space.all_diagnostics() if d.rule == "layer-axes"]
    assert len(found) == 1 and found[0].severity == "error"
    assert "speed [-3, 8]" in found[0].message and found[0].line is not None


def test_beta_layer_diagnostics_are_anchored_in_its_own_manifest(tmp_path: Path) -> None:
    space = analyse(_project(tmp_path))
    lateral = [d for d in space.all_diagnostics() if d.path and d.path.endswith("lateral.yaml")]
    assert [d.clips for d in lateral if d.rule == "missing-opposite"] == [("tip_left",)]


def test_style_without_a_backward_clip_and_a_mask_typo(tmp_path: Path) -> None:
    manifest = _project(
        tmp_path, style_clips="[styles/limp_fwd.usda]", mask="{joints: {Hips: 1, LeftUpleg: 1}}"
    )
    space = analyse(manifest)
    rules = {d.rule: d for d in space.all_diagnostics()}
    assert "backward" in rules["style-coverage"].message
    assert rules["mask-joints"].hint == "did you mean 'LeftUpLeg'?"


@pytest.mark.parametrize(
    "change", ["namespaced", "extra_joint", "missing_leaf", "reparented", "reordered", "fps"]
)
def test_a_layer_clip_on_another_rig_or_rate_is_reported(change: str, tmp_path: Path) -> None:
    """A style clip is blended joint by joint with the main clips: one of another skeleton (or
    rate) was not reported when the same clip in the main list was."""
    from blendspace_pipeline.motion.hostile import on_other_skeleton

    manifest = _project(tmp_path)
    if change == "fps":
        clip = generate(GaitSpec("limp_fwd", speed=0.9, sway=0.08, fps=60.0))
    else:
        clip = on_other_skeleton(generate(STYLE[0]), change)
    write_usd_clip(clip, tmp_path / "styles" / "limp_fwd.usda", meters_per_unit=1.0, up_axis="y")
    rule = "inconsistent-fps" if change == "fps" else "inconsistent-skeleton"
    found = [d for d in analyse(manifest).all_diagnostics() if d.rule == rule]
    assert [(d.clips, "style layer 'limp'" in d.message) for d in found] == [(("limp_fwd",), True)]
    layers_line = manifest.read_text(encoding="utf-8").splitlines().index("layers:") + 1
    assert found[0].line == layers_line  # at the layers (it was at `clips:`)


@pytest.mark.parametrize("fps, reported", [(25.0, True), (30.5, False), (29.5, False), (60.0, True)])
def test_a_main_clip_at_another_rate_is_reported_unless_within_2_percent(
    fps: float, reported: bool, tmp_path: Path
) -> None:
    """24 and 25 fps are two exports (4 % apart); a rate a reader fitted to a clip's length is not."""
    manifest = _project(tmp_path)
    write_usd_clip(
        generate(GaitSpec("walk", speed=1.4, fps=fps)),
        tmp_path / "clips" / "walk.usda",
        meters_per_unit=1.0,
        up_axis="y",
    )
    found = [
        d
        for d in analyse(manifest).all_diagnostics()
        if d.rule == "inconsistent-fps" and "layer" not in d.message
    ]
    assert [d.clips for d in found] == ([("walk",)] if reported else [])


def test_layer_clips_of_the_main_rig_and_rate_are_not_reported(tmp_path: Path) -> None:
    rules = {d.rule for d in analyse(_project(tmp_path)).all_diagnostics()}
    assert not rules & {"inconsistent-fps", "inconsistent-skeleton"}


def test_missing_beta_manifest_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _project(tmp_path)
    (tmp_path / "lateral.yaml").unlink()
    assert main(["check", str(manifest)]) == 2
    err = capsys.readouterr().err
    assert "lateral.yaml not found" in err and f"{manifest}:" in err


def test_no_fix_leaves_the_beta_layer_as_authored(tmp_path: Path) -> None:
    manifest = _project(tmp_path)
    assert main(["build", str(manifest), "--out", str(tmp_path / "out"), "--no-fix"]) in (0, 1)
    beta = json.loads((tmp_path / "out" / "loco.blendspace.json").read_text())["layers"][0]
    assert not [s for s in beta["samples"] if s["generated"]]
    assert not (tmp_path / "out" / "clips").exists()
