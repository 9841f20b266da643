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

from collections.abc import Callable
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


# --- Planted gaits: feet that stand still on the ground while in contact ------------------------
# `generate` swings the legs cosmetically and its feet slide; `generate_planted` places every
# footstep on the ground and solves the legs onto them with two-bone IK, so contact intervals,
# foot-down phases and foot sliding (zero) are known by construction.
ANKLE_HEIGHT = 0.06  # the toe (0.06 below the ankle in the rest pose) then touches the floor
FOOT_OFFSET = 0.09  # feet land this far left/right of the path (under the hip joints)
_SWING_LIFT = 0.08  # metres the ankle rises at mid-swing
_REACH = 0.97  # share of the straight leg (0.82 m) a planted step may use


@dataclass(frozen=True)
class PlantedTruth:
    """What `generate_planted` built: contact intervals (seconds) and foot-down phases."""

    contacts: dict[str, list[tuple[float, float]]]
    period: float  # seconds per stride, 0 when the feet never leave the ground
    duty: float  # share of a stride each foot is planted
    # Foot-down phases in the convention of `clip_ops.phase` (0: the left foot passes the right
    # one going forward): the left foot lands half its stance before its mid-stance.
    plant_phase: dict[str, float]


def _planted_cycles(spec: GaitSpec) -> float:
    if spec.speed > 1e-6:
        return _cadence(spec)
    if abs(spec.turn_rate) > 1e-6:  # turning on the spot steps too, about one stride a second
        return float(max(1, round(spec.duration / 1.0)))
    return 0.0


