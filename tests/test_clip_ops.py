"""Gait phase, phase-aligned blending and the output contract of every clip operation.

Oracles are procedural clips (period, phase and features known by construction), a procedural
walk re-timed with a known, drifting cadence, and CMU mocap from ../shared/data. The world-space
mirror checks live in test_clip_operations.py; this file adds what the phase alignment and the
generated-clip contract need.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from blendspace_pipeline.motion.clip import Clip, forward_kinematics, validate_clip
from blendspace_pipeline.motion.clip_ops import (
    IncompatibleClips,
    blend_clips,
    mirror_clip,
    phase,
    straighten_clip,
)
from blendspace_pipeline.motion.clip_ops.blend import resample_linear, resample_quaternions
from blendspace_pipeline.motion.clip_ops.phase import detect_cycle, foot_signal, frames_at_phases
from blendspace_pipeline.motion.detect import RigSettings, detect_tpose_frame
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips

SETTINGS = RigSettings()
SPAN = {"speed": 9.0, "turn_rate": 360.0}  # the default axis ranges: 2 % of each is the tolerance
CMU_METRES = 0.0564  # one CMU unit (SOURCES.md); fixed so both takes measure in the same unit


def features(clip: Clip, settings: RigSettings = SETTINGS) -> dict[str, float]:
    return measure(clip, settings).features


# -- gait phase ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("spec", "options", "period", "strides"),
    [
        (GaitSpec("walk", speed=1.3, duration=1.0), {}, 1.0, 1),
        (GaitSpec("run", speed=4.0, duration=1.0, stride_length=2.0), {}, 0.5, 2),
        (GaitSpec("walk60", speed=1.4, turn_rate=60.0, duration=1.5, fps=60.0), {"up": "z"}, 0.75, 2),
        (
            GaitSpec("back", speed=1.1, direction=180.0, duration=2.0, stride_length=0.75),
            {"with_root_joint": True, "root_yaw_offset": 90.0, "meters_per_unit": 0.01},
            2.0 / 3.0,
            3,
        ),
        (
            GaitSpec("strafe", speed=1.2, direction=90.0, duration=1.0, stride_length=1.2, fps=24.0),
            {},
            1.0,
            1,
        ),
    ],
)
def test_gait_cycle_of_procedural_clips(
    spec: GaitSpec, options: dict[str, object], period: float, strides: int
) -> None:
    clip = generate(spec, **options)  # type: ignore[arg-type]
    cycle = detect_cycle(clip, SETTINGS)
    assert cycle is not None
    assert cycle.period == pytest.approx(period, rel=0.01)
    assert cycle.cycles == pytest.approx(strides, abs=0.02)
    # Phase 0 is the left foot passing the right going forward: the generator's phase 0.
    times = np.arange(clip.frame_count) / clip.fps
    assert np.abs(cycle.phase - times / period).max() < 0.02
    assert not cycle.open_loop


def test_an_open_loop_is_recognised_and_wraps_across_its_seam() -> None:
    closed = generate(GaitSpec("walk", speed=1.3, duration=1.0))
    open_loop = closed.trimmed(0, closed.frame_count - 1)  # last frame leads into the first
    cycle = detect_cycle(open_loop, SETTINGS)
    assert cycle is not None and cycle.open_loop
    assert cycle.period == pytest.approx(1.0, rel=0.005) and cycle.cycles == pytest.approx(1.0, abs=0.01)
    # Phase 0.99 lies between the last frame (29) and the first one again (30 == 0).
    assert 29.0 < float(frames_at_phases(cycle, np.array([0.99]))[0]) < 30.0
    # Phase 1.25 is a quarter stride in, like 0.25.
    at = frames_at_phases(cycle, np.array([0.25, 1.25, -0.75]))
    assert np.allclose(at, at[0])


@pytest.mark.parametrize(
    ("spec", "frames"),
    [
        (GaitSpec("idle", duration=2.0), None),
        (GaitSpec("turn_in_place", turn_rate=90.0, duration=2.0), None),
        (GaitSpec("half_a_stride", speed=1.3, duration=1.0), (0, 16)),
        (GaitSpec("two_thirds", speed=1.3, duration=1.0), (3, 23)),
    ],
)
def test_no_gait_cycle_without_a_stride(spec: GaitSpec, frames: tuple[int, int] | None) -> None:
    clip = generate(spec)
    assert detect_cycle(clip.trimmed(*frames) if frames else clip, SETTINGS) is None


def retimed(clip: Clip, warp: Callable[[np.ndarray], np.ndarray]) -> Clip:
    """``clip`` played back at a drifting rate: output frame k shows source time warp(u_k)."""
    u = np.linspace(0.0, 1.0, clip.frame_count)
    at = warp(u) * (clip.frame_count - 1)
    return Clip(
        clip.name,
        clip.source,
        clip.skeleton,
        resample_quaternions(clip.rotations, at),
        resample_linear(clip.translations, at),
        clip.fps,
        clip.meters_per_unit,
        clip.up_axis,
    )


def test_phase_follows_a_drifting_cadence() -> None:
    """A 3-stride walk re-timed so its cadence swings +-35 %: the phase must follow the strides
    themselves, not a constant rate (which would be off by about 0.17 stride)."""
    source = generate(GaitSpec("walk", speed=1.3, duration=3.0, fps=120.0))
    amount = 0.35

    def warp(u: np.ndarray) -> np.ndarray:
        return np.asarray(u + amount * np.sin(2.0 * np.pi * u) / (2.0 * np.pi))

    clip = retimed(source, warp)
    cycle = detect_cycle(clip, SETTINGS)
    assert cycle is not None
    truth = 3.0 * warp(np.linspace(0.0, 1.0, clip.frame_count))
    linear_error = np.abs(truth - np.linspace(0.0, 3.0, clip.frame_count)).max()
    assert linear_error > 0.15
    assert np.abs(cycle.phase - truth).max() < 0.03
    assert (np.diff(cycle.phase) > 0).all()
    # Cut out of the loop (no seam to lean on), phase still follows within the crossings; only
    # the stride count is arbitrary, so compare modulo whole strides.
    cut = detect_cycle(clip.trimmed(30, 320), SETTINGS)
    assert cut is not None
    error = (cut.phase - truth[30:320] + 0.5) % 1.0 - 0.5
    assert np.abs(error).max() < 0.1


def test_cmu_walk_has_a_gait_cycle() -> None:
    clip = read_clips(shared_data("cmu", "131_02.bvh"))[0].trimmed(300, 700)
    cycle = detect_cycle(clip, SETTINGS)
    assert cycle is not None and cycle.feet == ("LeftAnkle", "RightAnkle")
    # About one stride per second (measured by hand from the ankle signal's zero crossings).
    assert 0.8 < cycle.period < 1.1 and cycle.cycles > 3


def test_stride_grid_fit_equals_the_direct_fit() -> None:
    """The chirp-z grid fit is the same least-squares R^2 as fitting each frequency on its own."""
    rng = np.random.default_rng(3)
    for _ in range(10):
        count, fps = int(rng.integers(40, 2000)), 30.0
        times = np.arange(count) / fps
        noise = rng.normal(0.0, rng.uniform(0.0, 1.0), count)
        signal = np.sin(2.0 * np.pi * rng.uniform(0.3, 3.0) * times + 1.0) + noise + rng.uniform(-1, 1)
        duration = (count - 1) / fps
        low, step = 0.95 / duration, 0.02 / duration
        grid = np.arange(low, 4.0 + step, step)
        direct = phase._sinusoid_fit(signal, times, grid)
        fast = phase._sinusoid_fit_grid(signal, low / fps, step / fps, len(grid))
        assert np.abs(direct - fast).max() < 1e-9


def test_stride_frequency_of_a_long_open_take() -> None:
    """Two minutes at 120 fps of a walk that does not loop (cut mid-stride): the period comes from
    the grid fit and the crossings, and must be the generator's cadence (1.3 m strides at 1.5 m/s)."""
    clip = generate(GaitSpec("walk", speed=1.5, duration=130.0, fps=120.0)).trimmed(37, 120 * 120 + 37)
    cycle = detect_cycle(clip, SETTINGS)
    assert cycle is not None and cycle.loop_strides == 0
    truth = 130.0 / round(1.5 * 130.0 / 1.3)
    assert cycle.period == pytest.approx(truth, rel=2e-3)
    frequency, fit = phase._stride_frequency(foot_signal(clip, SETTINGS)[0], clip.fps)  # type: ignore[index]
    assert frequency == pytest.approx(1.0 / truth, rel=2e-3) and fit > 0.9


