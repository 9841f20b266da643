"""A procedural locomotion-clip generator with known ground truth.

Makes a small humanoid (Hips, legs, spine, arms) walking at a given speed, travel direction and
turn rate, with gait detail real clips have (hip bob, side sway, pelvis yaw, swinging limbs), so
that measurement is tested against values known by construction. The sample project and the
unit tests use it; nothing here reads a file.

Conventions of the generated rig (before `up="z"` conversion): Y up, metres, the character faces
+Z in its rest pose and its left is +X. Heading 0 faces +Z; positive heading turns left
(counter-clockwise seen from above).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray

_Y = np.array([0.0, 1.0, 0.0])
_X = np.array([1.0, 0.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])

# (name, parent name, rest offset in metres). Hips is the root; a "Root" joint may be prepended.
_HUMANOID: tuple[tuple[str, str | None, tuple[float, float, float]], ...] = (
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("LeftUpLeg", "Hips", (0.09, -0.05, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, -0.42, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -0.40, 0.0)),
    ("LeftToe", "LeftFoot", (0.0, -0.06, 0.14)),
    ("RightUpLeg", "Hips", (-0.09, -0.05, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, -0.42, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -0.40, 0.0)),
    ("RightToe", "RightFoot", (0.0, -0.06, 0.14)),
    ("Spine", "Hips", (0.0, 0.12, 0.0)),
    ("Chest", "Spine", (0.0, 0.22, 0.0)),
    ("Neck", "Chest", (0.0, 0.22, 0.0)),
    ("Head", "Neck", (0.0, 0.10, 0.02)),
    ("LeftArm", "Chest", (0.18, 0.18, 0.0)),
    ("LeftForeArm", "LeftArm", (0.28, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (0.26, 0.0, 0.0)),
    ("RightArm", "Chest", (-0.18, 0.18, 0.0)),
    ("RightForeArm", "RightArm", (-0.28, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-0.26, 0.0, 0.0)),
)
HIP_HEIGHT = 0.92  # metres; legs are 0.05 + 0.42 + 0.40 + 0.06 = 0.93 long, slightly bent


@dataclass(frozen=True)
class GaitSpec:
    """Ground truth of one generated clip. Angles in degrees, speeds in m/s."""

    name: str
    speed: float = 0.0  # ground speed along the path, >= 0
    direction: float = 0.0  # travel direction relative to facing, > 0 to the left
    turn_rate: float = 0.0  # deg/s, > 0 turns left
    duration: float = 1.0
    fps: float = 30.0
    start_position: tuple[float, float] = (0.0, 0.0)  # ground (x, z) in metres
    start_heading: float = 0.0
    stride_length: float = 1.3  # metres per full gait cycle (two steps), for cadence
    sway: float = 0.03  # metres of side-to-side hip sway
    bob: float = 0.025  # metres of vertical hip bob
    pelvis_yaw: float = 4.0  # degrees of pelvis rotation over the stride
    extras: dict[str, float] = field(default_factory=dict)

    @property
    def forward_speed(self) -> float:
        return self.speed * float(np.cos(np.deg2rad(self.direction)))

    @property
    def lateral_speed(self) -> float:
        return self.speed * float(np.sin(np.deg2rad(self.direction)))

    @property
    def signed_speed(self) -> float:
        """The `speed` feature as spec.md defines it: negative when travel is backward (past 100 deg)."""
        return -self.speed if abs(self.direction) > 100.0 else self.speed

    @property
    def turn(self) -> float:
        return self.turn_rate * self.duration


def _cadence(spec: GaitSpec) -> float:
    """Gait cycles in the clip, rounded to whole cycles so the clip loops like a real cycle."""
    if spec.speed < 1e-6:
        return 0.0
    cycles = spec.speed * spec.duration / spec.stride_length
    return float(max(1, round(cycles)))


def _trajectory(spec: GaitSpec, times: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Heading (radians) and ground position (x, z) of the character's root at ``times``.

    Integrated on a fine sub-grid so the path is the true arc, not a per-frame approximation.
    """
    fine = np.linspace(0.0, spec.duration, max(2, len(times) - 1) * 32 + 1)
    heading = np.deg2rad(spec.start_heading + spec.turn_rate * fine)
    travel = heading + np.deg2rad(spec.direction)
    velocity = spec.speed * np.stack([np.sin(travel), np.cos(travel)], axis=-1)  # (x, z) of facing+direction
    step = np.diff(fine)[:, None]
    increments = 0.5 * (velocity[1:] + velocity[:-1]) * step
    path = np.concatenate([np.zeros((1, 2)), np.cumsum(increments, axis=0)]) + np.array(spec.start_position)
    positions = np.stack([np.interp(times, fine, path[:, 0]), np.interp(times, fine, path[:, 1])], axis=-1)
    return np.deg2rad(spec.start_heading + spec.turn_rate * times), positions


