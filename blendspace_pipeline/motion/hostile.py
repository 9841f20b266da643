"""Hostile mocap-like takes with known truth: what real studio files do to measurement.

A `procedural` clip is a clean loop. Real takes are not: the file states no unit and no up axis,
a static top joint (``Root``) sits at the origin while the hips start metres away, frame 0 is a
T-pose, the character stands, starts, walks a few steady strides and stops, and its pelvis sways
up to +-25 deg once a stride. `take` builds such a clip in any up axis (Y or Z) and unit (mm, cm,
m, inch, CMU's 1/0.45 inch) and says where its steady part is, so detection, the measured
features and ``range: auto`` can all be checked against values known by construction.

Conventions as in `procedural` before the up-axis change: Y up, the character faces +Z at
heading 0 and its left is +X; positive heading and turn rate turn left.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton, rest_positions
from blendspace_pipeline.motion.procedural import (
    HIP_HEIGHT,
    GaitSpec,
    _convert_up,
    _path_at,
    _scaled,
    generate_planted,
    humanoid_skeleton,
)
from blendspace_pipeline.motion.quaternions import FloatArray

UNITS = {"mm": 0.001, "cm": 0.01, "m": 1.0, "in": 0.0254, "cmu": 0.0254 / 0.45}
_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class HostileSpec:
    """One take. Speeds in m/s, angles in degrees, times in seconds, distances in metres."""

    name: str
    speed: float = 1.4  # steady ground speed
    direction: float = 0.0  # travel relative to facing, > 0 to the left
    turn_rate: float = 0.0  # steady turn rate, deg/s
    up: str = "y"
    unit: str = "cm"
    fps: float = 30.0
    hips_start: tuple[float, float] = (3.0, 0.0)  # ground (x, z) of the hips at the start
    start_heading: float = 0.0
    tpose_first_frame: bool = True
    pelvis_yaw: float = 20.0  # amplitude of the pelvis yaw sway over a stride
    stride_length: float = 1.3  # metres per stride (two steps) at the steady speed
    stand: float = 0.5  # seconds standing before the start and after the stop
    start_cycles: int = 2  # strides of speeding up (from standing)
    steady_cycles: int = 4
    stop_cycles: int = 2
    # A walk-turn-walk take: this many degrees turned smoothly over the steady strides but the
    # first and the last (turn_rate is then ignored).
    turn_total: float | None = None
    # Real-take untidiness: each stride's length varies by up to this fraction (the sway then
    # no longer repeats exactly), the pelvis yaw carries a second harmonic, and joints jitter.
    cadence_jitter: float = 0.0
    sway_harmonic: float = 0.0  # amplitude of the 2nd harmonic, relative to the first
    noise: float = 0.0  # metres of hip position noise (and 3x as many radians of pelvis yaw noise)
    seed: int = 0

    @property
    def period_frames(self) -> int:
        """Frames per stride: whole frames so the steady part starts and ends on a frame."""
        return max(8, round(self.stride_length / self.speed * self.fps))

    @property
    def period(self) -> float:
        return self.period_frames / self.fps


@dataclass(frozen=True)
class HostileTake:
    clip: Clip
    spec: HostileSpec
    steady: tuple[int, int]  # first and last frame (inclusive) of the steady strides

    @property
    def steady_seconds(self) -> tuple[float, float]:
        return self.steady[0] / self.spec.fps, self.steady[1] / self.spec.fps


def _envelope(frames: int, spec: HostileSpec) -> tuple[FloatArray, FloatArray, int, int]:
    """(gait amount 0..1 per frame, stride phase in radians, first and last steady frame)."""
    lead = (1 if spec.tpose_first_frame else 0) + round(spec.stand * spec.fps)
    p = spec.period_frames
    start, steady0 = lead, lead + spec.start_cycles * p
    steady1 = steady0 + spec.steady_cycles * p
    stop = steady1 + spec.stop_cycles * p
    index = np.arange(frames, dtype=np.float64)
    amount = np.zeros(frames)

    def smooth(u: FloatArray) -> FloatArray:
        u = np.clip(u, 0.0, 1.0)
        result: FloatArray = u * u * (3.0 - 2.0 * u)
        return result

    rising = (index >= start) & (index < steady0)
    amount[rising] = smooth((index[rising] - start) / max(1, steady0 - start))
    amount[(index >= steady0) & (index <= steady1)] = 1.0
    falling = (index > steady1) & (index <= stop)
    amount[falling] = 1.0 - smooth((index[falling] - steady1) / max(1, stop - steady1))
    phase = 2.0 * np.pi * (index - start) / p
    if spec.cadence_jitter > 0.0:
        # Stride k lasts p * (1 + jitter * u_k): the phase runs through whole strides at uneven
        # rates (the ground path, and so the truth, does not change).
        rng = np.random.default_rng(spec.seed)
        strides = int(np.ceil((frames - start) / p)) + 2
        lengths = p * (1.0 + spec.cadence_jitter * rng.uniform(-1.0, 1.0, strides))
        ends = start + np.concatenate([[0.0], np.cumsum(lengths)])
        phase = 2.0 * np.pi * np.interp(index, ends, np.arange(len(ends), dtype=np.float64))
    phase[index < start] = 0.0
    return amount, phase, steady0, steady1


def take(spec: HostileSpec, *, source: Path | None = None) -> HostileTake:
    """The take ``spec`` describes, as a file would read: no unit, no up axis."""
    p = spec.period_frames
    lead = (1 if spec.tpose_first_frame else 0) + round(spec.stand * spec.fps)
    frames = (
        lead
        + (spec.start_cycles + spec.steady_cycles + spec.stop_cycles) * p
        + round(spec.stand * spec.fps)
        + 1
    )
    amount, phase, steady0, steady1 = _envelope(frames, spec)
    # Heading and ground path integrated on a fine grid (the true arc), sampled at the frames.
    sub = 16
    fine = np.arange((frames - 1) * sub + 1) / (sub * spec.fps)
    fine_amount = np.interp(fine * spec.fps, np.arange(frames), amount)
    step = 1.0 / (sub * spec.fps)
    turned = np.concatenate([[0.0], np.cumsum(0.5 * (fine_amount[1:] + fine_amount[:-1]) * step)])
    fine_heading = np.deg2rad(spec.start_heading + spec.turn_rate * turned)
    if spec.turn_total is not None:
        first, last = steady0 + p, max(steady0 + p + 1, steady1 - p)
        u = np.clip((fine * spec.fps - first) / (last - first), 0.0, 1.0)
        fine_heading = np.deg2rad(spec.start_heading + spec.turn_total * u * u * (3.0 - 2.0 * u))
    travel = fine_heading + np.deg2rad(spec.direction)
    velocity = spec.speed * fine_amount[:, None] * np.stack([np.sin(travel), np.cos(travel)], axis=-1)
    path = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (velocity[1:] + velocity[:-1]) * step, axis=0)])
    path = path + np.array(spec.hips_start)
    heading = fine_heading[::sub]
    ground = path[::sub]

    skeleton = humanoid_skeleton(with_root_joint=True)
    joints = skeleton.names
    rotations = np.tile(quat.IDENTITY, (frames, len(joints), 1))
    translations = np.tile(skeleton.rest_translations, (frames, 1, 1))
    # The top joint stays at the origin, unrotated: the hips carry all the motion.
    translations[:, 0] = 0.0
    facing = quat.from_axis_angle(_Y, heading)
    left = quat.rotate(facing, np.broadcast_to(_X, (frames, 3)))
    sway = 0.03 * amount * np.sin(phase)
    bob = 0.025 * amount * np.cos(2.0 * phase)
    hips_world = np.stack([ground[:, 0], np.full(frames, HIP_HEIGHT), ground[:, 1]], axis=-1)
    translations[:, 1] = hips_world + left * sway[:, None] + _Y * bob[:, None]
    yaw = (
        np.deg2rad(spec.pelvis_yaw)
        * amount
        * (np.sin(phase) + spec.sway_harmonic * np.sin(2.0 * phase + 0.5))
    )
    rotations[:, 1] = quat.multiply(facing, quat.from_axis_angle(_Y, yaw))
    _legs_and_arms(rotations, joints, phase, amount)
    if spec.noise > 0.0:
        rng = np.random.default_rng(spec.seed + 1)
        translations[:, 1] += rng.normal(0.0, spec.noise, (frames, 3))
        jitter = quat.from_axis_angle(_Y, rng.normal(0.0, 3.0 * spec.noise, frames))  # 3 mm: 0.5 deg of yaw
        rotations[:, 1] = quat.multiply(rotations[:, 1], jitter)
    if spec.tpose_first_frame:
        rotations[0] = quat.IDENTITY
    translations, rotations = _convert_up(translations, rotations, spec.up, skeleton)
    scale = UNITS[spec.unit]
    clip = Clip(
        name=spec.name,
        source=source or Path(f"{spec.name}.hostile"),
        skeleton=_scaled(skeleton, scale, spec.up),
        rotations=rotations,
        translations=translations / scale,
        fps=spec.fps,
        meters_per_unit=None,  # as in a BVH file: nothing says the unit or the up axis
        up_axis=None,
    )
    return HostileTake(clip, spec, (steady0, steady1))


def _legs_and_arms(
    rotations: FloatArray, joints: tuple[str, ...], phase: FloatArray, amount: FloatArray
) -> None:
    """Legs swing in counter-phase, each knee bending through its own swing: the right leg does
    at phase + pi what the left does at phase, so the left foot passes the right one going
    forward exactly at phase 0 (where the strides of `take` begin)."""
    for side, shift in (("Left", 0.0), ("Right", np.pi)):
        swing = np.deg2rad(25.0) * amount * np.sin(phase + shift)
        knee = np.deg2rad(5.0) + np.deg2rad(30.0) * amount * np.clip(np.sin(phase + shift), 0.0, None)
        rotations[:, joints.index(f"{side}UpLeg")] = quat.from_axis_angle(_X, -swing)
        rotations[:, joints.index(f"{side}Leg")] = quat.from_axis_angle(_X, knee)
        sign = 1.0 if side == "Left" else -1.0
        rotations[:, joints.index(f"{side}Arm")] = quat.multiply(
            quat.from_axis_angle(_Z, np.full_like(phase, -sign * np.deg2rad(70.0))),
            quat.from_axis_angle(_X, 0.6 * swing),
        )


def grid(*, seed: int = 10) -> list[HostileSpec]:
    """Every up axis x unit, with the hips 0-10 m from the top joint, any start heading, pelvis
    sway up to +-25 deg and a spread of gaits (walks, runs, backward, strafes, diagonals, turns)."""
    rng = np.random.default_rng(seed)
    gaits = [
        ("walk", 1.4, 0.0, 0.0, 1.3),
        ("run", 3.8, 0.0, 0.0, 2.6),
        ("walk_back", 1.1, 180.0, 0.0, 1.1),
        ("strafe_left", 1.2, 90.0, 0.0, 1.0),
        ("strafe_right", 1.2, -90.0, 0.0, 1.0),
        ("diagonal", 1.3, 45.0, 0.0, 1.2),
        ("walk_turn_left", 1.4, 0.0, 30.0, 1.3),
        ("run_turn_right", 3.5, 0.0, -45.0, 2.5),
    ]
    specs: list[HostileSpec] = []
    for up in ("y", "z"):
        for unit in UNITS:
            for gait, speed, direction, turn_rate, stride in gaits:
                distance = float(rng.uniform(0.0, 10.0))
                angle = float(rng.uniform(0.0, 2.0 * np.pi))
                specs.append(
                    HostileSpec(
                        name=f"{gait}_{up}_{unit}",
                        speed=speed,
                        direction=direction,
                        turn_rate=turn_rate,
                        up=up,
                        unit=unit,
                        fps=float(rng.choice([30.0, 60.0, 120.0])),
                        hips_start=(distance * np.cos(angle), distance * np.sin(angle)),
                        start_heading=float(rng.uniform(-180.0, 180.0)),
                        pelvis_yaw=float(rng.uniform(0.0, 25.0)),
                        stride_length=stride,
                    )
                )
    return specs


def studio_set(*, seed: int = 118) -> list[HostileSpec]:
    """Takes like the held-out studio set of issue 10: 30 fps BVH in centimetres, Y up, a static
    `Root` at the origin with the hips 1-4 m away, a T-pose first frame, steady walks, runs,
    dashes, backward and diagonal walks and walking 90-degree turns, pelvis sway up to +-25 deg,
    measured whole (no `range:`)."""
    rng = np.random.default_rng(seed)
    kinds = [
        ("walk", 1.4, 0.0, None, 1.35),
        ("run", 3.6, 0.0, None, 2.5),
        ("dash", 6.0, 0.0, None, 3.6),
        ("walk_back", 1.1, 180.0, None, 1.1),
        ("diagonal_left", 1.3, 45.0, None, 1.25),
        ("diagonal_right", 1.3, -45.0, None, 1.25),
        ("turn_left", 1.3, 0.0, 90.0, 1.3),
        ("turn_right", 1.3, 0.0, -90.0, 1.3),
    ]
    specs = []
    for index in range(118):
        kind, speed, direction, turn, stride = kinds[index % len(kinds)]
        distance = float(rng.uniform(1.0, 4.0))
        angle = float(rng.uniform(0.0, 2.0 * np.pi))
        scale = float(rng.uniform(0.9, 1.1))
        specs.append(
            HostileSpec(
                name=f"{kind}_{index:03d}",
                speed=speed * scale,
                direction=direction,
                up="y",
                unit="cm",
                fps=30.0,
                hips_start=(distance * np.cos(angle), distance * np.sin(angle)),
                start_heading=float(rng.uniform(-180.0, 180.0)),
                pelvis_yaw=float(rng.uniform(0.0, 25.0)),
                stride_length=stride * scale,
                stand=0.0,
                start_cycles=0,
                steady_cycles=int(rng.integers(3, 7)) + (2 if turn is not None else 0),
                stop_cycles=0,
                turn_total=turn,
                cadence_jitter=0.06,
                sway_harmonic=0.3,
                noise=0.003,
                seed=index,
            )
        )
    return specs


# Ways a studio's clip ends up on another skeleton than the rest of its set, the motion unchanged:
# a DCC's namespace on every joint, a helper joint added (a prop or twist bone), a leaf joint lost
# on export, one joint under another parent, and the same joints written in another order.
SKELETON_CHANGES = ("namespaced", "extra_joint", "missing_leaf", "reparented", "reordered")


def on_other_skeleton(clip: Clip, change: str) -> Clip:
    """``clip``'s motion on a skeleton changed as ``change`` (one of `SKELETON_CHANGES`) says; the
    hips and legs keep their motion (and, but for `namespaced`, their names), so it still measures
    as ``clip`` does."""
    skeleton = clip.skeleton
    names, parents = list(skeleton.names), list(skeleton.parents)
    rest_t, rest_r = skeleton.rest_translations, skeleton.rest_rotations
    rotations, translations = clip.rotations, clip.translations
    leaf = max(
        i
        for i in range(len(names))
        if i not in parents and "foot" not in names[i].lower() and "toe" not in names[i].lower()
    )
    if change == "namespaced":
        names = [f"mixamorig:{name}" for name in names]
    elif change == "extra_joint":
        names.append("prop_r")
        parents.append(leaf)
        rest_t = np.vstack([rest_t, [[0.0, 0.05, 0.0]]])
        rest_r = np.vstack([rest_r, quat.IDENTITY[None]])
        frames = clip.frame_count
        rotations = np.concatenate([rotations, np.tile(quat.IDENTITY, (frames, 1, 1))], axis=1)
        translations = np.concatenate([translations, np.tile([0.0, 0.05, 0.0], (frames, 1, 1))], axis=1)
    elif change == "missing_leaf":
        keep = [i for i in range(len(names)) if i != leaf]
        remap = {old: new for new, old in enumerate(keep)}
        names = [names[i] for i in keep]
        parents = [-1 if parents[i] < 0 else remap[parents[i]] for i in keep]
        rest_t, rest_r = rest_t[keep], rest_r[keep]
        rotations, translations = rotations[:, keep], translations[:, keep]
    elif change == "reparented":
        # The leaf moves under its grandparent (same names, another hierarchy).
        grandparent = parents[parents[leaf]]
        parents[leaf] = grandparent if grandparent >= 0 else parents[leaf]
    elif change == "reordered":
        # Same joints and hierarchy, the root's branches written last to first (another exporter's
        # order): still parents before children, as every format stores them.
        order = _depth_first(parents, reverse_root=True)
        remap = {old: new for new, old in enumerate(order)}
        names = [names[i] for i in order]
        parents = [-1 if parents[i] < 0 else remap[parents[i]] for i in order]
        rest_t, rest_r = rest_t[order], rest_r[order]
        rotations, translations = rotations[:, order], translations[:, order]
    else:
        raise ValueError(f"unknown skeleton change {change!r}; one of {', '.join(SKELETON_CHANGES)}")
    other = Skeleton(
        names=tuple(names),
        parents=tuple(parents),
        rest_translations=np.asarray(rest_t, dtype=np.float64),
        rest_rotations=np.asarray(rest_r, dtype=np.float64),
        has_hierarchy=skeleton.has_hierarchy,
    )
    return replace(
        clip,
        skeleton=other,
        rotations=np.ascontiguousarray(rotations),
        translations=np.ascontiguousarray(translations),
        notes=list(clip.notes),
    )


def _depth_first(parents: list[int], reverse_root: bool) -> list[int]:
    """Joint indices depth first, children in index order (the root's reversed if asked)."""
    order: list[int] = []

    def visit(joint: int) -> None:
        order.append(joint)
        children = [j for j, p in enumerate(parents) if p == joint]
        for child in reversed(children) if reverse_root and parents[joint] < 0 else children:
            visit(child)

    for root in (j for j, p in enumerate(parents) if p < 0):
        visit(root)
    return order


# Joint naming schemes of public mocap sources and DCCs, for the humanoid rig's joints: DAZ/Poser
# (and CMU's Daz-friendly BVH release), CMU's ASF/AMC names, OptiTrack Motive's asset prefix,
# MikuMikuDance's Japanese names, and names that say nothing (`NAMELESS`: an exporter's `joint_07`,
# Blender's `Bone.007`): then only the skeleton's shape finds the hips (`body_shape`).
NAME_SCHEMES = ("daz", "asf", "prefixed", "mmd", "anonymous", "blender")
NAMELESS = ("anonymous", "blender")
_SCHEME_NAMES = {
    "daz": {
        "Hips": "hip", "UpLeg": "Thigh", "Leg": "Shin", "Foot": "Foot", "Toe": "Toe", "Spine": "abdomen",
        "Chest": "chest", "Neck": "neck", "Head": "head", "Arm": "ShldrBend", "ForeArm": "ForearmBend",
        "Hand": "Hand",
    },
    "asf": {
        "Hips": "root", "UpLeg": "femur", "Leg": "tibia", "Foot": "foot", "Toe": "toes", "Spine": "lowerback",
        "Chest": "thorax", "Neck": "lowerneck", "Head": "head", "Arm": "humerus", "ForeArm": "radius",
        "Hand": "hand",
    },
    "mmd": {
        "Hips": "下半身", "UpLeg": "足", "Leg": "ひざ", "Foot": "足首", "Toe": "つま先", "Spine": "上半身",
        "Chest": "上半身2", "Neck": "首", "Head": "頭", "Arm": "腕", "ForeArm": "ひじ", "Hand": "手首",
    },
}  # fmt: skip


def renamed(clip: Clip, scheme: str) -> Clip:
    """``clip`` with its joints named as ``scheme`` (one of `NAME_SCHEMES`) names them; the motion
    is unchanged, so it measures as ``clip`` does wherever the scheme's hips are recognised."""
    if scheme not in NAME_SCHEMES:
        raise ValueError(f"unknown naming scheme {scheme!r}; one of {', '.join(NAME_SCHEMES)}")
    names = [_scheme_name(name, scheme, index) for index, name in enumerate(clip.skeleton.names)]
    return replace(clip, skeleton=replace(clip.skeleton, names=tuple(names)), notes=list(clip.notes))


def _scheme_name(name: str, scheme: str, index: int) -> str:
    if scheme == "anonymous":
        return f"joint_{index:02d}"
    if scheme == "blender":
        return f"Bone.{index:03d}" if index else "Bone"
    side = next((s for s in ("Left", "Right") if name.startswith(s)), "")
    base = name[len(side) :]
    if scheme == "prefixed":
        return f"Skeleton1_{side[:1]}{'Thigh' if base == 'UpLeg' else base}"
    table = _SCHEME_NAMES[scheme]
    if base not in table:
        return name  # a joint the scheme has no name for (a top `Root`) keeps its own
    if scheme in ("daz", "asf"):  # a lower-case side letter: lThigh, lfemur
        return f"{side[:1].lower()}{table[base]}" if side else table[base]
    return f"{'左' if side == 'Left' else '右'}{table[base]}" if side else table[base]


def sides_swapped(clip: Clip) -> Clip:
    """``clip`` with every Left joint named Right and the other way round, the motion unchanged:
    an export whose side labels are swapped (the hip line then faces backwards)."""
    names = [
        ("Right" + n[4:]) if n.startswith("Left") else ("Left" + n[5:]) if n.startswith("Right") else n
        for n in clip.skeleton.names
    ]
    return replace(clip, skeleton=replace(clip.skeleton, names=tuple(names)), notes=list(clip.notes))


def mirrored_export(clip: Clip) -> Clip:
    """``clip`` written through a mirror across the world X = 0 plane (a left-handed export):
    names unchanged, every offset and translation's X negated and every rotation reflected. The
    body is then its own mirror image: forward and speed are the same, turns and sidesteps have
    the other sign, and the joint named left is on the character's right."""

    def reflect(q: FloatArray) -> FloatArray:
        out = q.copy()
        out[..., 1] *= -1.0  # M R M for the X reflection: x stays, y and z flip, w stays
        out[..., 2] *= -1.0
        return out

    translations = clip.translations.copy()
    translations[..., 0] *= -1.0
    rest = clip.skeleton.rest_translations.copy()
    rest[:, 0] *= -1.0
    skeleton = replace(
        clip.skeleton, rest_translations=rest, rest_rotations=reflect(clip.skeleton.rest_rotations)
    )
    return replace(
        clip,
        skeleton=skeleton,
        rotations=reflect(clip.rotations),
        translations=translations,
        notes=list(clip.notes),
    )


def held_keys(
    clip: Clip, leading: int, trailing: int, *, jitter: float = 0.0, ramp: float = 0.0, seed: int = 0
) -> Clip:
    """``clip`` with its first pose held for ``leading`` frames before it and its last pose for
    ``trailing`` frames after it: what a DCC exports when the scene's frame range is longer than
    the action (constant extrapolation past the first and last key). ``jitter``: radians of noise
    on every held rotation, as a re-evaluated key carries it (float32 storage: ~1e-7). ``ramp``:
    radians every joint's rotation drifts over each hold, on a straight line towards the motion
    (Blender's FBX curve simplification leaves a hold so: 0.4 mm a frame on the toes)."""
    rng = np.random.default_rng(seed)
    axis = np.array([1.0, 0.0, 0.0])

    def pad(values: FloatArray, quaternions: bool) -> FloatArray:
        head = np.repeat(values[:1], leading, axis=0)
        tail = np.repeat(values[-1:], trailing, axis=0)
        if quaternions and ramp:
            for block, towards in (
                (head, np.linspace(1.0, 0.0, leading + 1)[:-1]),
                (tail, np.linspace(0.0, 1.0, trailing + 1)[1:]),
            ):
                turn = quat.from_axis_angle(axis, ramp * towards)  # (n, 4), one turn per frame
                block[:] = quat.multiply(block, turn[:, None, :])
        if jitter and quaternions:
            for block in (head, tail):
                block += rng.normal(0.0, jitter / 2.0, block.shape)
                block /= np.linalg.norm(block, axis=-1, keepdims=True)
        return np.concatenate([head, values, tail])

    return replace(
        clip,
        rotations=pad(clip.rotations, True),
        translations=pad(clip.translations, False),
        notes=list(clip.notes),
    )


def still_pose(clip: Clip, frames: int, frame: int = 0) -> Clip:
    """One pose of ``clip`` (frame ``frame``) repeated ``frames`` times: a "TPose" action, or a
    pose exported as an animation."""
    return replace(
        clip,
        rotations=np.repeat(clip.rotations[frame : frame + 1], frames, axis=0),
        translations=np.repeat(clip.translations[frame : frame + 1], frames, axis=0),
        notes=list(clip.notes),
    )


def without_toes(clip: Clip) -> Clip:
    """``clip`` on its skeleton without the toe joints (legs of hip, knee and ankle: many game
    rigs and BVH exports end the leg at the ankle)."""
    skeleton = clip.skeleton
    keep = [i for i, name in enumerate(skeleton.names) if "toe" not in name.lower()]
    remap = {old: new for new, old in enumerate(keep)}
    parents = [-1 if skeleton.parents[i] < 0 else remap[skeleton.parents[i]] for i in keep]
    other = replace(
        skeleton,
        names=tuple(skeleton.names[i] for i in keep),
        parents=tuple(parents),
        rest_translations=skeleton.rest_translations[keep],
        rest_rotations=skeleton.rest_rotations[keep],
    )
    return replace(
        clip,
        skeleton=other,
        rotations=np.ascontiguousarray(clip.rotations[:, keep]),
        translations=np.ascontiguousarray(clip.translations[:, keep]),
        notes=list(clip.notes),
    )


# (name, parent's name, rest offset in the clip's units, the joint it is listed before or None)
Extra = tuple[str, str, tuple[float, float, float], str | None]


def with_joints(clip: Clip, extra: list[Extra]) -> Clip:
    """``clip`` with joints added that keep their rest offset and rotation on every frame (they
    ride along with their parent): foot-roll heels, cloth chains, IK helpers. Each goes right
    before the joint its fourth field names (the file order exporters write), else last."""
    skeleton = clip.skeleton
    names, parents = list(skeleton.names), list(skeleton.parents)
    rest_t, rest_r = list(skeleton.rest_translations), list(skeleton.rest_rotations)
    rotations, translations = (
        list(np.moveaxis(clip.rotations, 1, 0)),
        list(np.moveaxis(clip.translations, 1, 0)),
    )
    for name, parent, offset, before in extra:
        at = len(names) if before is None else names.index(before)
        parent_index = names.index(parent)
        parents = [p + 1 if p >= at else p for p in parents]
        names.insert(at, name)
        parents.insert(at, parent_index if parent_index < at else parent_index + 1)
        rest_t.insert(at, np.asarray(offset, dtype=np.float64))
        rest_r.insert(at, quat.IDENTITY.copy())
        rotations.insert(at, np.tile(quat.IDENTITY, (clip.frame_count, 1)))
        translations.insert(at, np.tile(np.asarray(offset, dtype=np.float64), (clip.frame_count, 1)))
    other = Skeleton(
        names=tuple(names),
        parents=tuple(parents),
        rest_translations=np.array(rest_t),
        rest_rotations=np.array(rest_r),
        has_hierarchy=skeleton.has_hierarchy,
    )
    return replace(
        clip,
        skeleton=other,
        rotations=np.ascontiguousarray(np.stack(rotations, 1)),
        translations=np.ascontiguousarray(np.stack(translations, 1)),
        notes=list(clip.notes),
    )


def heel_bones(clip: Clip) -> Clip:
    """A foot-roll heel on each foot of the procedural rig, listed before the toe: the toe no
    longer ends the foot's first (or only) line of descendants."""
    return with_joints(
        clip,
        [(f"{side}Heel", f"{side}Foot", (0.0, -0.06, -0.05), f"{side}Toe") for side in ("Left", "Right")],
    )


def long_coat(clip: Clip, hem: float = 0.03, segments: int = 3, sway: float = 0.0) -> Clip:
    """Four cloth chains hanging from the procedural rig's hips to ``hem`` metres above the floor,
    front and back on each side: mirror images of each other, longer than the legs. ``sway``:
    degrees each cloth joint swings to and fro over the take (a baked cloth simulation), else
    they ride along, static."""
    top = 0.10  # the waist, above the hips
    floor = float(np.min(_rest_heights(clip)))
    step = (top - (floor + hem)) / segments
    extra: list[Extra] = []
    for key, (x, z) in {
        "FL": (0.12, 0.10),
        "FR": (-0.12, 0.10),
        "BL": (0.12, -0.10),
        "BR": (-0.12, -0.10),
    }.items():
        extra.append((f"coat{key}0", "Hips", (x, top, z), None))
        extra += [(f"coat{key}{i + 1}", f"coat{key}{i}", (0.0, -step, 0.0), None) for i in range(segments)]
    coated = with_joints(clip, extra)
    if not sway:
        return coated
    cloth = [j for j, name in enumerate(coated.skeleton.names) if name.startswith("coat")]
    phase = np.arange(coated.frame_count)[:, None] * 0.3 + np.arange(len(cloth))[None, :]
    swing = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.radians(sway) * np.sin(phase))
    rotations = coated.rotations.copy()
    rotations[:, cloth] = quat.multiply(rotations[:, cloth], swing)
    return replace(coated, rotations=rotations)


