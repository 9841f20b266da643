"""Pose blending: a new clip whose motion is the weighted mix of two or more clips.

Clips are first put in step. Clips with a gait (see `phase`) are aligned by stride phase, the
way an engine syncs a blend space: the result takes the weighted stride period and the whole
number of strides nearest the weighted duration, so it loops, and every walking clip is sampled
at the same point of its stride (left foot passing right together), not at the same fraction of
its length; clips without a gait (idle, turning on the spot) are stretched over the result.
Without any gait, clips align in normalised time over the weighted duration.
Poses blend joint by joint (rotations by successive slerp, the n-way form of a weighted
quaternion mean, shortest arc; translations linearly); root motion blends as per-step
velocities in the character's own frame and yaw rates, then integrates. The blended velocity and
yaw rate are finally shifted so their means are exactly the weighted means of the sources
(sampling by phase weights a stride's fast and slow parts a little differently than time does),
so the result measures the weighted speed, direction and turn rate whatever the clips' lengths.
This is what an engine's blend space does at runtime, baked into a clip.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts, contact_joints
from blendspace_pipeline.motion.clip_ops.phase import GaitCycle, detect_cycle, frames_at_phases
from blendspace_pipeline.motion.clip_ops.root_motion import compose, decompose, integrate, step_velocities
from blendspace_pipeline.motion.contacts import FEET, BoolArray, plant_phases
from blendspace_pipeline.motion.detect import (
    RigSettings,
    motion_part,
    resolve_root,
    resolve_units,
    resolve_up,
    still_joints,
)
from blendspace_pipeline.motion.ik import solve_leg
from blendspace_pipeline.motion.quaternions import FloatArray


def check_compatible(clips: Sequence[Clip]) -> None:
    first = clips[0]
    for other in clips[1:]:
        if not first.skeleton.same_layout(other.skeleton):
            raise IncompatibleClips(
                f"{first.name} and {other.name} have different skeletons "
                f"({first.skeleton.joint_count} vs {other.skeleton.joint_count} joints or another hierarchy)"
            )
        units = (first.meters_per_unit, other.meters_per_unit)
        if None not in units and abs(units[0] - units[1]) > 1e-6 * max(units):  # type: ignore[operator,type-var]
            raise IncompatibleClips(
                f"{first.name} and {other.name} use different units ({units[0]} vs {units[1]})"
            )
    for clip in clips:
        if clip.frame_count < 2:
            raise IncompatibleClips(f"{clip.name} has {clip.frame_count} frame(s): no motion to blend")


def measured_part(clip: Clip, settings: RigSettings, *, rest: bool = True, held: bool = True) -> Clip:
    """The clip without keys held at either end and without a leading rest/T-pose frame, decided
    as `measure` decides them, so a generated clip (and a played blend) is made of exactly the
    motion its sources were measured on. ``clip`` is cut to its entry's `range:` already; pass that
    range's `measure.part_options` (a stated range keeps its held keys)."""
    part = motion_part(clip, forward_kinematics(clip)[1], settings, rest=rest, held=held)
    return clip if (part.first, part.stop) == (0, clip.frame_count) else clip.trimmed(part.first, part.stop)


