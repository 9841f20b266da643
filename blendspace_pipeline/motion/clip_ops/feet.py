"""Which joints of a clip touch the ground, and their contacts (see `motion.contacts`).

Kept beside `phase` (whose foot finding it shares) so that `motion.contacts` itself needs no
clip operation and the blend can use both without an import cycle.
"""

from __future__ import annotations

from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops.phase import foot_joints
from blendspace_pipeline.motion.contacts import FootContacts, detect_contacts
from blendspace_pipeline.motion.detect import RigSettings, toe_of
from blendspace_pipeline.motion.quaternions import FloatArray


def contact_joints(clip: Clip, settings: RigSettings) -> tuple[list[int], list[int]] | None:
    """Per foot (left, right): the ankle `clip_ops.phase` syncs on, then the joint below it (the
    toe) when there is one; None for rigs without recognisable legs or without a hierarchy."""
    if not clip.skeleton.has_hierarchy:
        return None
    feet = foot_joints(clip, settings)
    if feet is None:
        return None
    found: list[list[int]] = []
    for foot in feet:
        toe = toe_of(clip, foot)  # a heel bone beside the toe is not the toe (`detect.toe_of`)
        found.append([foot, toe] if toe is not None else [foot])
    return found[0], found[1]


def clip_contacts(
    clip: Clip,
    settings: RigSettings,
    world_pos: FloatArray,
    *,
    meters_per_unit: float,
    up_axis: str,
) -> FootContacts | None:
    """`detect_contacts` on ``clip`` (its forward kinematics ``world_pos``), None without feet."""
    joints = contact_joints(clip, settings)
    if joints is None or clip.frame_count < 4:
        return None
    return detect_contacts(world_pos, joints, fps=clip.fps, meters_per_unit=meters_per_unit, up_axis=up_axis)