def humanoid_skeleton(*, with_root_joint: bool = False, root_yaw_offset: float = 0.0) -> Skeleton:
    names = [name for name, _, _ in _HUMANOID]
    parents = [-1 if parent is None else names.index(parent) for _, parent, _ in _HUMANOID]
    offsets = [offset for _, _, offset in _HUMANOID]
    rest_rotations = np.tile(quat.IDENTITY, (len(names), 1))
    if with_root_joint:
        names = ["Root", *names]
        parents = [-1] + [p + 1 for p in parents]
        parents[1] = 0
        offsets = [(0.0, 0.0, 0.0), (0.0, HIP_HEIGHT, 0.0), *offsets[1:]]
        root_rest = quat.from_axis_angle(_Y, np.deg2rad(root_yaw_offset))
        rest_rotations = np.vstack([root_rest[None], np.tile(quat.IDENTITY, (len(names) - 1, 1))])
    return Skeleton(
        names=tuple(names),
        parents=tuple(parents),
        rest_translations=np.array(offsets, dtype=np.float64),
        rest_rotations=rest_rotations,
    )


def generate(
    spec: GaitSpec,
    *,
    up: str = "y",
    meters_per_unit: float = 1.0,
    with_root_joint: bool = False,
    root_yaw_offset: float = 0.0,
    tpose_first_frame: bool = False,
    source: Path | None = None,
) -> Clip:
    """A clip that does exactly what ``spec`` says.

    ``with_root_joint`` carries the trajectory on a ground-level ``Root`` joint (as many game
    rigs do) whose axes are turned ``root_yaw_offset`` degrees away from the character's facing.
    ``up="z"`` rotates the whole rig so that Z is up (forward becomes -Y).
    """
    frames = max(2, round(spec.duration * spec.fps) + 1)
    times = np.arange(frames) / spec.fps
    heading, ground = _trajectory(spec, times)
    phase = 2.0 * np.pi * _cadence(spec) * times / spec.duration if spec.duration > 0 else times * 0
    skeleton = humanoid_skeleton(with_root_joint=with_root_joint, root_yaw_offset=root_yaw_offset)
    joints = skeleton.names
    rotations = np.tile(quat.IDENTITY, (frames, len(joints), 1))
    translations = np.tile(skeleton.rest_translations, (frames, 1, 1))
    moving = 1.0 if spec.speed > 1e-6 else 0.0

    # Hips in the character's facing frame: height with bob, sideways sway, pelvis yaw.
    sway = moving * spec.sway * np.sin(phase)
    bob = moving * spec.bob * np.cos(2.0 * phase)
    yaw_wobble = np.deg2rad(moving * spec.pelvis_yaw * np.sin(phase))
    facing = quat.from_axis_angle(_Y, heading)
    left = quat.rotate(facing, np.broadcast_to(_X, (frames, 3)))
    hips_world = np.stack([ground[:, 0], np.full(frames, HIP_HEIGHT), ground[:, 1]], axis=-1)
    hips_world = hips_world + left * sway[:, None] + _Y * bob[:, None]
    hips_rotation = quat.multiply(facing, quat.from_axis_angle(_Y, yaw_wobble))

    hips = joints.index("Hips")
    if with_root_joint:
        root_rest = skeleton.rest_rotations[0]
        root_rotation = quat.multiply(facing, np.broadcast_to(root_rest, (frames, 4)))
        rotations[:, 0] = root_rotation
        translations[:, 0] = np.stack([ground[:, 0], np.zeros(frames), ground[:, 1]], axis=-1)
        inverse_root = quat.conjugate(root_rotation)
        rotations[:, hips] = quat.multiply(inverse_root, hips_rotation)
        translations[:, hips] = quat.rotate(inverse_root, hips_world - translations[:, 0])
    else:
        rotations[:, hips] = hips_rotation
        translations[:, hips] = hips_world

    _swing_limbs(rotations, joints, phase, moving)
    if tpose_first_frame:
        # Mocap exports often start with the rest (T-)pose: every joint unrotated, facing +Z.
        rotations[0] = quat.IDENTITY
    translations, rotations = _convert_up(translations, rotations, up, skeleton)
    return Clip(
        name=spec.name,
        source=source or Path(f"{spec.name}.procedural"),
        skeleton=_scaled(skeleton, meters_per_unit, up),
        rotations=rotations,
        translations=translations / meters_per_unit,
        fps=spec.fps,
        meters_per_unit=meters_per_unit,
        up_axis="z" if up == "z" else "y",
    )


