"""Straightening: remove a small, unintended turn from a clip meant to go straight.

The facing and the trajectory are turned back progressively (the yaw rate loses its mean, so the
heading stays at its start value on average), and the path is integrated again from the clip's
own velocities in the character's frame: speed and sideways drift are kept, the turn is gone.
This is the progressive counter-rotation angle(t) = -turn * t / T applied to the facing, with
the path re-laid along the straightened facing rather than only turned about each frame's root
point, so the travel direction relative to the facing stays what it was on every frame. A
leading rest/T-pose frame is left out first, as `measure` leaves it out.
"""

from __future__ import annotations

import numpy as np

from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.blend import measured_part
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.root_motion import compose, decompose, integrate, step_velocities
from blendspace_pipeline.motion.clip_ops.sway import sway_free
from blendspace_pipeline.motion.detect import RigSettings


def straighten_clip(clip: Clip, *, settings: RigSettings, name: str) -> Clip:
    """``clip`` with its net turn removed: measures turn 0 at the same speed and direction."""
    source = clip
    clip = measured_part(clip, settings)
    if clip.frame_count < 2:
        raise IncompatibleClips(f"{clip.name} has {clip.frame_count} frame(s): no turn to remove")
    motion = decompose(clip, settings)
    velocities, yaw_rates = step_velocities(motion.heading, motion.ground, clip.fps)
    # The turn `measure` reads: facing averaged over a gait cycle, so pelvis sway is not "turn".
    facing = sway_free(motion.heading, clip, settings, forward_kinematics(clip), positions=motion.ground)
    turn = float(facing[-1] - facing[0])
    straight = yaw_rates - turn / clip.duration
    heading, ground = integrate(velocities, straight, clip.fps, float(motion.heading[0]), motion.ground[0])
    return compose(
        clip,
        motion,
        heading,
        ground,
        clip.rotations,
        clip.translations,
        name=name,
        fps=clip.fps,
        note=f"{clip.name} straightened: {np.degrees(turn):+.1f} deg of turn removed"
        + ("" if clip is source else " (leading rest-pose frame left out)"),
    )