def _path_at(spec: GaitSpec, times: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Heading (radians) and ground (x, z) at any ``times``, also before 0 and after the end."""
    lo, hi = min(0.0, float(times.min())), max(spec.duration, float(times.max()))
    fine = np.linspace(lo, hi, int((hi - lo) * 400) + 2)
    heading = np.deg2rad(spec.start_heading + spec.turn_rate * fine)
    travel = heading + np.deg2rad(spec.direction)
    velocity = spec.speed * np.stack([np.sin(travel), np.cos(travel)], axis=-1)
    increments = 0.5 * (velocity[1:] + velocity[:-1]) * np.diff(fine)[:, None]
    path = np.concatenate([np.zeros((1, 2)), np.cumsum(increments, axis=0)])
    at_zero = np.array([np.interp(0.0, fine, path[:, 0]), np.interp(0.0, fine, path[:, 1])])
    path = path - at_zero + np.array(spec.start_position)
    ground = np.stack([np.interp(times, fine, path[:, 0]), np.interp(times, fine, path[:, 1])], axis=-1)
    return np.deg2rad(spec.start_heading + spec.turn_rate * times), ground


def planted_truth(spec: GaitSpec, duty: float | None = None) -> PlantedTruth:
    """Contact truth of ``generate_planted(spec, duty=duty)``."""
    duty = _duty(spec, duty)
    cycles = _planted_cycles(spec)
    if cycles == 0.0:
        whole = [(0.0, (max(2, round(spec.duration * spec.fps) + 1) - 1) / spec.fps)]
        return PlantedTruth({"left": whole, "right": list(whole)}, 0.0, 1.0, {})
    period = spec.duration / cycles
    end = (max(2, round(spec.duration * spec.fps) + 1) - 1) / spec.fps
    contacts: dict[str, list[tuple[float, float]]] = {}
    for foot, offset in (("left", 0.0), ("right", 0.5)):
        found = []
        for k in range(-2, int(cycles) + 3):
            mid = (k + offset) * period
            a, b = max(0.0, mid - 0.5 * duty * period), min(end, mid + 0.5 * duty * period)
            if b > a:
                found.append((a, b))
        contacts[foot] = found
    # Left mid-stance at phase 0.5 of `clip_ops.phase` (mid-swing of the left foot is where it
    # passes the right one): it lands duty/2 strides earlier, the right foot half a stride later.
    left = (0.5 - 0.5 * duty) % 1.0
    return PlantedTruth(contacts, period, duty, {"left": left, "right": (left + 0.5) % 1.0})


def _duty(spec: GaitSpec, duty: float | None) -> float:
    if duty is not None:
        if not 0.2 <= duty <= 0.8:
            raise ValueError("duty must lie in [0.2, 0.8]")
        return duty
    return 0.62 if spec.speed < 2.5 else 0.38  # walks keep double support, runs have flight


def _foot_targets(
    spec: GaitSpec, times: FloatArray, duty: float, cycles: float, side: float, offset: float
) -> tuple[FloatArray, FloatArray]:
    """World ankle positions (F, 3) and foot yaw (F,) of one foot: still during each stance, an
    arc from one footstep to the next during swing."""
    frames = len(times)
    if cycles == 0.0:
        heading, ground = _path_at(spec, np.zeros(1))
        spot = _footstep(heading, ground, side)
        return np.repeat(spot, frames, axis=0), np.repeat(heading, frames)
    period = spec.duration / cycles
    half = 0.5 * duty * period
    # The footstep whose stance is current or was last: its mid-stance time.
    index = np.floor((times - offset * period + half) / period)
    mids = (index + offset) * period
    next_mids = mids + period
    step_heading, step_ground = _path_at(spec, np.concatenate([mids, next_mids]))
    spots = _footstep(step_heading, step_ground, side)
    here, there = spots[:frames], spots[frames:]
    into_swing = np.clip((times - (mids + half)) / (period - 2.0 * half), 0.0, 1.0)
    ease = into_swing * into_swing * (3.0 - 2.0 * into_swing)
    position = here + (there - here) * ease[:, None]
    position[:, 1] += _SWING_LIFT * np.sin(np.pi * into_swing)
    yaw = step_heading[:frames] + (step_heading[frames:] - step_heading[:frames]) * ease
    return position, yaw


def _footstep(heading: FloatArray, ground: FloatArray, side: float) -> FloatArray:
    left = np.stack([np.cos(heading), np.zeros_like(heading), -np.sin(heading)], axis=-1)
    base = np.stack([ground[:, 0], np.full(len(heading), ANKLE_HEIGHT), ground[:, 1]], axis=-1)
    spot: FloatArray = base + side * FOOT_OFFSET * left
    return spot


def generate_planted(
    spec: GaitSpec,
    *,
    duty: float | None = None,
    up: str = "y",
    meters_per_unit: float = 1.0,
    source: Path | None = None,
    ground: Callable[[FloatArray], FloatArray] | None = None,
) -> Clip:
    """Like `generate`, but each foot stays planted on the ground for ``duty`` of every stride
    (default 0.62 for walks, 0.38 for runs) and swings to the next footstep in between; feet land
    under the hip joints on the path, so the root still does exactly what ``spec`` says. Standing
    clips keep both feet down; turning on the spot steps about once a second. The hips sit low
    enough that every footstep is within reach (see `planted_truth` for the contact truth).
    ``ground``: the floor's height (metres) at each world Z (a slope, stairs; default flat):
    footsteps land on it and the hips ride it, so the contacts and the ground speed are those
    of the flat clip.
    """
    from blendspace_pipeline.motion.ik import set_world_rotation, solve_leg

    duty = _duty(spec, duty)
    cycles = _planted_cycles(spec)
    base = generate(spec)  # hips, spine and arms as usual (Y up, metres, no Root joint)
    frames = base.frame_count
    times = np.arange(frames) / spec.fps
    period = spec.duration / cycles if cycles else spec.duration
    reach = 0.5 * duty * period * spec.speed + 0.05  # horizontal half-step, plus sway and margin
    leg = _REACH * 0.82
    hip_top = ANKLE_HEIGHT + 0.05 + float(np.sqrt(max(leg**2 - reach**2, 0.25 * leg**2)))
    drop = max(0.0, HIP_HEIGHT + (spec.bob if spec.speed > 1e-6 else 0.0) - hip_top)
    translations = base.translations.copy()
    hips = base.skeleton.index("Hips")
    translations[:, hips, 1] -= drop
    if ground is not None:
        translations[:, hips, 1] += ground(translations[:, hips, 2])
    clip = Clip(
        base.name, base.source, base.skeleton, base.rotations.copy(), translations, base.fps, 1.0, "y"
    )
    names = clip.skeleton.names
    heading = np.deg2rad(spec.start_heading + spec.turn_rate * times)
    forward = np.stack([np.sin(heading), np.zeros(frames), np.cos(heading)], axis=-1)
    everywhere = np.ones(frames, dtype=bool)
    for side_name, side, offset in (("Left", 1.0, 0.0), ("Right", -1.0, 0.5)):
        targets, yaw = _foot_targets(spec, times, duty, cycles, side, offset)
        if ground is not None:
            targets[:, 1] += ground(targets[:, 2])
        chain = (
            names.index(f"{side_name}UpLeg"),
            names.index(f"{side_name}Leg"),
            names.index(f"{side_name}Foot"),
        )
        clip = solve_leg(clip, chain, targets, everywhere, pole=forward)
        clip = set_world_rotation(clip, chain[2], quat.from_axis_angle(_Y, yaw), everywhere)
        clip.rotations[:, names.index(f"{side_name}Toe")] = quat.IDENTITY
    translations, rotations = _convert_up(clip.translations, clip.rotations, up, clip.skeleton)
    return Clip(
        name=spec.name,
        source=source or Path(f"{spec.name}.procedural"),
        skeleton=_scaled(clip.skeleton, meters_per_unit, up),
        rotations=rotations,
        translations=translations / meters_per_unit,
        fps=spec.fps,
        meters_per_unit=meters_per_unit,
        up_axis="z" if up == "z" else "y",
    )
