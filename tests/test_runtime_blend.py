"""The blend as the engine plays it: sync rates, the document-level model against a tick-by-tick
simulation of the clips, foot skate of the blended pose, and the build's `blend_quality`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, shared_data

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.blend_model import SYNC_MODES, play, playback_rates, prepare
from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.hostile import SKELETON_CHANGES
from blendspace_pipeline.motion.procedural import SAMPLE_SET, GaitSpec, generate_planted
from blendspace_pipeline.report.trajectory_error import document_trajectory_error
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.geometry import locate, normalise
from blendspace_pipeline.space.runtime_blend import delivered, runtime_grid
from blendspace_pipeline.writers.usd_clip import write_usd_clip

SETTINGS = RigSettings()


def _prepared(spec: GaitSpec):  # type: ignore[no-untyped-def]
    clip = generate_planted(spec)
    contacts = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    return prepare(clip, SETTINGS, 1.0, contacts)


def test_playback_rates_of_each_sync_mode() -> None:
    weights, durations, periods = [0.5, 0.5], [0.8, 1.0], [0.8, 0.5]
    assert playback_rates(weights, durations, periods, "none") == [1.0, 1.0]
    # normalized: lengths stretched to the weighted mean 0.9 s.
    assert playback_rates(weights, durations, periods, "normalized") == pytest.approx([0.8 / 0.9, 1.0 / 0.9])
    # markers: the leader (first of the heaviest) plays at 1, the other's strides match its 0.8 s.
    assert playback_rates([0.6, 0.4], durations, periods, "markers") == pytest.approx([1.0, 0.5 / 0.8])
    assert playback_rates([0.6, 0.4], durations, [None, 0.5], "markers") == pytest.approx([1.0, 1.0])
    with pytest.raises(ValueError, match="sync"):
        playback_rates(weights, durations, periods, "phase")  # type: ignore[arg-type]


def test_a_planted_clip_played_at_any_rate_does_not_slide() -> None:
    walk = _prepared(GaitSpec("walk", speed=1.4, turn_rate=30.0, duration=2.0))
    for rate in (1.0, 0.6, 1.3):
        played = play([walk], [1.0], [rate], SETTINGS)
        assert played.foot_sliding == pytest.approx(0.0, abs=0.01)  # 1 cm/s: interpolation noise
        assert played.forward_speed == pytest.approx(1.4 * rate, rel=0.01)
        assert played.turn_rate == pytest.approx(30.0 * rate, rel=0.01)
    # Blending a clip with itself is the clip.
    assert play([walk, walk], [0.3, 0.7], [1.0, 1.0], SETTINGS).foot_sliding == pytest.approx(0.0, abs=0.01)


def test_out_of_step_blends_slide_and_marker_sync_helps() -> None:
    run = _prepared(GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6))
    turn = _prepared(GaitSpec("run_turn_left", speed=4.0, turn_rate=90.0, duration=1.0, stride_length=2.6))
    sliding = {}
    for sync in SYNC_MODES:
        rates = playback_rates([0.5, 0.5], [0.8, 1.0], [0.8, 0.5], sync)
        sliding[sync] = play([run, turn], [0.5, 0.5], rates, SETTINGS).foot_sliding
    # Normalised time puts one stride against two: the feet skate; markers keep strides in step.
    assert sliding["markers"] < 0.5 * sliding["normalized"]
    assert sliding["normalized"] > 0.5  # m/s: a visible skate


@pytest.fixture(scope="module")
def planted_build(tmp_path_factory: pytest.TempPathFactory) -> tuple[BlendSpaceDocument, dict[str, object]]:
    folder = tmp_path_factory.mktemp("planted")
    for spec in SAMPLE_SET:
        write_usd_clip(
            generate_planted(spec), folder / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    manifest = folder / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: planted\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
        "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"
    )
    out = folder / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    text = (out / "planted.blendspace.json").read_text()
    return BlendSpaceDocument.model_validate_json(text), {"out": out, "json": json.loads(text)}


@pytest.mark.parametrize("sync", SYNC_MODES)
def test_the_model_agrees_with_a_simulation_of_the_clips(
    planted_build: tuple[BlendSpaceDocument, dict[str, object]], sync: str
) -> None:
    """20 random points inside the hull: the document-level model (closed form from the measured
    features) and a tick-by-tick play of the actual clips agree within 10 %."""
    doc, _ = planted_build
    specs = {s.name: s for s in SAMPLE_SET}
    prepared = {name: _prepared(spec) for name, spec in specs.items()}
    axes = ((doc.axes[0].min, doc.axes[0].max), (doc.axes[1].min, doc.axes[1].max))
    from blendspace_pipeline.space.geometry import AxisRange

    ranges = (AxisRange(*axes[0]), AxisRange(*axes[1]))
    placed = normalise(np.array([s.position for s in doc.samples]), ranges)
    tris = np.array(doc.triangles)
    rng = np.random.default_rng(12)
    checked = 0
    while checked < 20:
        query = rng.uniform(0.0, 100.0, (1, 2))
        found, bary = locate(query, placed, tris)
        if found[0] < 0:
            continue
        corners = [int(i) for i in tris[found[0]]]
        weights = [float(w) for w in bary[0]]
        samples = [doc.samples[i] for i in corners]
        model = delivered(samples, weights, sync)  # type: ignore[arg-type]
        assert model is not None
        rates = playback_rates(
            weights,
            [s.features["duration"] for s in samples],
            [s.clip.gait_period if s.clip else None for s in samples],
            sync,  # type: ignore[arg-type]
        )
        played = play([prepared[s.name] for s in samples], weights, rates, SETTINGS, seconds=12.0)
        scale_speed = max(abs(played.forward_speed), 0.5)
        scale_turn = max(abs(played.turn_rate), 10.0)
        assert abs(model.forward - played.forward_speed) <= 0.1 * scale_speed
        assert abs(model.lateral - played.lateral_speed) <= 0.1 * scale_speed
        assert abs(model.turn_rate - played.turn_rate) <= 0.1 * scale_turn
        checked += 1


def test_synced_error_exceeds_the_snapping_only_map(
    planted_build: tuple[BlendSpaceDocument, dict[str, object]],
) -> None:
    doc, data = planted_build
    snapping = document_trajectory_error(doc).max_distance
    none = runtime_grid(doc, "none")
    synced = runtime_grid(doc, "normalized")
    markers = runtime_grid(doc, "markers")
    # Even at rate 1 the engine blends velocity vectors, not speeds: a forward and a sideways
    # clip blend to a diagonal slower than their mean speed, which the snapping map cannot see.
    assert none.max_distance > snapping
    assert synced.max_distance > snapping and markers.max_distance > snapping
    # The build carries it: default sync, same grid, numbers in the summary, foot skate measured.
    quality = data["json"]["blend_quality"]  # type: ignore[index]
    assert quality["sync"] == "normalized"
    assert len(quality["trajectory_error"]) == len(quality["ys"]) and len(quality["xs"]) == len(quality["ys"])
    assert quality["summary"]["trajectory_error_max"] == pytest.approx(synced.max_distance, rel=1e-3)
    assert quality["summary"]["drift_max"] > 0.5  # metres over 6 s
    skate = [v for row in quality["foot_skate"] for v in row if v is not None]
    assert skate and min(skate) >= 0.0
    # At the samples' own positions nothing is blended: a planted clip does not slide.
    assert min(skate) < 0.05
    report = (data["out"] / "planted.report.html").read_text()  # type: ignore[operator]
    assert 'id="runtime-heat"' in report and 'id="skate-heat"' in report


def test_cmu_build_measures_foot_skate_of_real_mocap(tmp_path: Path) -> None:
    shared_data("cmu", "131_02.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: cmu\nclips:\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_02.bvh', range: [2.5, 5.8], name: walk_a}}\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_01.bvh', range: [1.0, 3.0], name: walk_left}}\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_01.bvh', range: [4.0, 6.0], name: walk_fast}}\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 36}\n"
        "  y: {feature: speed, min: -1, max: 2, divisions: 30}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json", "--no-fix"]) in (0, 1)
    doc = json.loads((out / "cmu.blendspace.json").read_text())
    quality = doc["blend_quality"]
    assert doc["triangles"]  # (-6, 0.23), (54, 0.43), (-5, 1.15): one triangle
    skate = [v for row in quality["foot_skate"] for v in row if v is not None]
    assert skate and all(0.0 <= v < 3.0 for v in skate)  # mocap feet slide a little, never metres a second
    assert quality["summary"]["foot_skate_max"] == pytest.approx(max(skate), rel=1e-3)


def test_eval_says_what_its_rates_deliver(
    planted_build: tuple[BlendSpaceDocument, dict[str, object]], capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's case: at (44.5, 4.0) run_fwd (0.8 s stride) blends with run_turn_left (0.5 s);
    eval's stride-syncing rates slow the turning clip, so about 34 deg/s come out of 44.5 asked.
    The line agrees with playing the clips at those rates."""
    _, data = planted_build
    path = data["out"] / "planted.blendspace.json"  # type: ignore[operator]
    capsys.readouterr()
    assert main(["eval", str(path), "--at", "x=44.5,y=4.0", "--format", "json"]) == 0
    entries = json.loads(capsys.readouterr().out)["weights"]
    assert main(["eval", str(path), "--at", "x=44.5,y=4.0"]) == 0
    line = next(t for t in capsys.readouterr().out.splitlines() if t.startswith("delivered at these rates"))
    turn = float(line.split("turn ")[1].split(" deg/s")[0])
    specs = {s.name: s for s in SAMPLE_SET}
    played = play(
        [_prepared(specs[e["clip"]]) for e in entries],
        [e["weight"] for e in entries],
        [e["playback_rate"] for e in entries],
        SETTINGS,
        seconds=12.0,
    )
    assert turn == pytest.approx(played.turn_rate, rel=0.1)
    assert turn < 0.85 * 44.5  # the rates cost a sixth of the turn or more