def test_stride_frequency_of_a_real_take_is_unchanged() -> None:
    """On a real walk, the fast grid finds the same frequency as the direct grid it replaces."""
    clip = read_clips(shared_data("cmu", "131_02.bvh"))[0]
    signal = foot_signal(clip, SETTINGS)[0]  # type: ignore[index]
    fps = clip.fps
    thin = max(1, int(fps // 30))
    duration = (len(signal) - 1) / fps
    low, step = 0.95 / duration, 0.02 / duration
    grid = np.arange(low, min(4.0, fps / 4.0) + step, step)
    direct = phase._sinusoid_fit(signal[::thin], np.arange(len(signal))[::thin] / fps, grid)
    frequency, _ = phase._stride_frequency(signal, fps)
    assert abs(frequency - grid[int(np.argmax(direct))]) <= step


# -- blending -------------------------------------------------------------------------------------


def want_features(specs: list[GaitSpec], weights: list[float]) -> dict[str, float]:
    return {
        "speed": sum(w * s.signed_speed for w, s in zip(weights, specs, strict=True)),
        "turn_rate": sum(w * s.turn_rate for w, s in zip(weights, specs, strict=True)),
    }


BLEND_CASES = [
    # The oracles: 1 + 3 m/s -> 2 m/s; turn in place 90 + idle -> 45; walk + turn in place.
    ([GaitSpec("slow", speed=1.0), GaitSpec("fast", speed=3.0)], [0.5, 0.5], {}),
    ([GaitSpec("tip", turn_rate=90.0, duration=2.0), GaitSpec("idle", duration=2.0)], [0.5, 0.5], {}),
    (
        [GaitSpec("walk", speed=1.4), GaitSpec("tip", turn_rate=90.0, duration=2.0, fps=24.0)],
        [0.5, 0.5],
        {},
    ),
    # Different durations, frame rates and stride counts, turning both ways.
    (
        [
            GaitSpec("walk_l", speed=1.4, turn_rate=40.0, duration=1.5, fps=60.0),
            GaitSpec("run_r", speed=4.0, turn_rate=-70.0, duration=0.8, stride_length=2.6, fps=24.0),
        ],
        [0.3, 0.7],
        {},
    ),
    # Three clips; a Z-up rig in centimetres with a turned root joint.
    (
        [
            GaitSpec("walk", speed=1.4, duration=1.0),
            GaitSpec("strafe", speed=1.2, direction=60.0, turn_rate=20.0, duration=2.0, stride_length=1.2),
            GaitSpec("run", speed=3.5, turn_rate=-30.0, duration=1.2, stride_length=2.1),
        ],
        [0.2, 0.3, 0.5],
        {"up": "z", "meters_per_unit": 0.01, "with_root_joint": True, "root_yaw_offset": 90.0},
    ),
    ([GaitSpec("back", speed=1.1, direction=180.0), GaitSpec("fwd", speed=1.4)], [0.8, 0.2], {}),
]


@pytest.mark.parametrize(("specs", "weights", "options"), BLEND_CASES)
def test_blend_measures_the_weighted_speed_and_turn_rate(
    specs: list[GaitSpec], weights: list[float], options: dict[str, object]
) -> None:
    clips = [generate(spec, **options) for spec in specs]  # type: ignore[arg-type]
    blended = blend_clips(clips, weights, name="mix", settings=SETTINGS)
    got = features(blended)
    for feature, want in want_features(specs, weights).items():
        assert abs(got[feature] - want) <= 0.02 * SPAN[feature], (feature, got[feature], want)


def test_blend_of_cmu_takes_measures_the_weighted_features() -> None:
    settings = RigSettings(units=CMU_METRES)
    a = read_clips(shared_data("cmu", "131_01.bvh"))[0].trimmed(240, 480)
    b = read_clips(shared_data("cmu", "131_02.bvh"))[0].trimmed(300, 700)
    blended = blend_clips([a, b], [0.3, 0.7], name="mix", settings=settings)
    fa, fb, got = features(a, settings), features(b, settings), features(blended, settings)
    for feature in ("speed", "turn_rate", "forward_speed", "lateral_speed"):
        want = 0.3 * fa[feature] + 0.7 * fb[feature]
        span = SPAN.get(feature, SPAN["speed"])
        assert abs(got[feature] - want) <= 0.02 * span, (feature, got[feature], want)
    assert "gait phase" in blended.notes[0]


def stride_swing(clip: Clip) -> float:
    """Peak-to-peak of the left-minus-right foot distance along the facing (file units)."""
    found = foot_signal(clip, SETTINGS)
    assert found is not None
    return float(np.ptp(found[0]))


def test_blend_keeps_walks_with_different_cadences_in_step() -> None:
    """One stride in 1 s blended with two strides in 1.6 s: played by normalised time the legs
    would swing against each other; aligned by phase the stride is the weighted one and the
    feet swing as far as in the sources."""
    one = generate(GaitSpec("one", speed=1.3, duration=1.0, stride_length=1.3))
    two = generate(GaitSpec("two", speed=1.3, duration=1.6, stride_length=1.04))
    blended = blend_clips([one, two], [0.5, 0.5], name="mix", settings=SETTINGS)
    cycle = detect_cycle(blended, SETTINGS)
    assert cycle is not None
    assert cycle.period == pytest.approx(0.5 * 1.0 + 0.5 * 0.8, rel=0.02)
    assert cycle.cycles == pytest.approx(round(cycle.cycles), abs=0.02)  # whole strides: it loops
    assert stride_swing(blended) > 0.95 * min(stride_swing(one), stride_swing(two))
    assert features(blended)["speed"] == pytest.approx(1.3, rel=0.02)


def test_blend_leaves_out_a_rest_pose_first_frame() -> None:
    specs = [GaitSpec("walk", speed=1.4, start_heading=70.0), GaitSpec("run", speed=3.0, stride_length=2.0)]
    clips = [generate(spec, tpose_first_frame=True) for spec in specs]
    blended = blend_clips(clips, [0.5, 0.5], name="mix", settings=SETTINGS)
    assert not detect_tpose_frame(blended, forward_kinematics(blended)[1], SETTINGS)
    assert features(blended)["speed"] == pytest.approx(2.2, rel=0.02)


def test_blend_refuses_clips_with_different_up_axes() -> None:
    y_up = generate(GaitSpec("a", speed=1.0))
    z_up = generate(GaitSpec("b", speed=1.0), up="z")
    with pytest.raises(IncompatibleClips, match="up axes"):
        blend_clips([y_up, z_up], [0.5, 0.5], name="x", settings=SETTINGS)


@pytest.mark.parametrize("weights", [[0.5], [1.0, -0.5], [0.0, 0.0], [float("nan"), 1.0]])
def test_blend_refuses_bad_weights(weights: list[float]) -> None:
    clips = [generate(GaitSpec("a", speed=1.0)), generate(GaitSpec("b", speed=2.0))]
    with pytest.raises(ValueError):
        blend_clips(clips, weights, name="x", settings=SETTINGS)


# -- the contract every generated clip keeps ------------------------------------------------------


def _blend(clip: Clip) -> Clip:
    other = generate(
        GaitSpec("run", speed=3.5, turn_rate=20.0, stride_length=2.1), up="z", meters_per_unit=0.01
    )
    return blend_clips([clip, other], [0.4, 0.6], name="made", settings=SETTINGS)


def _mirror(clip: Clip) -> Clip:
    return mirror_clip(clip, settings=SETTINGS, name="made")


def _straighten(clip: Clip) -> Clip:
    return straighten_clip(clip, settings=SETTINGS, name="made")


@pytest.mark.parametrize("operation", [_blend, _mirror, _straighten], ids=["blend", "mirror", "straighten"])
def test_generated_clips_keep_the_source_contract(operation: Callable[[Clip], Clip]) -> None:
    source = generate(
        GaitSpec("walk", speed=1.4, turn_rate=12.0, duration=1.5, fps=60.0), up="z", meters_per_unit=0.01
    )
    before = (source.rotations.copy(), source.translations.copy())
    made = validate_clip(operation(source))
    assert made.name == "made" and made.skeleton.same_layout(source.skeleton)
    assert (made.fps, made.meters_per_unit, made.up_axis) == (60.0, 0.01, "z")
    assert made.notes and source.name in made.notes[0]
    assert np.allclose(np.linalg.norm(made.rotations, axis=-1), 1.0)
    # The source is untouched and the operation is deterministic to the bit.
    assert np.array_equal(source.rotations, before[0]) and np.array_equal(source.translations, before[1])
    again = operation(source)
    assert np.array_equal(made.rotations, again.rotations)
    assert np.array_equal(made.translations, again.translations)


def test_mirroring_twice_gives_the_source_back() -> None:
    source = generate(
        GaitSpec("walk", speed=1.4, turn_rate=30.0, direction=20.0, start_heading=40.0),
        with_root_joint=True,
        root_yaw_offset=90.0,
    )
    twice = mirror_clip(mirror_clip(source, settings=SETTINGS, name="m"), settings=SETTINGS, name="mm")
    assert np.abs(forward_kinematics(twice)[1] - forward_kinematics(source)[1]).max() < 1e-6


@pytest.mark.parametrize("options", [{}, {"up": "z", "with_root_joint": True, "root_yaw_offset": 90.0}])
def test_straighten_on_other_rigs_and_after_a_rest_pose_frame(options: dict[str, object]) -> None:
    spec = GaitSpec("walk", speed=1.4, turn_rate=-8.0, duration=2.0, start_heading=70.0)
    source = generate(spec, tpose_first_frame=True, **options)  # type: ignore[arg-type]
    straight = features(straighten_clip(source, settings=SETTINGS, name="s"))
    assert abs(straight["turn"]) < 0.5
    assert straight["speed"] == pytest.approx(features(source)["speed"], rel=0.02)


# -- a picture to look at --------------------------------------------------------------------------


def render_stick_figures(clips: list[Clip], path: Path, frames: int = 6) -> np.ndarray:
    """Side-by-side panels, one per clip: a few frames as stick figures seen from the side (the
    clip's travel to the right, up up, the ground at the bottom), so a person can check the
    poses. Colours alternate red/blue and darken with time."""
    oiio = pytest.importorskip("OpenImageIO")
    panel, height = 360, 240
    image = oiio.ImageBuf(oiio.ImageSpec(panel * len(clips), height, 3, oiio.FLOAT))
    oiio.ImageBufAlgo.fill(image, (1.0, 1.0, 1.0))
    for index, clip in enumerate(clips):
        _, world = forward_kinematics(clip)
        scale = (clip.meters_per_unit or 1.0) * 100.0  # pixels per file unit
        up = np.array([0.0, 0.0, 1.0]) if clip.up_axis == "z" else np.array([0.0, 1.0, 0.0])
        hips = forward_kinematics(clip)[1][:, clip.skeleton.index("Hips")]
        travel = hips[-1] - hips[0]
        forward = travel - (travel @ up) * up
        norm = np.linalg.norm(forward)
        forward = forward / norm if norm > 1e-9 else np.cross(up, [1.0, 0.0, 0.0])
        for step, frame in enumerate(np.linspace(0, clip.frame_count - 1, frames).round().astype(int)):
            shade = 0.7 * (1.0 - step / max(frames - 1, 1))
            colour = (shade, shade, 1.0) if step % 2 else (1.0, shade, shade)
            for joint, parent in enumerate(clip.skeleton.parents):
                if parent < 0:
                    continue
                ends = [world[frame, j] - hips[0] + (hips[0] @ up) * up for j in (joint, parent)]
                xs = [int(index * panel + 40 + scale * float(p @ forward)) for p in ends]
                ys = [int(height - 30 - scale * float(p @ up)) for p in ends]
                oiio.ImageBufAlgo.render_line(image, xs[0], ys[0], xs[1], ys[1], colour)
    assert image.write(str(path))
    return np.asarray(image.get_pixels(oiio.FLOAT))


def test_stick_figure_render_of_blended_and_mirrored_clips(tmp_path: Path) -> None:
    slow = generate(GaitSpec("slow", speed=1.0, duration=1.0, stride_length=1.0))
    fast = generate(GaitSpec("fast", speed=2.2, duration=1.2, stride_length=1.32))
    blended = blend_clips([slow, fast], [0.5, 0.5], name="blend", settings=SETTINGS)
    mirrored = mirror_clip(blended, settings=SETTINGS, name="mirror")
    pixels = render_stick_figures([slow, fast, blended, mirrored], tmp_path / "clip_ops_stick_figures.png")
    panels = np.split(pixels, 4, axis=1)
    assert all((p < 0.9).any() for p in panels)  # every panel has a figure in it


def test_a_blend_led_by_its_second_clip_of_the_same_length() -> None:
    """The main clip was looked up by value among the cycles (arrays): a blend whose second clip
    weighs more, both of one length, stopped the build (exit 3)."""
    from blendspace_pipeline.motion.procedural import generate_planted

    back = generate_planted(GaitSpec("back", speed=1.1, direction=180.0, duration=2.0, stride_length=1.1))
    forward = generate_planted(GaitSpec("fwd", speed=1.4, duration=2.0))
    assert back.frame_count == forward.frame_count
    blended = blend_clips([back, forward], [0.3, 0.7], name="m", settings=RigSettings())
    assert blended.frame_count > 2


@pytest.mark.parametrize("idle_fps", [24.0, 120.0])
def test_a_blend_runs_at_the_rate_of_its_moving_sources(idle_fps: float) -> None:
    """A still idle's rate is arbitrary (a glTF's two keys tell none): first in the list it set a
    blend with a 30 fps walk to 24 fps; the finest rate of all would let it set 120."""
    from blendspace_pipeline.motion.hostile import still_pose

    walk = generate(GaitSpec("walk", speed=0.8, duration=2.0, stride_length=0.9, fps=30.0))
    idle = still_pose(generate(GaitSpec("idle", duration=2.0, fps=idle_fps)), round(2 * idle_fps))
    blended = blend_clips([idle, walk], [0.5, 0.5], name="m", settings=RigSettings())
    assert blended.fps == 30.0
