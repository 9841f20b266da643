"""The fix loop end to end: generated clips are real, land where they were placed, and the loop is
deterministic and idempotent. Ground truth comes from procedural clips."""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.fix_loop import mirrored_name
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

# A first-draft set: left turns only, so mirroring and axis clips have work to do.
DRAFT = (
    GaitSpec("idle", duration=2.0),
    GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, stride_length=1.1),
    GaitSpec("walk_turn_left", speed=1.4, turn_rate=50.0, duration=1.5),
    GaitSpec("walk_turn_right", speed=1.4, turn_rate=-50.0, duration=1.5),
    GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0),
)
# The straight gaits and left turns only (walking, running, on the spot): mirrors to make.
LEFT_TURNS = (
    GaitSpec("idle", duration=2.0),
    GaitSpec("walk_fwd", speed=1.4, duration=2.0),
    GaitSpec("run_fwd", speed=4.0, duration=1.6, stride_length=2.6),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, stride_length=1.1, duration=2.0),
    GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0),
    GaitSpec("walk_turn_left", speed=1.4, turn_rate=50.0, duration=2.0),
    GaitSpec("run_turn_left", speed=4.0, turn_rate=60.0, duration=1.6, stride_length=2.6),
)
# With a slow walk on the speed axis: the axis clip at the left/right turns' crossing (1.4 m/s)
# is a blend of two gaits (slow walk, run). Between the idle and the run it plants no foot.
WITH_SLOW_WALK = (*DRAFT, GaitSpec("walk_slow", speed=0.5, duration=1.8, stride_length=0.9))
AXES = "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"
RANGES = (360.0, 9.0)