def test_eval_json_and_sync_modes_carry_the_delivered_motion(
    planted_build: tuple[BlendSpaceDocument, dict[str, object]], capsys: pytest.CaptureFixture[str]
) -> None:
    """`--format json` carries what the text line says; `--sync` changes the rates (and so what is
    delivered); each mode's delivered turn agrees with playing the clips at its rates."""
    _, data = planted_build
    path = str(data["out"] / "planted.blendspace.json")  # type: ignore[operator]
    specs = {s.name: s for s in SAMPLE_SET}
    turns = {}
    for sync in SYNC_MODES:
        capsys.readouterr()
        assert main(["eval", path, "--at", "x=44.5,y=4.0", "--sync", sync, "--format", "json"]) == 0
        result = json.loads(capsys.readouterr().out)
        got = result["delivered"]
        assert got["sync"] == sync
        entries = result["weights"]
        assert set(got["playback_rates"]) == {e["clip"] for e in entries}
        if sync == "normalized":  # the rates eval lists
            assert got["playback_rates"] == {e["clip"]: e["playback_rate"] for e in entries}
        if sync == "none":
            assert set(got["playback_rates"].values()) == {1.0}
        rates = [got["playback_rates"][e["clip"]] for e in entries]
        played = play(
            [_prepared(specs[e["clip"]]) for e in entries],
            [e["weight"] for e in entries],
            rates,
            SETTINGS,
            seconds=12.0,
        )
        assert got["turn_rate"] == pytest.approx(played.turn_rate, rel=0.1)
        assert got["forward_speed"] == pytest.approx(played.forward_speed, rel=0.1)
        [turn_axis] = [a for a in got["axes"] if a["feature"] == "turn_rate"]
        assert turn_axis == {
            "feature": "turn_rate",
            "unit": "deg/s",
            "delivered": got["turn_rate"],
            "asked": 44.5,
        }
        # The text form says the same numbers.
        assert main(["eval", path, "--at", "x=44.5,y=4.0", "--sync", sync]) == 0
        line = next(
            t for t in capsys.readouterr().out.splitlines() if t.startswith("delivered at these rates")
        )
        assert f"turn {got['turn_rate']:.3g} deg/s" in line
        assert (f"(sync {sync})" in line) == (sync != "normalized")
        turns[sync] = got["turn_rate"]
    # At rate 1 the blend turns as placed (about what was asked); syncing slows the turning clip.
    assert turns["none"] == pytest.approx(44.5, rel=0.1)
    assert turns["normalized"] < 0.85 * turns["none"]
    assert len(set(turns.values())) >= 2, turns
    capsys.readouterr()
    assert main(["eval", path, "--at", "x=44.5,y=4.0", "--sync", "phase"]) == 2
    assert "--sync" in capsys.readouterr().err