def _swing_limbs(rotations: FloatArray, joints: tuple[str, ...], phase: FloatArray, moving: float) -> None:
    """Leg and arm swing in counter-phase: cosmetic, but it gives FK and the readers real work."""
    swing = np.deg2rad(25.0 * moving) * np.sin(phase)
    knee = np.deg2rad(30.0 * moving) * np.clip(np.sin(phase + np.pi / 2), 0.0, None) + np.deg2rad(5.0)
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        rotations[:, joints.index(f"{side}UpLeg")] = quat.from_axis_angle(_X, -sign * swing)
        rotations[:, joints.index(f"{side}Leg")] = quat.from_axis_angle(_X, knee if sign > 0 else knee[::-1])
        rotations[:, joints.index(f"{side}Arm")] = quat.multiply(
            quat.from_axis_angle(_Z, np.full_like(phase, -sign * np.deg2rad(70.0))),
            quat.from_axis_angle(_X, sign * 0.6 * swing),
        )


def _convert_up(
    translations: FloatArray, rotations: FloatArray, up: str, skeleton: Skeleton
) -> tuple[FloatArray, FloatArray]:
    if up == "y":
        return translations, rotations
    if up != "z":
        raise ValueError(f"up must be 'y' or 'z', not {up!r}")
    to_z_up = quat.from_axis_angle(_X, np.pi / 2)  # +Y -> +Z, +Z -> -Y
    translations = translations.copy()
    rotations = rotations.copy()
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0:
            translations[:, joint] = quat.rotate(to_z_up, translations[:, joint])
            rotations[:, joint] = quat.multiply(to_z_up, rotations[:, joint])
    return translations, rotations


def _scaled(skeleton: Skeleton, meters_per_unit: float, up: str) -> Skeleton:
    rest = skeleton.rest_translations / meters_per_unit
    if up == "z":
        rest = rest.copy()
        to_z_up = quat.from_axis_angle(_X, np.pi / 2)
        for joint, parent in enumerate(skeleton.parents):
            if parent < 0:
                rest[joint] = quat.rotate(to_z_up, rest[joint])
    return Skeleton(
        names=skeleton.names,
        parents=skeleton.parents,
        rest_translations=rest,
        rest_rotations=skeleton.rest_rotations,
    )


# The sample project's clip set: the key clips of a (turn_rate, speed) locomotion space.
SAMPLE_SET: tuple[GaitSpec, ...] = (
    GaitSpec("idle", duration=2.0),
    GaitSpec("walk_fwd", speed=1.4, duration=1.0),
    GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, duration=1.0, stride_length=1.1),
    GaitSpec("run_bwd", speed=2.6, direction=180.0, duration=0.8, stride_length=2.0),
    GaitSpec("walk_turn_left", speed=1.4, turn_rate=60.0, duration=1.5),
    GaitSpec("walk_turn_right", speed=1.4, turn_rate=-60.0, duration=1.5),
    GaitSpec("run_turn_left", speed=4.0, turn_rate=90.0, duration=1.0, stride_length=2.6),
    GaitSpec("run_turn_right", speed=4.0, turn_rate=-90.0, duration=1.0, stride_length=2.6),
    GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0),
    GaitSpec("turn_in_place_right", turn_rate=-90.0, duration=2.0),
    GaitSpec("strafe_left", speed=1.2, direction=90.0, duration=1.0, stride_length=1.0),
    GaitSpec("strafe_right", speed=1.2, direction=-90.0, duration=1.0, stride_length=1.0),
)