def _rest_heights(clip: Clip) -> FloatArray:
    heights: FloatArray = rest_positions(clip.skeleton)[:, 1]
    return heights


def thigh_twist(clip: Clip) -> Clip:
    """A twist joint halfway down each thigh of the procedural rig (DAZ's ThighBend / ThighTwist):
    the knee is no longer the second joint of the leg. Positions are unchanged."""
    skeleton = clip.skeleton
    out = clip
    for side in ("Left", "Right"):
        names = out.skeleton.names
        knee = names.index(f"{side}Leg")
        half = out.skeleton.rest_translations[knee] / 2.0
        out = with_joints(out, [(f"{side}ThighTwist", f"{side}UpLeg", tuple(half), f"{side}Leg")])
        names = out.skeleton.names
        knee, twist = names.index(f"{side}Leg"), names.index(f"{side}ThighTwist")
        parents = list(out.skeleton.parents)
        parents[knee] = twist
        rest_t = out.skeleton.rest_translations.copy()
        rest_t[knee] = half
        translations = out.translations.copy()
        translations[:, knee] = translations[:, knee] - half
        out = replace(
            out,
            skeleton=replace(out.skeleton, parents=tuple(parents), rest_translations=rest_t),
            translations=translations,
        )
    assert out.skeleton.joint_count == skeleton.joint_count + 2
    return out


