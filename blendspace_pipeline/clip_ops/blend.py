"""Pose blending: a new clip whose motion is the weighted mix of two or more clips.

Clips are aligned in normalised time (each clip's duration maps to [0, 1]) and resampled to the
weighted duration. Poses blend joint by joint (rotations by successive slerp, the n-way form of a
weighted quaternion mean; translations linearly); root motion blends as per-step velocities in
the character's own frame and yaw rates, then integrates, so the result's speed and turn rate
are the weighted values whatever the clips' lengths. This is what an engine's blend space does at
runtime, baked into a clip.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from blendspace_pipeline import quaternions as quat
from blendspace_pipeline.clip import Clip
from blendspace_pipeline.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.clip_ops.root_motion import compose, decompose, integrate, step_velocities
from blendspace_pipeline.detect import RigSettings
from blendspace_pipeline.quaternions import FloatArray


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


def _sample_frames(values: FloatArray, positions: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Neighbouring frames and fractions for fractional frame ``positions``."""
    last = len(values) - 1
    clipped = np.clip(positions, 0.0, last)
    lower = np.minimum(np.floor(clipped).astype(int), max(last - 1, 0))
    upper = np.minimum(lower + 1, last)
    return lower, upper, clipped - lower


def resample_quaternions(values: FloatArray, positions: FloatArray) -> FloatArray:
    lower, upper, t = _sample_frames(values, positions)
    return quat.slerp(values[lower], values[upper], t[:, None])


def resample_linear(values: FloatArray, positions: FloatArray) -> FloatArray:
    lower, upper, t = _sample_frames(values, positions)
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


def blend_clips(clips: Sequence[Clip], weights: Sequence[float], *, name: str, settings: RigSettings) -> Clip:
    """The weighted blend of ``clips`` (weights >= 0, normalised to sum to 1)."""
    if len(clips) != len(weights) or not clips:
        raise ValueError("one weight per clip")
    w = np.asarray(weights, dtype=np.float64)
    if (w < 0).any() or w.sum() <= 0:
        raise ValueError("weights must be >= 0 and not all 0")
    w = w / w.sum()
    check_compatible(clips)
    fps = clips[0].fps
    duration = float(sum(wi * c.duration for wi, c in zip(w, clips, strict=True)))
    frames = max(2, round(duration * fps) + 1)
    phase = np.linspace(0.0, 1.0, frames)
    step_phase = (np.arange(frames - 1) + 0.5) / (frames - 1)

    rotations, translations, rel_rot, rel_pos, velocities, yaw_rates = [], [], [], [], [], []
    motions = []
    for clip in clips:
        motion = decompose(clip, settings)
        motions.append(motion)
        at = phase * (clip.frame_count - 1)
        rotations.append(resample_quaternions(clip.rotations, at))
        translations.append(resample_linear(clip.translations, at))
        rel_rot.append(resample_quaternions(motion.rel_rotations, at))
        rel_pos.append(resample_linear(motion.rel_positions, at))
        velocity, yaw_rate = step_velocities(motion.heading, motion.ground, clip.fps)
        steps_at = step_phase * (clip.frame_count - 1) - 0.5
        velocities.append(resample_linear(velocity, steps_at))
        yaw_rates.append(resample_linear(yaw_rate, steps_at))

    weights_list = [float(x) for x in w]
    motion = motions[0]
    motion.rel_rotations = weighted_slerp(rel_rot, weights_list)
    motion.rel_positions = weighted_sum(rel_pos, weights_list)
    velocity = weighted_sum(velocities, weights_list)
    yaw_rate = weighted_sum(yaw_rates, weights_list)
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
        note=f"blend of {parts} (time-normalised, velocities blended in the character frame)",
    )
