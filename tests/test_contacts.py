"""Foot contacts: oracle tests on planted procedural gaits, end to end on the real clips."""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, shared_data
from pxr import Usd

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts, contact_joints
from blendspace_pipeline.motion.clip_ops.phase import detect_cycle
from blendspace_pipeline.motion.contacts import FootContacts, detect_contacts, plant_phases, sync_markers
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.hostile import in_place
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate, generate_planted, planted_truth
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.usd_clip import write_usd_clip

SETTINGS = RigSettings()
GAITS = [
    GaitSpec("walk", speed=1.4, duration=2.0),
    GaitSpec("run", speed=4.0, duration=1.6, stride_length=2.6),
    GaitSpec("walk_turn", speed=1.4, turn_rate=60.0, duration=3.0),
    GaitSpec("strafe", speed=1.2, direction=90.0, duration=2.0, stride_length=1.0),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, duration=2.0, stride_length=1.1),
    GaitSpec("turn_in_place", turn_rate=90.0, duration=2.0),
]


def _spans_match(
    found: list[tuple[float, float]], truth: list[tuple[float, float]], tolerance: float
) -> None:
    assert len(found) == len(truth), (found, truth)
    for (a, b), (ta, tb) in zip(found, truth, strict=True):
        assert a == pytest.approx(ta, abs=tolerance) and b == pytest.approx(tb, abs=tolerance)


@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
def test_planted_generator_keeps_feet_still_and_bones_rigid(spec: GaitSpec) -> None:
    clip = generate_planted(spec)
    truth = planted_truth(spec)
    _, positions = forward_kinematics(clip)
    names = clip.skeleton.names
    times = np.arange(clip.frame_count) / clip.fps
    contacts = FootContacts(truth.contacts["left"], truth.contacts["right"], clip.duration)
    for foot, side in (("left", "Left"), ("right", "Right")):
        planted = contacts.mask(foot, times)
        for joint in (f"{side}Foot", f"{side}Toe"):
            track = positions[:, names.index(joint)]
            steady = planted[1:] & planted[:-1]
            assert np.abs(np.diff(track, axis=0)[steady]).max() < 1e-9  # not a millimetre of slide
        assert positions[planted, names.index(f"{side}Toe"), 1] == pytest.approx(0.0, abs=1e-9)
        assert positions[~planted, names.index(f"{side}Foot"), 1].max() > 0.1  # the swing lifts it
    # Only rotations changed: every bone keeps its rest length on every frame.
    for joint, parent in enumerate(clip.skeleton.parents):
        if parent >= 0:
            lengths = np.linalg.norm(positions[:, joint] - positions[:, parent], axis=1)
            assert lengths == pytest.approx(np.linalg.norm(clip.skeleton.rest_translations[joint]), abs=1e-9)


def test_planted_generator_measures_what_its_spec_says() -> None:
    spec = GaitSpec("walk_turn", speed=1.4, turn_rate=60.0, duration=3.0)
    features = measure(generate_planted(spec), SETTINGS).features
    assert features["speed"] == pytest.approx(1.4, rel=0.02)
    assert features["turn_rate"] == pytest.approx(60.0, rel=0.02)


def test_the_cosmetic_generator_is_unchanged() -> None:
    # Existing clips (the sample project, goldens) come from `generate`: planting is opt-in.
    spec = GaitSpec("walk", speed=1.4)
    assert generate(spec).rotations[5, 2] == pytest.approx(generate(spec).rotations[5, 2])
    assert not np.allclose(generate(spec).rotations, generate_planted(spec).rotations)


@pytest.mark.parametrize("spec", GAITS, ids=lambda s: s.name)
@pytest.mark.parametrize(("up", "meters_per_unit"), [("y", 1.0), ("z", 0.01)])
def test_contacts_match_the_planted_truth(spec: GaitSpec, up: str, meters_per_unit: float) -> None:
    clip = generate_planted(spec, up=up, meters_per_unit=meters_per_unit)
    truth = planted_truth(spec)
    _, positions = forward_kinematics(clip)
    found = clip_contacts(clip, SETTINGS, positions, meters_per_unit=meters_per_unit, up_axis=up)
    assert found is not None
    for foot in ("left", "right"):
        # Within two frames: a foot touches down between frames.
        _spans_match(found.of(foot), truth.contacts[foot], 2.0 / clip.fps)
        assert found.duty(foot) == pytest.approx(
            sum(b - a for a, b in truth.contacts[foot]) / clip.duration, abs=0.08
        )