def big_feet(clip: Clip, toe_length: float) -> Clip:
    """The procedural rig's toes ``toe_length`` metres ahead of the ankles (0.14 as generated): a
    stylised character's feet, as long as a quarter of its leg or more."""
    skeleton = clip.skeleton
    rest = skeleton.rest_translations.copy()
    translations = clip.translations.copy()
    for side in ("Left", "Right"):
        toe = skeleton.names.index(f"{side}Toe")
        rest[toe, 2] = toe_length
        translations[:, toe, 2] = toe_length
    return replace(clip, skeleton=replace(skeleton, rest_translations=rest), translations=translations)


def posed_rest(clip: Clip, frame: int) -> Clip:
    """``clip`` with frame ``frame``'s pose for its rest pose: what the FBX and USD readers see in
    a Blender export, where an armature-only file keeps no rest pose but the exported frame's (a
    walk's stride: knees bent, a heel lifted, toes off the floor)."""
    skeleton = replace(
        clip.skeleton,
        rest_translations=clip.translations[frame].copy(),
        rest_rotations=clip.rotations[frame].copy(),
    )
    return replace(clip, skeleton=skeleton, notes=list(clip.notes))


def static_leg_copies(clip: Clip, parent: str = "Spine", first: bool = False) -> Clip:
    """The procedural rig with a copy of each leg hanging from ``parent`` (Spine or Hips) that
    never moves: the ORG or IK helper chains of a Rigify-like rig, left in their rest by an
    unbaked export. In a posed rest (`posed_rest`) they are the straightest legs there; hung
    from the Hips and listed ``first`` (before the legs), they tie with the legs in every way but
    the take's motion."""
    skeleton = clip.skeleton
    top = skeleton.names.index(parent)
    extra: list[Extra] = []
    for side in ("Left", "Right"):
        hip = skeleton.names.index(f"{side}UpLeg")
        to_hip = skeleton.rest_translations[hip] - (skeleton.rest_translations[top] if top else 0.0)
        chain = [f"org_{side}_{part}" for part in ("thigh", "shin", "foot", "toe")]
        extra.append((chain[0], parent, tuple(to_hip), "LeftUpLeg" if first else None))
        for above, name, joint in zip(chain, chain[1:], ("Leg", "Foot", "Toe"), strict=False):
            offset = skeleton.rest_translations[skeleton.names.index(f"{side}{joint}")]
            extra.append((name, above, tuple(offset), "LeftUpLeg" if first else None))
    return with_joints(clip, extra)


