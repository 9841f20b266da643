"""A blend played the way a game engine plays it, measured on the resulting pose.

Engines do not blend clips frame by frame in their own time: they weight the samples, sync them
(`sync`), and advance each at a playback rate. The rate changes what a clip does: a stride
played at 0.8x covers 0.8x the ground and turns 0.8x as much per second. This module plays
several cycles of such a blend tick by tick:

- each clip's local time advances at ``rate`` times real time and wraps at its end (a loop);
- the root moves by the weighted sum of the clips' per-tick root motion in the character's own
  frame (velocity times rate), as root-motion extraction does;
- the pose is the weighted blend of the clips' local rotations (successive slerp), the root
  joints placed on the blended trajectory; forward kinematics of that pose gives the feet;
- a foot counts as planted where the weighted vote of the clips' own contacts (at their local
  times) says so, and its sliding is its ground speed there.

`playback_rates` gives the rates of each sync mode: ``none`` (every clip at 1), ``normalized``
(every clip's whole length stretched to the weighted mean length: Unity blend trees, Unreal
blend spaces, Godot's sync) and ``markers`` (foot-down markers aligned to the leader, the
heaviest clip, which plays at 1: Unreal's marker-based sync groups).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.blend import resample_linear, resample_quaternions, weighted_slerp
from blendspace_pipeline.motion.clip_ops.feet import contact_joints
from blendspace_pipeline.motion.clip_ops.root_motion import (
    RootMotion,
    compose,
    decompose,
    integrate,
    step_velocities,
)
from blendspace_pipeline.motion.contacts import FEET, FootContacts
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.quaternions import FloatArray

SyncMode = Literal["none", "normalized", "markers"]
SYNC_MODES: tuple[SyncMode, ...] = ("none", "normalized", "markers")
# What our exports set up: Unity blend trees and Unreal blend spaces sync by normalised time.
DEFAULT_SYNC: SyncMode = "normalized"


def playback_rates(
    weights: Sequence[float],
    durations: Sequence[float],
    periods: Sequence[float | None],
    sync: SyncMode,
) -> list[float]:
    """Each clip's playback rate under ``sync``.

    ``durations`` are the clips' lengths (what normalised time stretches), ``periods`` their
    stride periods (None without a gait: no markers, the clip plays freely at 1 under markers).
    """
    if sync == "none":
        return [1.0] * len(weights)
    if sync == "normalized":
        total = sum(weights)
        blended = sum(w * d for w, d in zip(weights, durations, strict=True)) / total if total > 0 else 0.0
        return [d / blended if blended > 0 else 1.0 for d in durations]
    if sync == "markers":
        walking = [(w, p) for w, p in zip(weights, periods, strict=True) if p is not None and p > 0]
        if not walking:
            return [1.0] * len(weights)
        leader = max(walking, key=lambda wp: wp[0])[1]
        return [p / leader if p is not None and p > 0 else 1.0 for p in periods]
    raise ValueError(f"sync must be one of {', '.join(SYNC_MODES)}, not {sync!r}")


@dataclass(frozen=True)
class PlayedBlend:
    """What the blend did over the simulated time (SI units, the character's own frame)."""

    forward_speed: float  # m/s
    lateral_speed: float  # m/s, > 0 to the left
    turn_rate: float  # deg/s, > 0 to the left
    foot_sliding: float | None  # m/s: mean ground speed of planted feet; None without feet
    duration: float  # seconds simulated

    @property
    def speed(self) -> float:
        return float(np.hypot(self.forward_speed, self.lateral_speed))


@dataclass
class PreparedClip:
    """A clip split once into what the simulation samples every tick."""

    clip: Clip
    meters_per_unit: float
    contacts: FootContacts | None
    motion: RootMotion
    rotations: FloatArray
    rel_rotations: FloatArray
    rel_positions: FloatArray
    velocity: FloatArray  # (F-1, 2) per step, file units / s, character frame
    yaw_rate: FloatArray  # (F-1,) rad/s


def prepare(
    clip: Clip, settings: RigSettings, meters_per_unit: float, contacts: FootContacts | None
) -> PreparedClip:
    motion = decompose(clip, settings)
    velocity, yaw_rate = step_velocities(motion.heading, motion.ground, clip.fps)
    return PreparedClip(
        clip,
        meters_per_unit,
        contacts,
        motion,
        clip.rotations,
        motion.rel_rotations,
        motion.rel_positions,
        velocity,
        yaw_rate,
    )


def play(
    clips: Sequence[PreparedClip],
    weights: Sequence[float],
    rates: Sequence[float],
    settings: RigSettings,
    *,
    seconds: float | None = None,
    fps: float = 30.0,
) -> PlayedBlend:
    """Play the blend for ``seconds`` (default: three of the longest synced cycles) at ``fps``."""
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    if seconds is None:
        seconds = 3.0 * max(p.clip.duration / r for p, r in zip(clips, rates, strict=True) if r > 0)
    ticks = max(3, round(seconds * fps) + 1)
    times = np.arange(ticks) / fps
    mids = (np.arange(ticks - 1) + 0.5) / fps
    first = clips[0]
    unit = first.meters_per_unit
    velocity = np.zeros((ticks - 1, 2))
    yaw_rate = np.zeros(ticks - 1)
    poses, rel_rot, rel_pos = [], [], []
    planted = {foot: np.zeros(ticks) for foot in FEET}
    for prepared, weight, rate in zip(clips, w, rates, strict=True):
        clip = prepared.clip
        length = clip.frame_count - 1  # a loop's last frame is its first again
        at = np.mod(times * rate * clip.fps, length)
        steps_at = np.mod(mids * rate * clip.fps, length) - 0.5
        scale = prepared.meters_per_unit / unit  # everything in the first clip's units
        velocity += weight * rate * scale * resample_linear(prepared.velocity, np.clip(steps_at, 0, None))
        yaw_rate += weight * rate * resample_linear(prepared.yaw_rate, np.clip(steps_at, 0, None))
        poses.append(resample_quaternions(prepared.rotations, at))
        rel_rot.append(resample_quaternions(prepared.rel_rotations, at))
        rel_pos.append(resample_linear(prepared.rel_positions, at) * scale)
        if prepared.contacts is not None:
            local = at / clip.fps
            for foot in FEET:
                planted[foot] += weight * prepared.contacts.mask(foot, local)
    heading, ground = integrate(velocity, yaw_rate, fps, 0.0, np.zeros(2))
    motion = replace(first.motion)
    motion.rel_rotations = weighted_slerp(rel_rot, list(w))
    motion.rel_positions = np.sum([wi * p for wi, p in zip(w, rel_pos, strict=True)], axis=0)
    translations = np.repeat(first.clip.translations[:1], ticks, axis=0)
    pose = compose(
        first.clip,
        motion,
        heading,
        ground,
        weighted_slerp(poses, list(w)),
        translations,
        name="played",
        fps=fps,
        note="",
    )
    sliding = _sliding(pose, settings, motion.up_axis, planted, fps, unit)
    return PlayedBlend(
        forward_speed=float(velocity[:, 0].mean()) * unit,
        lateral_speed=float(velocity[:, 1].mean()) * unit,
        turn_rate=float(np.degrees(yaw_rate.mean())),
        foot_sliding=sliding,
        duration=float(times[-1]),
    )


def _sliding(
    pose: Clip, settings: RigSettings, up_axis: str, planted: dict[str, FloatArray], fps: float, unit: float
) -> float | None:
    """Mean ground speed (m/s) of the feet while the blend's contact vote says they are planted;
    per foot the slower of ankle and toe (a rolling foot pivots on one of them)."""
    joints = contact_joints(pose, settings)
    if joints is None or not any(v.any() for v in planted.values()):
        return None
    _, positions = forward_kinematics(pose)
    ground = [0, 1] if up_axis == "z" else [0, 2]
    speeds = []
    for foot, chain in zip(FEET, joints, strict=True):
        down = planted[foot] >= 0.5
        steady = down[1:] & down[:-1]
        if not steady.any():
            continue
        per_joint = [
            np.linalg.norm(np.diff(positions[:, j][:, ground], axis=0), axis=1) * fps * unit for j in chain
        ]
        speeds.append(np.minimum.reduce(per_joint)[steady])
    if not speeds:
        return None
    return float(np.concatenate(speeds).mean())