@pytest.mark.parametrize("spec", GAITS[:3], ids=lambda s: s.name)
def test_plant_phases_match_the_planted_truth(spec: GaitSpec) -> None:
    clip = generate_planted(spec)
    truth = planted_truth(spec)
    cycle = detect_cycle(clip, SETTINGS)
    assert cycle is not None
    found = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    assert found is not None
    phases = plant_phases(found, cycle.phase, clip.fps)
    assert phases is not None
    for foot in ("left", "right"):
        assert phases[foot] == pytest.approx(truth.plant_phase[foot], abs=0.06)


def test_contacts_survive_mocap_noise() -> None:
    spec = GaitSpec("walk", speed=1.4, duration=3.0, fps=120.0)
    clip = generate_planted(spec)
    truth = planted_truth(spec)
    _, positions = forward_kinematics(clip)
    noisy = positions + np.random.default_rng(7).normal(0.0, 0.003, positions.shape)  # 3 mm jitter
    found = detect_contacts(
        noisy, contact_joints(clip, SETTINGS), fps=120.0, meters_per_unit=1.0, up_axis="y"
    )  # type: ignore[arg-type]
    for foot in ("left", "right"):
        _spans_match(found.of(foot), truth.contacts[foot], 0.05)


def test_standing_feet_never_leave_the_ground() -> None:
    clip = generate_planted(GaitSpec("idle", duration=2.0))
    found = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    assert found is not None and found.left == [(0.0, 2.0)] and found.right == [(0.0, 2.0)]
    assert sync_markers(found) == []


def test_sync_markers_are_foot_down_events_in_time_order() -> None:
    contacts = FootContacts([(0.0, 0.3), (0.7, 1.3)], [(0.2, 0.8), (1.2, 1.5)], 1.5)
    assert sync_markers(contacts) == [(0.2, "RightFootDown"), (0.7, "LeftFootDown"), (1.2, "RightFootDown")]


def test_build_writes_contacts_to_json_and_usd(tmp_path: Path) -> None:
    specs = [
        GaitSpec("walk", speed=1.4, duration=2.0),
        GaitSpec("run", speed=4.0, duration=1.6, stride_length=2.6),
    ]
    for spec in specs:
        write_usd_clip(
            generate_planted(spec), tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: feet\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 18}\n"
        "  y: {feature: speed, min: 0, max: 5, divisions: 50}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    doc = json.loads((out / "feet.blendspace.json").read_text())
    stage = Usd.Stage.Open(str(out / "feet.blendspace.usda"))
    for spec in specs:
        [sample] = [s for s in doc["samples"] if s["name"] == spec.name]
        truth = planted_truth(spec)
        prim = stage.GetDefaultPrim().GetChild("Samples").GetChild(spec.name)
        for foot in ("left", "right"):
            spans = [tuple(s) for s in sample["contacts"][foot]]
            _spans_match(spans, truth.contacts[foot], 2.0 / spec.fps)  # type: ignore[arg-type]
            written = np.array(prim.GetAttribute(f"blendspace:contacts:{foot}").Get())
            assert written == pytest.approx(np.array(spans))
        for foot, phase in sample["clip"]["plant_phases"].items():
            assert phase == pytest.approx(truth.plant_phase[foot], abs=0.06)
        # Sync markers: the foot-down times of the planted truth (contacts under way at frame 0
        # are not events), sorted by time, in the JSON and in the USD asset.
        expected = sorted(
            (start, name)
            for foot, name in (("left", "LeftFootDown"), ("right", "RightFootDown"))
            for start, _ in truth.contacts[foot]
            if start > 0.0
        )
        markers = sample["markers"]
        assert [m["name"] for m in markers] == [name for _, name in expected], (markers, expected)
        assert [m["time"] for m in markers] == pytest.approx([t for t, _ in expected], abs=2.0 / spec.fps)
        assert [m["time"] for m in markers] == sorted(m["time"] for m in markers)
        assert len(markers) >= 2
        assert list(prim.GetAttribute("blendspace:markers:names").Get()) == [m["name"] for m in markers]
        assert list(prim.GetAttribute("blendspace:markers:times").Get()) == pytest.approx(
            [m["time"] for m in markers]
        )
    report = (out / "feet.report.html").read_text()
    assert report.count('class="contacts-strip"') == len(specs)