def keyed_everywhere(clip: Clip, radians: float = 1e-4) -> Clip:
    """``clip`` with every joint turning by a wobble of ``radians`` (a mocap bake keys every bone,
    and no joint holds exactly still): nothing tells static helpers from the body by stillness."""
    frames, joints = clip.rotations.shape[:2]
    phase = np.arange(frames)[:, None] * 0.37 + np.arange(joints)[None, :]
    wobble = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), radians * np.sin(phase))
    rotations = quat.multiply(clip.rotations, wobble)
    return replace(clip, rotations=quat.normalize(rotations), notes=list(clip.notes))


def joined(name: str, parts: list[GaitSpec]) -> Clip:
    """One long take of ``parts`` played one after the other (a LaFAN1 or 100STYLE take: a walk,
    then a turn, then a run), each a planted-feet `generate_planted` clip that starts where and
    facing as the one before it ended. All parts share the first's rate; every part after the
    first drops its first frame (the last of the one before). Truth: each part's own spec."""
    clips: list[Clip] = []
    position, heading = (0.0, 0.0), 0.0
    for part in parts:
        spec = replace(part, name=name, fps=parts[0].fps, start_position=position, start_heading=heading)
        clips.append(generate_planted(spec))
        turned, ground = _path_at(spec, np.array([spec.duration]))
        position, heading = (float(ground[0, 0]), float(ground[0, 1])), float(np.degrees(turned[0]))
    first = clips[0]
    return replace(
        first,
        rotations=np.concatenate([first.rotations] + [c.rotations[1:] for c in clips[1:]]),
        translations=np.concatenate([first.translations] + [c.translations[1:] for c in clips[1:]]),
    )


def in_place(clip: Clip) -> Clip:
    """``clip`` with its root's travel over the ground taken out (Mixamo's "In Place", a treadmill
    take): the hips keep their height and turn, and each planted foot slides back under the body
    at the walk's speed. Truth: the contacts and the stride of the clip with root motion."""
    root = 0  # the procedural rig's root (Hips, or the ground-level Root joint)
    up = "xyz".index((clip.up_axis or "y").lstrip("+-"))
    translations = clip.translations.copy()
    for axis in range(3):
        if axis != up:
            translations[:, root, axis] = translations[0, root, axis]
    return replace(clip, translations=translations)
