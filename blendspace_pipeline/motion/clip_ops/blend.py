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
from dataclasses import dataclass

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.phase import GaitCycle, detect_cycle, frames_at_phases
from blendspace_pipeline.motion.clip_ops.root_motion import compose, decompose, integrate, step_velocities
from blendspace_pipeline.motion.detect import RigSettings, detect_tpose_frame
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


def without_rest_frame(clip: Clip, settings: RigSettings) -> Clip:
    """The clip without a leading rest/T-pose frame, decided as `measure` decides it, so a
    generated clip is made of exactly the motion its sources were measured on."""
    if detect_tpose_frame(clip, forward_kinematics(clip)[1], settings):
        return clip.trimmed(1, clip.frame_count)
    return clip


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


def align(clips: Sequence[Clip], weights: Sequence[float], fps: float, settings: RigSettings) -> Timing:
    """Put the clips in step: by stride phase when any has a gait, else by normalised time."""
    cycles: list[GaitCycle | None] = [detect_cycle(clip, settings) for clip in clips]
    walking = [(w, c) for w, c in zip(weights, cycles, strict=True) if c is not None and w > 0.0]
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
    share = sum(w for w, _ in walking)
    period = sum(w * c.period for w, c in walking) / share
    strides = max(1, int(np.floor(duration / period + 0.5)))
    frames = max(2, round(strides * period * fps) + 1)
    lead = max(walking, key=lambda wc: wc[0])[1]  # the result starts where its main clip starts
    start = float(lead.phase[0])
    along = np.linspace(0.0, 1.0, frames)
    mid = (np.arange(frames - 1) + 0.5) / (frames - 1)
    poses, steps, wraps = [], [], []
    for clip, cycle in zip(clips, cycles, strict=True):
        if cycle is None:
            poses.append(along * (clip.frame_count - 1))
            steps.append(mid * (clip.frame_count - 1) - 0.5)
            wraps.append(False)
        else:
            poses.append(frames_at_phases(cycle, start + strides * along))
            steps.append(frames_at_phases(cycle, start + strides * mid) - 0.5)
            wraps.append(cycle.open_loop)
    periods = ", ".join(f"{c.period:.3g} s" for c in cycles if c is not None)
    return Timing(
        frames,
        poses,
        steps,
        wraps,
        f"aligned by gait phase (strides of {periods} -> {strides} x {period:.3g} s)",
    )


def blend_clips(clips: Sequence[Clip], weights: Sequence[float], *, name: str, settings: RigSettings) -> Clip:
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
    sources = [without_rest_frame(clip, settings) for clip in clips]
    motions = [decompose(clip, settings) for clip in sources]
    if len({m.up_axis for m in motions}) > 1:
        raise IncompatibleClips(
            f"{clips[0].name} and the other clips have different up axes "
            f"({', '.join(sorted({m.up_axis.upper() for m in motions}))})"
        )
    weights_list = [float(x) for x in w]
    fps = clips[0].fps
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
    parts = " + ".join(f"{wi:.3f} x {c.name}" for wi, c in zip(weights_list, clips, strict=True))
    return compose(
        clips[0],
        motion,
        heading,
        ground,
        weighted_slerp(rotations, weights_list),
        weighted_sum(translations, weights_list),
        name=name,
        fps=fps,
        note=f"blend of {parts}, {timing.description}; root velocities blended in the character frame",
    )
