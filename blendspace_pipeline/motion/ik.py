"""Analytic two-bone inverse kinematics (hip - knee - ankle), vectorised over frames.

The method of the two-bone IK constraints in NeurAnimation (seed 003): the knee angle is set by
the law of cosines so the hip-to-ankle distance equals the hip-to-target distance, then the
thigh turns so the ankle points at the target. The leg keeps its own bend plane (the knee stays
where the animator bent it), bone lengths never change (only rotations are edited), and a
target out of reach is approached as far as the straightened leg allows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.quaternions import FloatArray

BoolArray = NDArray[np.bool_]
# Never straighten the leg completely: at full extension the bend plane is undefined.
_MAX_EXTENSION = 0.999


def _unit(v: FloatArray) -> FloatArray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    unit: FloatArray = v / np.where(norm > 1e-12, norm, 1.0)
    return unit


def _angle(a: FloatArray, b: FloatArray) -> FloatArray:
    angle: FloatArray = np.arccos(np.clip(np.einsum("fi,fi->f", _unit(a), _unit(b)), -1.0, 1.0))
    return angle


def solve_leg(
    clip: Clip,
    chain: tuple[int, int, int],
    targets: FloatArray,
    active: BoolArray,
    pole: FloatArray | None = None,
) -> Clip:
    """``clip`` with the leg ``chain`` (hip, knee, ankle joints) reaching ``targets`` (F, 3 world,
    file units) on the frames where ``active`` is True; the ankle keeps its world rotation.

    ``pole`` (F, 3) is the direction the knee bends towards when the leg is nearly straight
    (the character's forward, usually).
    """
    hip, knee, ankle = chain
    skeleton = clip.skeleton
    if skeleton.parents[ankle] != knee or skeleton.parents[knee] != hip:
        raise ValueError("solve_leg needs a hip -> knee -> ankle chain")
    world_rot, world_pos = forward_kinematics(clip)
    rows = np.flatnonzero(active)
    if not len(rows):
        return clip
    a, b, c = world_pos[rows, hip], world_pos[rows, knee], world_pos[rows, ankle]
    t = targets[rows]
    hip_rot, knee_rot, ankle_rot = world_rot[rows, hip], world_rot[rows, knee], world_rot[rows, ankle]
    lab = np.linalg.norm(b - a, axis=1)
    lcb = np.linalg.norm(c - b, axis=1)
    lat = np.clip(np.linalg.norm(t - a, axis=1), np.abs(lab - lcb) + 1e-9, _MAX_EXTENSION * (lab + lcb))
    # Current and wanted interior angles at the hip (ankle-hip-knee) and at the knee.
    ac_ab_0 = _angle(c - a, b - a)
    ba_bc_0 = _angle(a - b, c - b)
    ac_ab_1 = np.arccos(np.clip((lcb**2 - lab**2 - lat**2) / (-2.0 * lab * lat), -1.0, 1.0))
    ba_bc_1 = np.arccos(np.clip((lat**2 - lab**2 - lcb**2) / (-2.0 * lab * lcb), -1.0, 1.0))
    # The bend plane's normal: from the knee's offset off the hip-ankle line, or the pole.
    bend = np.cross(c - a, b - a)
    if pole is not None:
        fallback = np.cross(c - a, pole[rows])
        weak = np.linalg.norm(bend, axis=1) < 1e-6 * np.maximum(lab * lcb, 1e-12)
        bend = np.where(weak[:, None], fallback, bend)
    axis0 = _unit(bend)
    axis1 = _unit(np.cross(c - a, t - a))
    ac_at_0 = _angle(c - a, t - a)
    inv_hip, inv_knee = quat.conjugate(hip_rot), quat.conjugate(knee_rot)
    # Local hip = old local * r2 * r0: in world terms the bend (r0) comes first and the swing onto
    # the target (r2) after it; the other order only reaches targets in the bend plane.
    r0 = quat.from_axis_angle(_unit(quat.rotate(inv_hip, axis0)), ac_ab_1 - ac_ab_0)
    r1 = quat.from_axis_angle(_unit(quat.rotate(inv_knee, axis0)), ba_bc_1 - ba_bc_0)
    r2 = quat.from_axis_angle(_unit(quat.rotate(inv_hip, axis1)), ac_at_0)
    rotations = clip.rotations.copy()
    rotations[rows, hip] = quat.normalize(quat.multiply(quat.multiply(rotations[rows, hip], r2), r0))
    rotations[rows, knee] = quat.normalize(quat.multiply(rotations[rows, knee], r1))
    # The ankle keeps its world rotation: parent's new world rotation, then the local that gives it.
    parent = skeleton.parents[hip]
    parent_rot = world_rot[rows, parent] if parent >= 0 else np.tile(quat.IDENTITY, (len(rows), 1))
    new_knee = quat.multiply(quat.multiply(parent_rot, rotations[rows, hip]), rotations[rows, knee])
    rotations[rows, ankle] = quat.normalize(quat.multiply(quat.conjugate(new_knee), ankle_rot))
    return Clip(
        clip.name,
        clip.source,
        skeleton,
        rotations,
        clip.translations,
        clip.fps,
        clip.meters_per_unit,
        clip.up_axis,
        list(clip.notes),
    )


def set_world_rotation(clip: Clip, joint: int, rotations: FloatArray, active: BoolArray) -> Clip:
    """``clip`` with ``joint`` turned to world ``rotations`` (F, 4) on the ``active`` frames."""
    world_rot, _ = forward_kinematics(clip)
    parent = clip.skeleton.parents[joint]
    rows = np.flatnonzero(active)
    local = clip.rotations.copy()
    parent_rot = world_rot[rows, parent] if parent >= 0 else np.tile(quat.IDENTITY, (len(rows), 1))
    local[rows, joint] = quat.normalize(quat.multiply(quat.conjugate(parent_rot), rotations[rows]))
    return Clip(
        clip.name,
        clip.source,
        clip.skeleton,
        local,
        clip.translations,
        clip.fps,
        clip.meters_per_unit,
        clip.up_axis,
        list(clip.notes),
    )