def _project(tmp_path: Path, specs: tuple[GaitSpec, ...] = DRAFT, extra: str = "") -> Path:
    folder = tmp_path / "clips"
    folder.mkdir(parents=True, exist_ok=True)
    for spec in specs:
        write_usd_clip(generate(spec), folder / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: loco\nclips:\n  - path: clips/*.usda\n"
        "    ignore: [{rule: in-place-clip, reason: idle}]\n" + AXES + extra
    )
    return manifest


def _bvh_project(folder: Path, specs: Sequence[GaitSpec], manifest: str, **options: bool) -> Path:
    """``specs`` generated (with ``options``) as BVH files in ``folder``, and the manifest text
    ``manifest`` beside the folder; returns the manifest's path."""
    folder.mkdir(parents=True, exist_ok=True)
    for spec in specs:
        write_bvh_clip(generate(spec, **options), folder / f"{spec.name}.bvh")  # type: ignore[arg-type]
    path = folder.parent / "manifest.yaml"
    path.write_text(manifest)
    return path


def _build(manifest: Path, out: Path, *args: str) -> dict[str, object]:
    code = main(["build", str(manifest), "--out", str(out), "--format", "json", *args])
    assert code in (0, 1)
    return json.loads((out / "loco.blendspace.json").read_text())  # type: ignore[no-any-return]


def _tree(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _crossing_edges(doc: dict[str, object], tau: float = 5.0) -> list[tuple[str, str]]:
    """Independent check: triangle edges crossing x = 0 or y = 0 with both ends beyond tau."""
    samples = doc["samples"]  # type: ignore[index]
    normal = [((s["position"][0] + 180) / 3.6, (s["position"][1] + 3) / 0.09) for s in samples]  # type: ignore[index]
    lines = (50.0, 3 / 0.09)
    found = []
    for tri in doc["triangles"]:  # type: ignore[attr-defined]
        for i in range(3):
            a, b = tri[i], tri[(i + 1) % 3]
            for k in (0, 1):
                da, db = normal[a][k] - lines[k], normal[b][k] - lines[k]
                if da * db < 0 and min(abs(da), abs(db)) > tau:
                    found.append((samples[a]["name"], samples[b]["name"]))  # type: ignore[index]
    return found


def test_mirrored_names() -> None:
    assert mirrored_name("walk_turn_left") == "walk_turn_right"
    assert mirrored_name("TurnRight90") == "TurnLeft90"
    assert mirrored_name("strafe_l") == "strafe_r"
    assert mirrored_name("idle") == "idle_mirror"


def test_fixes_fill_the_set_and_no_edge_crosses_a_main_axis(tmp_path: Path) -> None:
    manifest = _project(tmp_path, WITH_SLOW_WALK)
    before = _tree(tmp_path / "clips")
    doc = _build(manifest, tmp_path / "out")
    generated = {s["name"]: s for s in doc["samples"] if s["generated"]}  # type: ignore[attr-defined]
    assert "turn_in_place_right" in generated
    assert generated["turn_in_place_right"]["fix"] == "missing-opposite"
    assert generated["turn_in_place_right"]["features"]["turn_rate"] == pytest.approx(-90.0, abs=0.02 * 360)
    assert _crossing_edges(doc) == []
    assert not [d for d in doc["diagnostics"] if d["rule"] == "crossing-axis"]  # type: ignore[attr-defined]
    # Every generated clip is on disk, as UsdSkel, and referenced by the JSON.
    for name, sample in generated.items():
        path = (tmp_path / "out" / sample["source"]).resolve()
        assert path == (tmp_path / "out" / "clips" / f"{name}.usda").resolve() and path.is_file()
    assert _tree(tmp_path / "clips") == before  # sources untouched


def test_a_generated_clip_measures_where_it_was_placed_on_its_own(tmp_path: Path) -> None:
    doc = _build(_project(tmp_path, WITH_SLOW_WALK), tmp_path / "out")
    made = [s for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert any(s["fix"] == "crossing-axis" for s in made), "expected an interpolated axis clip"
    for sample in made:
        clip = read_clips(tmp_path / "out" / sample["source"])[0]
        features = measure(clip, RigSettings()).features
        for axis, feature, span in ((0, "turn_rate", RANGES[0]), (1, "speed", RANGES[1])):
            assert abs(features[feature] - sample["position"][axis]) <= 0.02 * span, (
                sample["name"],
                feature,
                features[feature],
                sample["position"],
            )


def test_no_fix_and_check_generate_nothing(tmp_path: Path) -> None:
    manifest = _project(tmp_path)
    doc = _build(manifest, tmp_path / "out", "--no-fix")
    assert not [s for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert not (tmp_path / "out" / "clips").exists()
    listing = sorted(p.name for p in tmp_path.iterdir())
    assert main(["check", str(manifest)]) == 1  # crossing-axis errors are reported, not fixed
    assert sorted(p.name for p in tmp_path.iterdir()) == listing


def test_builds_are_byte_identical_and_idempotent(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)  # the default must be reproducible
    manifest = _project(tmp_path)
    _build(manifest, tmp_path / "a")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    _build(manifest, tmp_path / "b")
    assert _tree(tmp_path / "a") == _tree(tmp_path / "b")

    # Feeding the generated clips back as sources makes nothing new.
    shutil.copytree(tmp_path / "a" / "clips", tmp_path / "clips", dirs_exist_ok=True)
    again = _build(manifest, tmp_path / "c")
    assert not [s for s in again["samples"] if s["generated"]]  # type: ignore[attr-defined]


def test_a_fix_no_better_until_a_later_fix_is_tried_again_so_the_next_build_adds_nothing(
    tmp_path: Path,
) -> None:
    """The mirror of the running left turn does not improve the space before the turn in place is
    mirrored, and does after: each fix was tried once, so the next build, with the
    generated clips fed back, added them. A fix not kept is tried again after a later one is kept,
    and said once."""
    manifest = _project(tmp_path, LEFT_TURNS, "fixes: {mirror: true, axis_clips: true}\n")
    first = _build(manifest, tmp_path / "a")
    made = {s["name"] for s in first["samples"] if s["generated"]}  # type: ignore[attr-defined]
    assert {"turn_in_place_right", "run_turn_right"} <= made, made  # the second one was the next build's
    verdicts = [
        (d["rule"], tuple(d["clips"]), tuple(d["position"]) if d["position"] else None)
        for d in first["diagnostics"]  # type: ignore[attr-defined]
        if d["rule"] in ("fix-rejected", "fix-skipped")
    ]
    assert len(verdicts) == len({(clips, position) for _, clips, position in verdicts}), verdicts
    # Rejected at first, kept after the turn in place: no verdict stays on it.
    assert ("fix-rejected", ("run_turn_left",), None) not in verdicts, verdicts
    shutil.copytree(tmp_path / "a" / "clips", tmp_path / "clips", dirs_exist_ok=True)
    again = _build(manifest, tmp_path / "b")
    assert not [s for s in again["samples"] if s["generated"]]  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("specs", "fixes"),
    [
        # The two turning walks are too close and off the axes: merged.
        (
            (
                *DRAFT,
                GaitSpec("walk_turn_a", speed=1.4, turn_rate=25.0),
                GaitSpec("walk_turn_b", speed=1.5, turn_rate=28.0),
            ),
            "fixes: {too_close: merge, straighten: true}\n",
        ),
        # walk_fwd turns 4 deg/s: straightened.
        ((*DRAFT, GaitSpec("walk_fwd", speed=1.4, turn_rate=4.0)), "fixes: {straighten: true}\n"),
    ],
    ids=["merge", "straighten"],
)
def test_merge_and_straighten_are_idempotent(tmp_path: Path, specs: tuple[GaitSpec, ...], fixes: str) -> None:
    """A merged or straightened clip fed back beside its originals is recognised, not made again."""
    manifest = _project(tmp_path, specs, fixes)
    first = _build(manifest, tmp_path / "a")
    made = {s["name"] for s in first["samples"] if s["generated"]}  # type: ignore[attr-defined]
    assert made, "the set is meant to need fixes"
    shutil.copytree(tmp_path / "a" / "clips", tmp_path / "clips", dirs_exist_ok=True)
    again = _build(manifest, tmp_path / "c")
    assert not [s for s in again["samples"] if s["generated"]]  # type: ignore[attr-defined]
    names = {s["name"] for s in again["samples"]}  # type: ignore[attr-defined]
    assert names == {s["name"] for s in first["samples"]}  # type: ignore[attr-defined]


def test_too_close_keep_representative_and_merge(tmp_path: Path) -> None:
    # Off the main axes and inside the hull: neither is a key clip, so too-close may act on them.
    specs = (
        *DRAFT,
        GaitSpec("walk_fwd", speed=1.4, turn_rate=25.0),
        GaitSpec("walk_relaxed", speed=1.5, turn_rate=28.0, stride_length=1.4),
    )
    keep = _build(
        _project(tmp_path / "k", specs, "fixes: {too_close: keep-representative}\n"), tmp_path / "k1"
    )
    names = {s["name"] for s in keep["samples"]}  # type: ignore[attr-defined]
    assert ("walk_fwd" in names) != ("walk_relaxed" in names)
    assert any(d["rule"] == "fix-removed" for d in keep["diagnostics"])  # type: ignore[attr-defined]

    merged = _build(_project(tmp_path / "m", specs, "fixes: {too_close: merge}\n"), tmp_path / "m1")
    by_name = {s["name"]: s for s in merged["samples"]}  # type: ignore[attr-defined]
    assert "walk_fwd" not in by_name and "walk_relaxed" not in by_name
    merge = next(s for s in by_name.values() if s["fix"] == "too-close")
    assert merge["features"]["speed"] == pytest.approx(1.45, abs=0.02 * RANGES[1])


def test_straighten_replaces_a_slightly_turning_clip(tmp_path: Path) -> None:
    specs = (*DRAFT, GaitSpec("walk_fwd", speed=1.4, turn_rate=4.0))
    doc = _build(_project(tmp_path, specs, "fixes: {straighten: true}\n"), tmp_path / "out")
    straight = next(s for s in doc["samples"] if s["fix"] == "misalignment")  # type: ignore[attr-defined]
    assert abs(straight["features"]["turn_rate"]) < 0.5
    assert straight["features"]["speed"] == pytest.approx(1.4, rel=0.02)
    assert straight["position"][0] == 0.0


def test_generated_clip_plays_the_same_motion_in_usd(tmp_path: Path) -> None:
    doc = _build(_project(tmp_path), tmp_path / "out")
    sample = next(s for s in doc["samples"] if s["name"] == "turn_in_place_right")  # type: ignore[attr-defined]
    clip = read_clips(tmp_path / "out" / sample["source"])[0]
    source = generate(GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0))
    assert clip.frame_count == source.frame_count and clip.fps == source.fps
    assert np.isfinite(clip.rotations).all()


def test_bvh_sources_get_bvh_generated_clips_with_the_same_motion(tmp_path: Path) -> None:
    from blendspace_pipeline.motion.clip import forward_kinematics

    folder = tmp_path / "clips"
    manifest = _bvh_project(
        folder,
        DRAFT,
        "schema_version: 1\nname: loco\nskeleton: {units: m}\nclips:\n  - path: clips/*.bvh\n" + AXES,
    )
    doc = _build(manifest, tmp_path / "out")
    made = [s["name"] for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made
    for name in made:
        usd = read_clips(tmp_path / "out" / "clips" / f"{name}.usda")[0]
        bvh_path = tmp_path / "out" / "clips" / f"{name}.bvh"
        bvh = read_clips(bvh_path)[0]
        # Same hierarchy and channel layout as the sources, and the same motion in both files.
        source_header = (folder / "idle.bvh").read_text().split("MOTION")[0]
        assert bvh_path.read_text().split("MOTION")[0] == source_header
        assert np.abs(forward_kinematics(usd)[1] - forward_kinematics(bvh)[1]).max() < 1e-3


def test_a_fix_from_a_minus_y_up_source_is_skipped_not_a_crash(tmp_path: Path) -> None:
    """Measurement reads any up axis (issue 10); the clip operations make +Y/+Z up clips only, so
    a fix whose source is upside down (-Y up) is a `fix-skipped` finding, never an exit 3."""
    from blendspace_pipeline.motion import quaternions as quat
    from blendspace_pipeline.writers.bvh import write_bvh_clip

    folder = tmp_path / "clips"
    folder.mkdir()
    flip = np.array([1.0, 0.0, 0.0, 0.0])  # 180 degrees about X: +Y up becomes -Y up
    for spec in (
        GaitSpec("walk_left", speed=1.4, turn_rate=40.0, duration=2.0),
        GaitSpec("idle", duration=2.0),
    ):
        clip = generate(spec)
        rotations, translations = clip.rotations.copy(), clip.translations.copy()
        rotations[:, 0] = quat.multiply(np.broadcast_to(flip, rotations[:, 0].shape), rotations[:, 0])
        translations[:, 0] = translations[:, 0] * np.array([1.0, -1.0, -1.0])
        upside_down = type(clip)(
            name=clip.name,
            source=clip.source,
            skeleton=clip.skeleton,
            rotations=rotations,
            translations=translations,
            fps=clip.fps,
        )
        write_bvh_clip(upside_down, folder / f"{spec.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: loco\nskeleton: {units: m}\nclips:\n  - path: clips/*.bvh\n" + AXES
    )
    doc = _build(manifest, tmp_path / "out")
    walk = next(s for s in doc["samples"] if s["name"] == "walk_left")  # type: ignore[attr-defined]
    assert walk["clip"]["up_axis"] == "-y"
    assert walk["features"]["turn_rate"] == pytest.approx(40.0, abs=1.0)
    skipped = [d for d in doc["diagnostics"] if d["rule"] == "fix-skipped"]  # type: ignore[attr-defined]
    assert any("-y-up" in d["message"] for d in skipped), skipped


def test_an_axis_clip_blocked_by_a_sample_near_the_crossing_says_which_and_how_far(tmp_path: Path) -> None:
    """The crossing edge's own end 6.7 (normalised) from the crossing point, within too_close
    (8): the fix is skipped, and the finding names that sample, its distance and the ways out
    (it said only "a sample already sits within too_close")."""
    specs = (
        GaitSpec("idle", duration=2.0),
        GaitSpec("walk_fwd", speed=1.4),
        GaitSpec("walk_bwd", speed=1.1, direction=180.0, stride_length=1.1),
        GaitSpec("turn_in_place_left", turn_rate=150.0, duration=2.0),
        GaitSpec("turn_in_place_right", turn_rate=-150.0, duration=2.0),
        GaitSpec("slow_turn_left", speed=0.6, turn_rate=60.0, duration=1.5, stride_length=1.2),
        GaitSpec(
            "slow_bwd_turn_left", speed=1.0, direction=180.0, turn_rate=60.0, duration=1.5, stride_length=1.2
        ),
    )
    doc = _build(_project(tmp_path, specs, "fixes: {mirror: false}\n"), tmp_path / "out")
    [skipped] = [d for d in doc["diagnostics"] if d["rule"] == "fix-skipped"]  # type: ignore[attr-defined]
    assert skipped["message"].startswith("crossing-axis fix not applied: slow_turn_left sits 6.")
    assert "within too_close (8)" in skipped["message"]
    assert "lower thresholds.too_close below 6." in skipped["hint"]


def test_a_mirror_is_of_the_merged_clip_not_of_a_take_the_merge_removed(tmp_path: Path) -> None:
    specs = (
        GaitSpec("idle", duration=2.0),
        GaitSpec("walk_fwd", speed=1.4),
        GaitSpec("run_fwd", speed=4.0, duration=1.0, stride_length=2.0),
        GaitSpec("walk_bwd", speed=1.1, direction=180.0, stride_length=1.1),
        GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0),
        GaitSpec("turn_in_place_right", turn_rate=-90.0, duration=2.0),
        GaitSpec("walk_turn_left", speed=1.4, turn_rate=150.0, duration=1.2, stride_length=1.68),
        GaitSpec("run_turn_left", speed=4.0, turn_rate=150.0, duration=1.2, stride_length=2.4),
        GaitSpec("mid_a", speed=2.5, turn_rate=80.0, duration=1.0, stride_length=2.5),
        GaitSpec("mid_b", speed=2.6, turn_rate=86.0, duration=1.0, stride_length=2.6),
    )
    fixes = "fixes: {mirror: true, axis_clips: true, too_close: merge}\n"
    doc = _build(_project(tmp_path, specs, fixes), tmp_path / "out")
    made = {s["name"]: s for s in doc["samples"] if s["generated"]}  # type: ignore[attr-defined]
    assert "merged_mid_a_mid_b" in made
    mirrors = [s for s in made.values() if s["fix"] == "missing-opposite"]
    assert "merged_mid_a_mid_b_mirror" in [s["name"] for s in mirrors]
    assert not [s for s in mirrors if s["name"].startswith(("mid_a", "mid_b"))]
    merged, mirror = made["merged_mid_a_mid_b"]["position"], made["merged_mid_a_mid_b_mirror"]["position"]
    assert mirror == [-merged[0], merged[1]]


def test_an_axis_clip_that_plants_no_foot_is_not_baked(tmp_path: Path) -> None:
    """Between the idle and the run (no slow walk on the axis) the interpolated clip's feet never
    touch the floor (18-42 cm up, the body tilted 28 deg) while its root motion reads right: it
    was baked without a word. Now the fix is rejected and says why; the crossing stays reported."""
    doc = _build(_project(tmp_path), tmp_path / "out")
    assert not [s for s in doc["samples"] if s["fix"] == "crossing-axis"]  # type: ignore[attr-defined]
    rejected = [d["message"] for d in doc["diagnostics"] if d["rule"] == "fix-rejected"]  # type: ignore[attr-defined]
    assert any("never plants a foot where idle and run_fwd do" in m for m in rejected), rejected
    assert _crossing_edges(doc)


def test_a_straightened_bvh_with_root_motion_on_a_root_joint_is_written(tmp_path: Path) -> None:
    """The sources carry the trajectory on a `Root` joint and their Hips have no position channels:
    the straightened clip moves the Hips, which the source's layout cannot hold (exit 3). It is
    written in its own layout, and reads back as made."""
    specs = (*DRAFT, GaitSpec("walk_fwd", speed=1.4, turn_rate=4.0, duration=2.0))
    manifest = _bvh_project(
        tmp_path / "clips",
        specs,
        "schema_version: 1\nname: loco\nclips:\n  - path: clips/*.bvh\n"
        "    ignore: [{rule: in-place-clip, reason: idle}]\n" + AXES + "fixes: {straighten: true}\n",
        with_root_joint=True,
    )
    doc = _build(manifest, tmp_path / "out")
    made = {s["name"]: s for s in doc["samples"] if s["generated"]}  # type: ignore[attr-defined]
    assert "walk_fwd_straight" in made, sorted(made)
    written = read_clips(tmp_path / "out" / "clips" / "walk_fwd_straight.bvh")[0]
    features = measure(written, RigSettings()).features
    assert features["turn_rate"] == pytest.approx(0.0, abs=0.5)
    assert features["speed"] == pytest.approx(made["walk_fwd_straight"]["features"]["speed"], abs=0.01)


def test_findings_left_when_the_fix_attempts_run_out_say_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The loop stops at `MAX_ATTEMPTS`: the findings no fix was tried on said nothing (and the
    next build, with the clips made fed back, made more)."""
    from blendspace_pipeline.pipeline import fix_loop

    monkeypatch.setattr(fix_loop, "MAX_ATTEMPTS", 1)
    doc = _build(_project(tmp_path, LEFT_TURNS, "fixes: {mirror: true}\n"), tmp_path / "out")
    made = [s["name"] for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    untried = [
        d
        for d in doc["diagnostics"]  # type: ignore[attr-defined]
        if d["rule"] == "fix-skipped" and "not tried: the build tries at most 1 fixes" in d["message"]
    ]
    assert len(made) <= 1 and untried, (made, [d["message"] for d in doc["diagnostics"]])  # type: ignore[attr-defined]


def test_a_corner_the_mirrors_move_inside_stays_a_key_clip_in_the_next_build(tmp_path: Path) -> None:
    """walk_c is a corner of the authored set, so the merge with walk_b is refused. The mirrors the
    build adds widen the hull; fed back as sources, they made walk_c an inner clip, and the next
    build merged it away. Key clips are of the authored set: the clips an earlier build made are
    left out of its hull."""
    specs = (
        GaitSpec("idle", duration=2.0),
        GaitSpec("walk", speed=1.4, duration=2.0),
        GaitSpec("walk_b", speed=1.45, turn_rate=31.0, duration=2.0),
        GaitSpec("walk_c", speed=1.40, turn_rate=29.0, duration=2.0),
        GaitSpec("run", speed=4.0, duration=1.6, stride_length=2.6),
        GaitSpec("run_l", speed=4.0, turn_rate=60.0, duration=1.6, stride_length=2.6),
        GaitSpec("strafe", speed=1.2, turn_rate=-60.0, duration=2.0),
    )
    folder = tmp_path / "clips"
    manifest = _bvh_project(
        folder,
        specs,
        "schema_version: 1\nname: loco\nclips:\n  - path: clips/*.bvh\n"
        "    ignore: [{rule: in-place-clip, reason: idle}]\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 36}\n"
        "  y: {feature: speed, min: 0, max: 5, divisions: 50}\n"
        "fixes: {mirror: true, axis_clips: true, too_close: merge}\n",
    )
    first = _build(manifest, tmp_path / "a")
    made = [s["name"] for s in first["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made and "merged_walk_b_walk_c" not in made, made
    for name in made:
        shutil.copy(tmp_path / "a" / "clips" / f"{name}.bvh", folder)
    again = _build(manifest, tmp_path / "b")
    assert not [s["name"] for s in again["samples"] if s["generated"]]  # type: ignore[attr-defined]