CADENCES = [
    GaitSpec("walk", speed=1.4, duration=2.0),  # 1.4 m strides
    GaitSpec("run", speed=4.0, duration=1.6, stride_length=2.6),
    GaitSpec("walk_turn", speed=1.4, turn_rate=60.0, duration=3.0),
    GaitSpec("run_turn", speed=3.0, turn_rate=-60.0, duration=1.5, stride_length=1.5),
]


def _cadence_project(folder: Path, blend: str, stem: str) -> Path:
    for spec in CADENCES:
        path = folder / "clips" / f"{spec.name}.usda"
        if not path.exists():
            write_usd_clip(generate_planted(spec), path, meters_per_unit=1.0, up_axis="y")
    manifest = folder / f"{stem}.yaml"
    manifest.write_text(
        "schema_version: 1\nname: cadence\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 18}\n"
        "  y: {feature: speed, min: 0, max: 5, divisions: 50}\n"
        f"output: {{formats: [json]}}\n{blend}"
    )
    return manifest


def test_the_manifest_sync_mode_reaches_the_blend_quality_maps(tmp_path: Path) -> None:
    """Clips of different cadences: each sync mode plays them at different rates, so the build's
    maps differ, and each equals the model run in that mode on the written document."""
    maxima = {}
    for sync in SYNC_MODES:
        manifest = _cadence_project(tmp_path, f"blend:\n  sync: {sync}\n", sync)
        out = tmp_path / f"out_{sync}"
        assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
        text = (out / "cadence.blendspace.json").read_text()
        quality = json.loads(text)["blend_quality"]
        assert quality["sync"] == sync
        model = runtime_grid(BlendSpaceDocument.model_validate_json(text), sync)  # type: ignore[arg-type]
        assert quality["summary"]["trajectory_error_max"] == pytest.approx(model.max_distance, abs=1e-5)
        maxima[sync] = (quality["summary"]["trajectory_error_mean"], quality["summary"]["drift_max"])
    assert len(set(maxima.values())) == 3, maxima
    # Without `blend:` the build plays as the exports set it up: normalized.
    default = tmp_path / "out_default"
    assert main(
        ["build", str(_cadence_project(tmp_path, "", "default")), "--out", str(default), "--no-fix"]
    ) in (0, 1)
    quality = json.loads((default / "cadence.blendspace.json").read_text())["blend_quality"]
    assert quality["sync"] == "normalized"
    assert quality["summary"]["trajectory_error_mean"] == maxima["normalized"][0]


