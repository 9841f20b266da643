"""Split a clip into its trajectory and its pose, and put them back together.

The trajectory is what measurement sees: the root point's ground position and the facing
heading on every frame (the same `detect` decisions `measure` makes). The pose is everything
else: root joints expressed in the trajectory's moving frame, and every other joint's local
transform. Fixes edit the trajectory through its per-step velocities in the character's own
frame (forward, left) and its yaw rate, then integrate it back, so a blended or straightened clip
measures exactly the speed and turn rate it was built with. `decompose` followed by `compose`
reproduces the clip to float precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.detect import RigSettings, resolve_facing, resolve_root, resolve_up
from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.motion.quaternions import FloatArray


def ground_basis(up_axis: str) -> FloatArray:
    """Rows e1, e2 spanning the ground with e1 x e2 = up (the basis `measure` uses)."""
    if up_axis == "z":
        return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


@dataclass
class RootMotion:
    """A clip's trajectory (ground point + heading) and its root joints relative to it."""

    up_axis: str
    heading: FloatArray  # (F,) radians, unwrapped, counter-clockwise seen from above
    ground: FloatArray  # (F, 2) root point on the ground, file units, in `ground_basis`
    roots: tuple[int, ...]  # joints without a parent (or every joint of a flat skeleton)
    rel_rotations: FloatArray  # (F, R, 4) root joint world rotations in the trajectory frame
    rel_positions: FloatArray  # (F, R, 3) root joint world positions in the trajectory frame

    @property
    def up(self) -> FloatArray:
        return np.array([0.0, 0.0, 1.0]) if self.up_axis == "z" else np.array([0.0, 1.0, 0.0])

    def trajectory_points(self, ground: FloatArray | None = None) -> FloatArray:
        """(F, 3) world points of the trajectory (height 0)."""
        return (self.ground if ground is None else ground) @ ground_basis(self.up_axis)


def root_joints(clip: Clip) -> tuple[int, ...]:
    skeleton = clip.skeleton
    if not skeleton.has_hierarchy:
        return tuple(range(skeleton.joint_count))
    return tuple(j for j, parent in enumerate(skeleton.parents) if parent < 0)


def decompose(clip: Clip, settings: RigSettings) -> RootMotion:
    world_rot, world_pos = forward_kinematics(clip)
    up_axis, _ = resolve_up(clip, world_pos, settings)
    if up_axis not in ("y", "z"):
        # Measurement reads any up axis; the clip operations and the clip writers work in +Y or +Z
        # up files (what DCCs and engines write). Refused as a skipped fix, not a crash.
        raise IncompatibleClips(
            f"{clip.name!r} is {up_axis}-up; generated clips are made from +Y or +Z up sources only"
        )
    basis = ground_basis(up_axis)
    root = resolve_root(clip, settings, world_pos)
    facing = resolve_facing(clip, settings, up_axis, (world_rot, world_pos))
    ground = root.positions(world_pos) @ basis.T
    forward = facing.vectors(world_rot, world_pos) @ basis.T
    heading = np.unwrap(np.arctan2(forward[:, 1], forward[:, 0]))
    motion = RootMotion(up_axis, heading, ground, root_joints(clip), np.empty(0), np.empty(0))
    inverse_yaw = quat.conjugate(quat.from_axis_angle(motion.up, heading))  # (F, 4)
    roots = list(motion.roots)
    offsets = world_pos[:, roots] - motion.trajectory_points()[:, None]
    motion.rel_rotations = quat.multiply(inverse_yaw[:, None], world_rot[:, roots])
    motion.rel_positions = quat.rotate(
        np.broadcast_to(inverse_yaw[:, None], (*offsets.shape[:2], 4)), offsets
    )
    return motion


def step_velocities(heading: FloatArray, ground: FloatArray, fps: float) -> tuple[FloatArray, FloatArray]:
    """Per step: (forward, left) velocity in the facing frame at mid-step, and yaw rate (rad/s)."""
    steps = np.diff(ground, axis=0)
    mid = 0.5 * (heading[1:] + heading[:-1])
    cos, sin = np.cos(mid), np.sin(mid)
    local = np.stack([steps[:, 0] * cos + steps[:, 1] * sin, -steps[:, 0] * sin + steps[:, 1] * cos], axis=-1)
    return local * fps, np.diff(heading) * fps


def integrate(
    velocities: FloatArray, yaw_rates: FloatArray, fps: float, heading0: float, ground0: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Inverse of `step_velocities`: heading (F,) and ground (F, 2) from a start."""
    heading = heading0 + np.concatenate([[0.0], np.cumsum(yaw_rates / fps)])
    mid = 0.5 * (heading[1:] + heading[:-1])
    cos, sin = np.cos(mid), np.sin(mid)
    forward, left = velocities[:, 0] / fps, velocities[:, 1] / fps
    steps = np.stack([forward * cos - left * sin, forward * sin + left * cos], axis=-1)
    ground = np.asarray(ground0, dtype=np.float64) + np.concatenate(
        [np.zeros((1, 2)), np.cumsum(steps, axis=0)]
    )
    return heading, ground


def compose(
    template: Clip,
    motion: RootMotion,
    heading: FloatArray,
    ground: FloatArray,
    rotations: FloatArray,
    translations: FloatArray,
    *,
    name: str,
    fps: float,
    note: str,
) -> Clip:
    """A new clip: local ``rotations``/``translations`` for every joint, root joints placed on
    the trajectory (``heading``, ``ground``) from ``motion``'s relative transforms."""
    rotations = rotations.copy()
    translations = translations.copy()
    yaw = quat.from_axis_angle(motion.up, heading)
    points = motion.trajectory_points(ground)
    for index, joint in enumerate(motion.roots):
        rotations[:, joint] = quat.normalize(quat.multiply(yaw, motion.rel_rotations[:, index]))
        translations[:, joint] = points + quat.rotate(yaw, motion.rel_positions[:, index])
    return Clip(
        name=name,
        source=template.source.with_name(f"{safe_file_stem(name)}.generated"),
        skeleton=template.skeleton,
        rotations=rotations,
        translations=translations,
        fps=fps,
        meters_per_unit=template.meters_per_unit,
        up_axis=template.up_axis,
        notes=[note],
    )
