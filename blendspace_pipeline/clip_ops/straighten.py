"""Straightening: remove a small, unintended turn from a clip meant to go straight.

The facing and the trajectory are turned back progressively (the yaw rate loses its mean, so the
heading stays at its start value on average), and the path is integrated again from the clip's
own velocities in the character's frame: speed and sideways drift are kept, the turn is gone.
"""

from __future__ import annotations

import numpy as np

from blendspace_pipeline.clip import Clip
from blendspace_pipeline.clip_ops.root_motion import compose, decompose, integrate, step_velocities
from blendspace_pipeline.detect import RigSettings


def straighten_clip(clip: Clip, *, settings: RigSettings, name: str) -> Clip:
    motion = decompose(clip, settings)
    velocities, yaw_rates = step_velocities(motion.heading, motion.ground, clip.fps)
    turn = float(motion.heading[-1] - motion.heading[0])
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
        note=f"{clip.name} straightened: {np.degrees(turn):+.1f} deg of turn removed",
    )