def test_cmu_walks_alternate_their_feet(tmp_path: Path) -> None:
    """131_02's steady walk (frames 300-700, 3.3 s): both feet step, alternately, each contact
    with the foot nearly still; the same intervals whatever unit the file is read in."""
    clip = read_clips(shared_data("cmu", "131_02.bvh"))[0].trimmed(300, 700)
    m = measure(clip, SETTINGS)
    positions = forward_kinematics(clip)[1]
    found = clip_contacts(clip, SETTINGS, positions, meters_per_unit=m.meters_per_unit, up_axis=m.up_axis)
    assert found is not None
    for foot in ("left", "right"):
        assert len(found.of(foot)) >= 3  # a step at least every 1.1 s
        assert 0.35 < found.duty(foot) < 0.9  # walking: planted more than half the time, never always
    downs = [name for _, name in sync_markers(found)]
    alternating = sum(a != b for a, b in itertools.pairwise(downs))
    assert alternating >= 0.7 * (len(downs) - 1)
    # A planted foot barely moves: the slower of ankle and toe (the heel lifts before the toe
    # does) has a median ground speed under 0.15 m/s during contacts.
    joints = contact_joints(clip, SETTINGS)[0]  # type: ignore[index]
    times = np.arange(clip.frame_count) / clip.fps
    speeds = [
        np.linalg.norm(np.diff(positions[:, j][:, [0, 2]], axis=0), axis=1) * clip.fps * m.meters_per_unit
        for j in joints
    ]
    assert float(np.median(np.minimum(*speeds)[found.mask("left", times)[1:]])) < 0.15
    # Unit-aware: the same take scaled to centimetres gives the same contacts.
    scaled = detect_contacts(
        positions * 10.0,
        contact_joints(clip, SETTINGS),
        fps=clip.fps,
        meters_per_unit=m.meters_per_unit / 10.0,
        up_axis=m.up_axis,  # type: ignore[arg-type]
    )
    assert np.array(scaled.left) == pytest.approx(np.array(found.left))
    assert np.array(scaled.right) == pytest.approx(np.array(found.right))


def test_real_data_build_carries_contacts_where_legs_are_known(tmp_path: Path) -> None:
    shared_data("cmu", "131_02.bvh")
    shared_data("godot-tps-demo", "SOURCES.md")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: real\nclips:\n"
        f"  - {{path: '{SHARED_DATA.as_posix()}/cmu/131_02.bvh', range: [2.5, 5.8]}}\n"
        f"  - path: '{SHARED_DATA.as_posix()}/godot-tps-demo/walking_nogun-cycle.tres'\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 18}\n"
        "  y: {feature: speed, min: -5, max: 5, divisions: 50}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json", "--no-fix"]) in (0, 1)
    doc = json.loads(next(out.glob("*.blendspace.json")).read_text())
    by_source = {Path(s["source"]).name: s for s in doc["samples"]}
    cmu = by_source["131_02.bvh"]
    assert len(cmu["contacts"]["left"]) >= 3 and len(cmu["contacts"]["right"]) >= 3
    assert all(0.0 <= a < b <= cmu["features"]["duration"] + 1e-3 for a, b in cmu["contacts"]["left"]), cmu
    # Godot Animation resources carry tracks without the hierarchy: no feet to put down.
    assert by_source["walking_nogun-cycle.tres"].get("contacts") is None