def _sample_frames(
    count: int, positions: FloatArray, wrap: bool = False
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Neighbouring frames and fractions for fractional frame ``positions``; with ``wrap``,
    position ``count`` is frame 0 again (an open loop's seam)."""
    last = count - 1
    if wrap:
        clipped = np.clip(positions, 0.0, float(count) - 1e-9)
        lower = np.floor(clipped).astype(int)
        return lower, (lower + 1) % count, clipped - lower
    clipped = np.clip(positions, 0.0, last)
    lower = np.minimum(np.floor(clipped).astype(int), max(last - 1, 0))
    upper = np.minimum(lower + 1, last)
    return lower, upper, clipped - lower


def resample_quaternions(values: FloatArray, positions: FloatArray, wrap: bool = False) -> FloatArray:
    lower, upper, t = _sample_frames(len(values), positions, wrap)
    return quat.slerp(values[lower], values[upper], t[:, None])


def resample_linear(values: FloatArray, positions: FloatArray, wrap: bool = False) -> FloatArray:
    lower, upper, t = _sample_frames(len(values), positions, wrap)
    shape = (len(t),) + (1,) * (values.ndim - 1)
    mixed: FloatArray = values[lower] * (1.0 - t.reshape(shape)) + values[upper] * t.reshape(shape)
    return mixed


def weighted_sum(arrays: Sequence[FloatArray], weights: Sequence[float]) -> FloatArray:
    total = np.zeros_like(arrays[0])
    for array, weight in zip(arrays, weights, strict=True):
        total += weight * array
    return total


def weighted_slerp(quaternions: Sequence[FloatArray], weights: Sequence[float]) -> FloatArray:
    """Successive slerp: q = slerp(acc, q_i, w_i / (w_0 + ... + w_i)); exact for two clips."""
    result = quaternions[0]
    total = weights[0]
    for q, w in zip(quaternions[1:], weights[1:], strict=True):
        total += w
        if w > 0.0:
            result = quat.slerp(result, q, w / total)
    return quat.normalize(result)


@dataclass
class Timing:
    """Where each source clip is sampled for every frame (and every step) of the blend."""

    frames: int
    poses: list[FloatArray]  # per clip: fractional source frame for each output frame
    steps: list[FloatArray]  # per clip: fractional source step for each output step
    wraps: list[bool]  # per clip: position frame_count means frame 0 (an open loop)
    description: str
    loops: bool = False  # the result holds whole strides: its last frame should be its first


def align(clips: Sequence[Clip], weights: Sequence[float], fps: float, settings: RigSettings) -> Timing:
    """Put the clips in step: by stride phase when any has a gait, else by normalised time."""
    cycles: list[GaitCycle | None] = [detect_cycle(clip, settings) for clip in clips]
    walking = [
        (w, c, i) for i, (w, c) in enumerate(zip(weights, cycles, strict=True)) if c is not None and w > 0.0
    ]
    duration = float(sum(w * clip.duration for w, clip in zip(weights, clips, strict=True)))
    if not walking:
        frames = max(2, round(duration * fps) + 1)
        along = np.linspace(0.0, 1.0, frames)
        mid = (np.arange(frames - 1) + 0.5) / (frames - 1)
        return Timing(
            frames,
            [along * (c.frame_count - 1) for c in clips],
            [mid * (c.frame_count - 1) - 0.5 for c in clips],
            [False] * len(clips),
            "aligned in normalised time (no gait found)",
        )
    share = sum(w for w, _, _ in walking)
    period = sum(w * c.period for w, c, _ in walking) / share
    strides = max(1, int(np.floor(duration / period + 0.5)))
    frames = max(2, round(strides * period * fps) + 1)
    # The result starts where its main clip starts. By position: cycles hold arrays, and
    # `list.index` compared two clips' cycles by value (an error when the weights favoured the second).
    _, lead, lead_index = max(walking, key=lambda entry: entry[0])
    start = float(lead.phase[0])
    offsets = plant_offsets(clips, cycles, lead_index, settings)
    along = np.linspace(0.0, 1.0, frames)
    mid = (np.arange(frames - 1) + 0.5) / (frames - 1)
    poses, steps, wraps = [], [], []
    for index, (clip, cycle) in enumerate(zip(clips, cycles, strict=True)):
        if cycle is None:
            poses.append(along * (clip.frame_count - 1))
            steps.append(mid * (clip.frame_count - 1) - 0.5)
            wraps.append(False)
        else:
            shift = offsets[index] if offsets is not None else 0.0
            poses.append(frames_at_phases(cycle, start + strides * along - shift))
            steps.append(frames_at_phases(cycle, start + strides * mid - shift) - 0.5)
            wraps.append(cycle.open_loop)
    periods = ", ".join(f"{c.period:.3g} s" for c in cycles if c is not None)
    return Timing(
        frames,
        poses,
        steps,
        wraps,
        f"aligned by gait phase (strides of {periods} -> {strides} x {period:.3g} s)",
        loops=True,
    )


# Largest phase shift (strides) contact alignment may apply: more means the contacts disagree
# so much (a crossed or odd gait) that the swing alignment is the safer choice.
_MAX_PLANT_SHIFT = 0.2


def plant_offsets(
    clips: Sequence[Clip], cycles: Sequence[GaitCycle | None], lead: int, settings: RigSettings
) -> list[float] | None:
    """Per clip, the stride phase by which to delay it so its feet land when the lead clip's do
    (engines' marker sync: foot-down events, not only the legs' swing, line up). 0 for clips
    without a gait or contacts; None when the lead has no plant phases."""
    phases: list[dict[str, float] | None] = []
    for clip, cycle in zip(clips, cycles, strict=True):
        if cycle is None:
            phases.append(None)
            continue
        positions = forward_kinematics(clip)[1]
        up, _ = resolve_up(clip, positions, settings)
        unit = _unit_of(clip, settings, up)
        contacts = clip_contacts(clip, settings, positions, meters_per_unit=unit, up_axis=up)
        phases.append(plant_phases(contacts, cycle.phase, clip.fps) if contacts is not None else None)
    reference = phases[lead]
    if reference is None:
        return None
    offsets = []
    for own in phases:
        if own is None:
            offsets.append(0.0)
            continue
        # Circular mean of the per-foot differences, in (-0.5, 0.5].
        angles = [2.0 * np.pi * (reference[f] - own[f]) for f in FEET]
        shift = float(np.arctan2(np.mean(np.sin(angles)), np.mean(np.cos(angles)))) / (2.0 * np.pi)
        offsets.append(shift if abs(shift) <= _MAX_PLANT_SHIFT else 0.0)
    return offsets


def blend_clips(
    clips: Sequence[Clip], weights: Sequence[float], *, name: str, settings: RigSettings, plant: bool = True
) -> Clip:
    """The weighted blend of ``clips`` (weights >= 0, normalised to sum to 1).

    Raises `IncompatibleClips` when the clips cannot share poses (other skeleton, units or up
    axis): the caller falls back to a placeholder.
    """
    if len(clips) != len(weights) or not clips:
        raise ValueError("one weight per clip")
    w = np.asarray(weights, dtype=np.float64)
    if not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise ValueError("weights must be finite, >= 0 and not all 0")
    w = w / w.sum()
    check_compatible(clips)
    sources = [measured_part(clip, settings) for clip in clips]
    motions = [decompose(clip, settings) for clip in sources]
    if len({m.up_axis for m in motions}) > 1:
        raise IncompatibleClips(
            f"{clips[0].name} and the other clips have different up axes "
            f"({', '.join(sorted({m.up_axis.upper() for m in motions}))})"
        )
    weights_list = [float(x) for x in w]
    # The finest rate of the sources that move and weigh: a still idle's rate is arbitrary (a
    # glTF's two keys tell none), and first in the list it made a blend with a 30 fps walk run at 24.
    weighed = [clip for clip, weight in zip(sources, weights_list, strict=True) if weight > 0.0]
    moving = [clip for clip in weighed if len(still_joints(clip)) < clip.skeleton.joint_count]
    fps = max(clip.fps for clip in moving or weighed)
    timing = align(sources, weights_list, fps, settings)

    rotations, translations, rel_rot, rel_pos, velocities, yaw_rates = [], [], [], [], [], []
    mean_velocity, mean_yaw_rate = [], []
    for clip, motion, at, steps_at, wrap in zip(
        sources, motions, timing.poses, timing.steps, timing.wraps, strict=True
    ):
        rotations.append(resample_quaternions(clip.rotations, at, wrap))
        translations.append(resample_linear(clip.translations, at, wrap))
        rel_rot.append(resample_quaternions(motion.rel_rotations, at, wrap))
        rel_pos.append(resample_linear(motion.rel_positions, at, wrap))
        velocity, yaw_rate = step_velocities(motion.heading, motion.ground, clip.fps)
        velocities.append(resample_linear(velocity, steps_at))
        yaw_rates.append(resample_linear(yaw_rate, steps_at))
        mean_velocity.append(velocity.mean(axis=0))
        mean_yaw_rate.append(yaw_rate.mean(keepdims=True))

    motion = motions[0]
    motion.rel_rotations = weighted_slerp(rel_rot, weights_list)
    motion.rel_positions = weighted_sum(rel_pos, weights_list)
    velocity = weighted_sum(velocities, weights_list)
    yaw_rate = weighted_sum(yaw_rates, weights_list)
    velocity += weighted_sum(mean_velocity, weights_list) - velocity.mean(axis=0)
    yaw_rate += weighted_sum(mean_yaw_rate, weights_list) - yaw_rate.mean()
    heading, ground = integrate(velocity, yaw_rate, fps, float(motion.heading[0]), motion.ground[0])
    pose = weighted_slerp(rotations, weights_list)
    if timing.loops:
        # Strides of mocap differ: wrapping a source by whole strides lands on a slightly other
        # pose, so the last frame misses the first by a centimetre or two. Spread that over
        # the clip (root joints in the character frame, every other joint locally).
        pose = _spread_seam(pose)
        motion.rel_rotations = _spread_seam(motion.rel_rotations)
        motion.rel_positions = motion.rel_positions + np.linspace(0.0, 1.0, timing.frames)[:, None, None] * (
            motion.rel_positions[0] - motion.rel_positions[-1]
        )
    parts = " + ".join(f"{wi:.3f} x {c.name}" for wi, c in zip(weights_list, clips, strict=True))
    blended = compose(
        clips[0],
        motion,
        heading,
        ground,
        pose,
        weighted_sum(translations, weights_list),
        name=name,
        fps=fps,
        note=f"blend of {parts}, {timing.description}; root velocities blended in the character frame",
    )
    if not plant:
        return blended
    trajectory = (
        (quat.from_axis_angle(motion.up, heading), motion.trajectory_points(ground)) if timing.loops else None
    )
    planted = replant(blended, sources, weights_list, timing, settings, motion.up_axis, trajectory)
    if planted is not blended:
        planted.notes[0] += "; feet re-planted during contacts (two-bone IK)"
    return planted


# Frames over which a pinned foot eases in and out of its plant (seconds).
_PLANT_EASE = 0.1


def _unit_of(clip: Clip, settings: RigSettings, up_axis: str) -> float:
    if clip.meters_per_unit is not None:
        return clip.meters_per_unit
    positions = forward_kinematics(clip)[1]
    return resolve_units(clip, positions, settings, up_axis, resolve_root(clip, settings, positions))[0]


def contact_vote(
    sources: Sequence[Clip], weights: Sequence[float], timing: Timing, settings: RigSettings, up_axis: str
) -> dict[str, FloatArray] | None:
    """Per foot, the weighted share of the sources planted at each frame of the blend."""
    vote = {foot: np.zeros(timing.frames) for foot in FEET}
    for clip, weight, at in zip(sources, weights, timing.poses, strict=True):
        unit = _unit_of(clip, settings, up_axis)
        contacts = clip_contacts(
            clip, settings, forward_kinematics(clip)[1], meters_per_unit=unit, up_axis=up_axis
        )
        if contacts is None:
            return None
        for foot in FEET:
            vote[foot] += weight * contacts.mask(foot, np.mod(at, clip.frame_count) / clip.fps)
    return vote


def replant(
    clip: Clip,
    sources: Sequence[Clip],
    weights: Sequence[float],
    timing: Timing,
    settings: RigSettings,
    up_axis: str,
    trajectory: tuple[FloatArray, FloatArray] | None = None,
) -> Clip:
    """``clip`` with each foot held still on the ground while the sources (by weighted vote)
    have it planted: the ankle keeps its blended height but not its slide (two-bone IK on
    hip, knee, ankle; bone lengths untouched), easing in and out over `_PLANT_EASE`; then the
    legs' loop seam, if the IK opened one, is spread over the clip so the loop stays closed."""
    vote = contact_vote(sources, weights, timing, settings, up_axis)
    joints = contact_joints(clip, settings)
    if vote is None or joints is None:
        return clip
    # A foot the blend itself puts down (low and slow) is planted too, even where the sources'
    # vote is split: otherwise it slides at the speed the blend gives it.
    own = clip_contacts(
        clip,
        settings,
        forward_kinematics(clip)[1],
        meters_per_unit=_unit_of(clip, settings, up_axis),
        up_axis=up_axis,
    )
    times = np.arange(clip.frame_count) / clip.fps
    skeleton = clip.skeleton
    up = 2 if up_axis == "z" else 1
    ground = [axis for axis in range(3) if axis != up]
    positions = forward_kinematics(clip)[1]
    ease = max(1, round(_PLANT_EASE * clip.fps))
    result = clip
    legs: list[int] = []
    for foot, chain in zip(FEET, joints, strict=True):
        ankle = chain[0]
        knee = skeleton.parents[ankle]
        hip = skeleton.parents[knee] if knee >= 0 else -1
        if hip < 0:
            continue
        legs += [hip, knee, ankle]
        down = vote[foot] >= 0.5
        if own is not None:
            down |= own.mask(foot, times)
        targets = positions[:, ankle].copy()
        blend = np.zeros(clip.frame_count)
        runs = _runs(down)
        pins = [positions[a : b + 1, ankle].mean(axis=0) for a, b in runs]
        last = clip.frame_count - 1
        if trajectory is not None and len(runs) > 1 and runs[0][0] == 0 and runs[-1][1] == last:
            # A loop: the contact at the end goes on at the start of the next turn. One spot for
            # both, carried by the trajectory from the end's frame to the start's, so the foot
            # stands on it across the seam and the loop stays closed.
            head, tail = runs[0], runs[-1]
            spots = np.concatenate(
                [positions[tail[0] :, ankle], _carried(trajectory, positions[: head[1] + 1, ankle], 0, -1)]
            )
            pins[-1] = spots.mean(axis=0)
            pins[0] = _carried(trajectory, pins[-1], -1, 0)
        for (start, stop), pinned in zip(runs, pins, strict=True):
            # Where the foot was on average: the least reach asked of the leg on either side.
            span = np.arange(max(0, start - ease), min(clip.frame_count, stop + ease + 1))
            inside = np.clip(np.minimum(span - (start - ease), (stop + ease) - span) / ease, 0.0, 1.0)
            inside = inside * inside * (3.0 - 2.0 * inside)
            for frame, amount in zip(span, inside, strict=True):
                if amount > blend[frame]:
                    blend[frame] = amount
                    targets[frame, ground] = (
                        positions[frame, ankle, ground] * (1.0 - amount) + pinned[ground] * amount
                    )
        forward = positions[:, knee] - positions[:, hip]
        result = solve_leg(result, (hip, knee, ankle), targets, blend > 0.0, pole=forward)
    return _close_seam(result, sorted(set(legs)))


def _carried(
    trajectory: tuple[FloatArray, FloatArray], p: FloatArray, source: int, target: int
) -> FloatArray:
    """World points ``p`` moved with the trajectory from frame ``source``'s frame to ``target``'s."""
    yaw, points = trajectory
    local = quat.rotate(quat.conjugate(yaw[source]), p - points[source])
    moved: FloatArray = quat.rotate(yaw[target], local) + points[target]
    return moved


def _runs(mask: BoolArray) -> list[tuple[int, int]]:
    runs, start = [], None
    for i, on in enumerate([*list(mask), False]):
        if on and start is None:
            start = i
        elif not on and start is not None:
            runs.append((start, i - 1))
            start = None
    return runs


def _spread_seam(rotations: FloatArray) -> FloatArray:
    """(F, J, 4) rotations whose last frame equals the first: the difference between them is
    spread linearly over the clip (a fraction t of it applied at t of the way)."""
    frames = len(rotations)
    if frames < 3:
        return rotations
    error = quat.multiply(rotations[0], quat.conjugate(rotations[-1]))  # (J, 4)
    error = np.where(error[:, 3:4] < 0.0, -error, error)
    t = np.linspace(0.0, 1.0, frames)[:, None, None]
    identity = np.broadcast_to(quat.IDENTITY, error.shape)
    correction = quat.slerp(identity[None], error[None], t)  # (F, J, 4)
    return quat.normalize(quat.multiply(correction, rotations))


def _close_seam(clip: Clip, joints: list[int]) -> Clip:
    """``clip`` with the local rotations of ``joints`` closed again at the seam (`_spread_seam`)."""
    if clip.frame_count < 3 or not joints:
        return clip
    rotations = clip.rotations.copy()
    rotations[:, joints] = _spread_seam(rotations[:, joints])
    return replace(clip, rotations=rotations, notes=list(clip.notes))