def test_a_bad_sync_mode_is_a_manifest_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _cadence_project(tmp_path, "blend:\n  sync: phase\n", "bad")
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) == 2
    err = capsys.readouterr().err
    line = manifest.read_text().splitlines().index("  sync: phase") + 1
    assert f"{manifest.name}:{line}:" in err and "sync" in err, err
    assert "Traceback" not in err
    assert not (out / "cadence.blendspace.json").exists()


def _mixed_skeleton_project(folder: Path, change: str) -> Path:
    """The tidy set with its turning walks on another skeleton (``change``): every triangle that
    touches them mixes skeletons, the others do not."""
    from conftest import tidy_set

    from blendspace_pipeline.motion.hostile import on_other_skeleton
    from blendspace_pipeline.motion.procedural import generate
    from blendspace_pipeline.writers.bvh import write_bvh_clip

    clips = folder / "clips"
    clips.mkdir(parents=True)
    for name, spec in tidy_set().items():
        clip = generate(spec)
        if name in ("walk_left", "tip_right"):
            clip = on_other_skeleton(clip, change)
        write_bvh_clip(clip, clips / f"{name}.bvh")
    manifest = folder / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: mixed\nclips:\n  - path: clips/*.bvh\n"
        "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 72}\n"
        "  y: {feature: speed, min: -2, max: 2, divisions: 40}\n",
        encoding="utf-8",
    )
    return manifest


@pytest.mark.parametrize("fix", [False, True])
@pytest.mark.parametrize("change", SKELETON_CHANGES)
def test_a_set_that_mixes_skeletons_builds_and_plays_only_same_skeleton_blends(
    change: str, fix: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A blend of clips on different skeletons is not played (no engine blends them; it crashed
    the build with a broadcasting error): `inconsistent-skeleton` says why, and the foot-skate map
    holds the blends of one skeleton."""
    manifest = _mixed_skeleton_project(tmp_path / "p", change)
    out = tmp_path / "out"
    code = main(["build", str(manifest), "--out", str(out), "--jobs", "1", *([] if fix else ["--no-fix"])])
    printed = capsys.readouterr()
    assert code in (0, 1), printed.err
    # Every change is reported (a joint under another parent, or the joints in another order,
    # were not: the rule compared names only), and exactly the two clips on the other skeleton.
    doc = json.loads((out / "mixed.blendspace.json").read_text(encoding="utf-8"))
    reported = {d["clips"][0] for d in doc["diagnostics"] if d["rule"] == "inconsistent-skeleton"}
    assert reported == {"walk_left", "tip_right"}, printed.out
    skate = [v for row in doc["blend_quality"]["foot_skate"] or [] for v in row if v is not None]
    assert skate and all(0.0 <= v < 1.0 for v in skate)  # the one-skeleton triangles were played


def test_real_mocap_beside_procedural_clips_builds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """CMU's 31-joint take in a triangle with two 19-joint procedural clips (a reviewer's first
    draft): exit 3 before; now the build finishes and says the skeletons differ."""
    shared_data("cmu", "131_01.bvh")
    from blendspace_pipeline.motion.procedural import generate
    from blendspace_pipeline.writers.bvh import write_bvh_clip

    for spec in (GaitSpec("idle", duration=2.0), GaitSpec("tip_left", turn_rate=90.0, duration=2.0)):
        write_bvh_clip(generate(spec), tmp_path / f"{spec.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: mix\nclips:\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_01.bvh', range: auto}}\n"
        "  - path: idle.bvh\n  - path: tip_left.bvh\n"
        "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
        "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n",
        encoding="utf-8",
    )
    for fix in ([], ["--no-fix"]):
        out = tmp_path / f"out{len(fix)}"
        code = main(["build", str(manifest), "--out", str(out), *fix])
        printed = capsys.readouterr()
        assert code in (0, 1), printed.err
        assert "internal error" not in printed.err
        assert (out / "mix.blendspace.json").is_file()