def _stairs(rise: float, tread: float) -> Callable[[np.ndarray], np.ndarray]:
    """Steps of ``rise`` metres, ``tread`` deep, centred on multiples of ``tread`` (the 0.6 m stride
    of `ON_SLOPES`'s climb plants each foot on every other tread's middle)."""
    return lambda z: rise * np.floor(z / tread + 0.5)


# Ground that is not flat: slopes up and down, stairs up and down (its height at each world Z).
GROUNDS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "slope 8%": lambda z: 0.08 * z,
    "slope 25%": lambda z: 0.25 * z,
    "down 30%": lambda z: -0.3 * z,
    # Up then down: the body's height has no trend over the take, the ground under the feet does.
    "hill": lambda z: 0.3 - 0.3 * np.abs(z - 1.2) / 1.2,
    "stairs 17 cm": _stairs(0.17, 0.3),
    "stairs down 15 cm": _stairs(-0.15, 0.3),
}
ON_SLOPES = [
    GaitSpec("walk", speed=1.4, duration=3.0, stride_length=1.4, fps=30.0),
    GaitSpec("run", speed=3.5, duration=2.0, stride_length=2.8, fps=60.0),
    GaitSpec("climb", speed=0.6, duration=3.0, stride_length=0.6, fps=120.0),
]


# Stairs only at the climb's 0.6 m stride (a 1.4 m stride skips steps).
ON_GROUNDS = [(s, g) for s in ON_SLOPES for g in GROUNDS if "stairs" not in g or s.name == "climb"]


@pytest.mark.parametrize(("spec", "ground"), ON_GROUNDS, ids=[f"{s.name}-{g}" for s, g in ON_GROUNDS])
def test_contacts_on_slopes_and_stairs_match_the_planted_truth(spec: GaitSpec, ground: str) -> None:
    """The floor was one height for the whole take (its 5th percentile): on a slope or stairs
    only the plants at the bottom were near it, and every later one was lost (and the plant
    phases with them), without a word. Each foot's floor is now the ground under it."""
    clip = generate_planted(spec, ground=GROUNDS[ground])
    truth = planted_truth(spec)
    found = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    assert found is not None
    for foot in ("left", "right"):
        # A slow foot leaves the floor slowly: on flat ground the 0.6 m/s walk's contacts end
        # 0.02 s after the truth's lift-off too. On stairs the swing rises to the next step
        # from its first frame (it leaves the floor 0.04 s before the truth's end of stance),
        # and down them it drops onto the step below (it lands 0.06 s after the truth's).
        tolerance = 0.08 if "stairs" in ground else max(2.0 / clip.fps, 0.03)
        _spans_match(found.of(foot), truth.contacts[foot], tolerance)


@pytest.mark.parametrize("spec", [g for g in GAITS if g.speed > 0.0], ids=lambda s: s.name)
def test_contacts_of_an_in_place_clip_match_its_root_motion_clip(spec: GaitSpec) -> None:
    """An in-place clip (Mixamo's "In Place", a treadmill take) slides each planted foot back under
    the body at the walk's speed: no frame was slow enough for a contact, so it had none and no
    sync markers. Its contacts are the root-motion clip's."""
    clip = in_place(generate_planted(spec))
    truth = planted_truth(spec)
    found = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    assert found is not None
    for foot in ("left", "right"):
        _spans_match(found.of(foot), truth.contacts[foot], 2.0 / clip.fps)


@pytest.mark.parametrize("fps", [120.0, 240.0])
def test_contacts_of_an_in_place_clip_at_a_high_rate_match_its_root_motion_clip(fps: float) -> None:
    """The belt is sampled at most 60 times a second (a 300 s take at 240 fps had cost 5 s and
    484 MB); the contacts are still the root-motion clip's."""
    spec = GaitSpec("walk", speed=1.4, duration=3.0, fps=fps)
    clip = in_place(generate_planted(spec))
    found = clip_contacts(clip, SETTINGS, forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y")
    assert found is not None
    for foot in ("left", "right"):
        _spans_match(found.of(foot), planted_truth(spec).contacts[foot], 0.03)
