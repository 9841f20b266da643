"""What a clip file does not say, decided from the data or the manifest's `skeleton:` block.

Up axis, length unit, the root point whose ground projection is the root motion, the facing
direction, and a rest/T-pose first frame. Every decision is returned with a label so the build
can report what was used, and every automatic guess can be overridden in the manifest.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field, replace
from typing import TypeVar, cast

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion import stats
from blendspace_pipeline.motion.body_shape import ShapeHips, ankle_of, hips_by_shape, leg_chain
from blendspace_pipeline.motion.clip import Clip, rest_positions
from blendspace_pipeline.motion.joint_names import find_hips, split_side
from blendspace_pipeline.motion.notes import REST_FRAME_NOTE, STILL_NOTE, held_note
from blendspace_pipeline.motion.quaternions import FloatArray

UNIT_METERS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
# CMU's ASF skeletons scale inches by 0.45 ("length 0.45"), so one unit is 1/0.45 inch; BVH
# conversions of the database keep that unit (legs about 14 units long).
CMU_UNIT = 0.0254 / 0.45
_CONVENTIONS = {**UNIT_METERS, "cmu": CMU_UNIT}
# An adult's leg from the hip socket to the ankle: about 0.82 m (0.47 x height), 0.6-1.1 m
# from small to tall adults; the ranges of neighbouring units (x2.2 apart at least) never meet.
REFERENCE_LEG = 0.82
_PLAUSIBLE_LEG = (0.55, 1.15)
# An adult's hip socket stands about 0.9 m above the floor (roughly 0.53 x body height).
REFERENCE_HIP_HEIGHT = 0.9
# `hip_height` measures down to the lowest *joint* (toe or ankle), which stands a few centimetres
# above the floor, so the height compared with it is the socket's height less that.
_LOWEST_JOINT_HEIGHT = 0.04
# `hip_height` takes this percentile of the per-frame heights: the character at its most upright
# (legs nearly straight), which is what the reference describes. The median read a walk's bent
# knees, and a take's crouches or start/stop phases dragged it down (CMU 131_01: 13.1 units by
# the median vs 14.1 at the 90th percentile; 131_02, same performer: 14.0 vs 14.4).
_UPRIGHT_PERCENTILE = 90.0
_PLAUSIBLE_HIP_HEIGHT = (0.45, 1.5)
_AXIS_VECTORS = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}


@dataclass(frozen=True)
class RigSettings:
    """The manifest's `skeleton:` block, format-neutral. "auto" means detect."""

    units: str | float = "auto"
    up: str = "auto"
    root: str = "auto"
    left_hip: str = "auto"
    right_hip: str = "auto"
    forward: str = "auto"
    tpose: str = "auto"

    def cache_key(self) -> str:
        return repr((self.units, self.up, self.root, self.left_hip, self.right_hip, self.forward, self.tpose))


@dataclass(frozen=True)
class DetectionGuess:
    """A decision the data did not settle: reported as a `detection-guess` warning.

    ``what`` is up axis, units, root or facing; ``evidence`` says what was seen and ``override``
    is the exact manifest setting that replaces the guess. ``stated``: the value is not a guess
    but one the file or the manifest states, which the data contradicts (used, and doubted).
    """

    what: str
    value: str
    evidence: str
    override: str
    stated: bool = False


@dataclass
class RootPoint:
    label: str
    positions: Callable[[FloatArray], FloatArray]
    notes: list[str] = field(default_factory=list)
    guess: DetectionGuess | None = None


@dataclass
class Facing:
    label: str
    vectors: Callable[[FloatArray, FloatArray], FloatArray]
    notes: list[str] = field(default_factory=list)
    guess: DetectionGuess | None = None


_T = TypeVar("_T")
# Answers that depend on the rig alone (joint names, hierarchy, the manifest's hip names), never on
# the motion: measuring one clip asks for them a dozen times, and a library shares a few rigs.
_RIG_MEMO: dict[Hashable, object] = {}
_RIG_MEMO_SIZE = 4096


def rig_memo(kind: str, clip: Clip, settings: RigSettings, compute: Callable[[], _T], *extra: Hashable) -> _T:
    """``compute()``, remembered per rig: joint names, parents, whether there is a hierarchy, the
    manifest's hip names and ``extra`` (whatever else the answer depends on). A ``compute`` that
    raises (a joint the manifest names is missing) is not remembered: the next clip raises too,
    with its own name in the message."""
    skeleton = clip.skeleton
    key = (
        kind,
        tuple(skeleton.names),
        tuple(skeleton.parents),
        skeleton.has_hierarchy,
        settings.left_hip,
        settings.right_hip,
        *extra,
    )
    if skeleton.has_hierarchy and find_hips(skeleton) is None:
        # Hips found by the rest pose's shape (`body_shape`): rigs that share numbered names
        # (`joint_01`...) and parents may still be other bodies, and the legs are the chains the
        # take moves where the rest pose is a posed frame (every kind that builds on the hips).
        key += (skeleton.rest_translations.tobytes(), skeleton.rest_rotations.tobytes(), still_joints(clip))
    try:
        return cast(_T, _RIG_MEMO[key])
    except KeyError:
        pass
    value = compute()
    if len(_RIG_MEMO) >= _RIG_MEMO_SIZE:
        _RIG_MEMO.clear()
    _RIG_MEMO[key] = value
    return value


def _joint(clip: Clip, name: str, what: str) -> int:
    try:
        return clip.skeleton.index(name)
    except ValueError:
        import difflib

        close = difflib.get_close_matches(name, clip.skeleton.names, n=3)
        suggestion = f"did you mean {', '.join(repr(c) for c in close)}? " if close else ""
        raise ClipReadError(
            f"clip {clip.name!r} has no joint {name!r} (skeleton.{what} in the manifest)",
            path=clip.source,
            hint=f"{suggestion}joints: {', '.join(clip.skeleton.names[:12])}"
            + (" …" if clip.skeleton.joint_count > 12 else ""),
        ) from None


def hip_pair(clip: Clip, settings: RigSettings) -> tuple[int, int] | None:
    return rig_memo("hip_pair", clip, settings, lambda: _hip_pair(clip, settings))


def _hip_pair(clip: Clip, settings: RigSettings) -> tuple[int, int] | None:
    if settings.left_hip != "auto" and settings.right_hip != "auto":
        return _two_hips(
            clip, _joint(clip, settings.left_hip, "left_hip"), _joint(clip, settings.right_hip, "right_hip")
        )
    if not clip.skeleton.has_hierarchy:
        return None
    found = find_hips(clip.skeleton)
    if found is None:
        shaped = shape_hips(clip, settings)
        if shaped is None:
            return None
        found = (shaped.left, shaped.right)
    left, right = found
    if settings.left_hip != "auto":
        left = _joint(clip, settings.left_hip, "left_hip")
    if settings.right_hip != "auto":
        right = _joint(clip, settings.right_hip, "right_hip")
    return _two_hips(clip, left, right)


def shape_hips(clip: Clip, settings: RigSettings) -> ShapeHips | None:
    """The hips by the skeleton's shape (`body_shape`), when no joint names say left and right."""
    if not clip.skeleton.has_hierarchy or find_hips(clip.skeleton) is not None:
        return None
    return rig_memo(
        "shape_hips",
        clip,
        settings,
        lambda: hips_by_shape(clip.skeleton, rest_positions(clip.skeleton), still=still_joints(clip)),
    )


# The last clip `still_joints` looked at, and its answer: `measure` asks for one clip several
# times (every rig memo of a nameless rig), at the cost of a pass over the whole take each.
_last_still: tuple[weakref.ref[Clip], frozenset[int]] | None = None


def still_joints(clip: Clip) -> frozenset[int]:
    """Joints whose local transforms never change over ``clip``: rotations to 1e-6 (q and -q are
    one rotation), translations to 1e-5 of the rig's longest offset (an FBX bake leaves 1e-5 cm
    of noise on static bones). Empty for a clip of one frame: nothing tells."""
    global _last_still
    if _last_still is not None and _last_still[0]() is clip:
        return _last_still[1]
    still: frozenset[int] = frozenset()
    if clip.frame_count >= 2:
        scale = float(np.abs(clip.skeleton.rest_translations).max(initial=0.0)) or 1.0
        # Each key in the first key's hemisphere, so that q and -q do not count as a turn.
        signs = np.where(np.sum(clip.rotations * clip.rotations[:1], axis=-1) < 0.0, -1.0, 1.0)
        turned = np.ptp(clip.rotations * signs[..., None], axis=0).max(axis=1) > 1e-6
        moved = np.ptp(clip.translations, axis=0).max(axis=1) > 1e-5 * scale
        still = frozenset(int(j) for j in np.flatnonzero(~(turned | moved)))
    _last_still = (weakref.ref(clip), still)
    return still


def _two_hips(clip: Clip, left: int, right: int) -> tuple[int, int]:
    """(left, right), refused when both name one joint: its hip line is no line, and a walk read
    1.2 m/s straight ahead by an accident of the zero vector's angle."""
    if left == right:
        raise ClipReadError(
            f"clip {clip.name!r}: skeleton.left_hip and skeleton.right_hip both name {clip.skeleton.names[left]!r}",
            path=clip.source,
            hint="name the two hip joints, or leave them auto",
        )
    return left, right


# Up axes as signed axis names; measurement works in any of them (Y-up, Z-up and their negatives).
UP_VECTORS = {
    "y": np.array([0.0, 1.0, 0.0]),
    "z": np.array([0.0, 0.0, 1.0]),
    "x": np.array([1.0, 0.0, 0.0]),
    "-y": np.array([0.0, -1.0, 0.0]),
    "-z": np.array([0.0, 0.0, -1.0]),
    "-x": np.array([-1.0, 0.0, 0.0]),
}
# The body's up (head over hips over feet, averaged over the take) must lie this close to one
# axis (cosine) for the axis to count as detected: a walk leans a few degrees, a run about 10-15,
# far inside this; a rig lying down or a wrong head guess falls below it and is reported.
_UP_CONFIDENT_COS = 0.8
_HEAD_BASES = ("head", "neck", "chest", "spine")
_FOOT_BASES = ("foot", "ankle")


def up_vector(up_axis: str) -> FloatArray:
    return UP_VECTORS[up_axis]


def _named_below(clip: Clip, joint: int, bases: tuple[str, ...]) -> int | None:
    """The first descendant of ``joint`` whose base name (side token removed) holds a base of
    ``bases``, trying the bases in order."""
    below = clip.skeleton.descendants(joint)
    for wanted in bases:
        for j in below:
            if wanted in split_side(clip.skeleton.names[j])[1]:
                return j
    return None


def _lowest_common_ancestor(clip: Clip, a: int, b: int) -> int | None:
    parents = clip.skeleton.parents
    chain = set()
    while a >= 0:
        chain.add(a)
        a = parents[a]
    while b >= 0:
        if b in chain:
            return b
        b = parents[b]
    return None


@dataclass(frozen=True)
class BodyJoints:
    """The joints the up axis and the unit are read from: hip sockets, feet, and a head (or the
    top of the spine), found from the hierarchy and the names, never from where joints are."""

    hips: tuple[int, int]
    feet: tuple[int, int]
    head: int | None


def body_joints(clip: Clip, settings: RigSettings) -> BodyJoints | None:
    return rig_memo("body_joints", clip, settings, lambda: _body_joints(clip, settings))


def _body_joints(clip: Clip, settings: RigSettings) -> BodyJoints | None:
    if not clip.skeleton.has_hierarchy:
        return None
    hips = hip_pair(clip, settings)
    if hips is None:
        return None
    feet = []
    rest = rest_positions(clip.skeleton) if shape_hips(clip, settings) is not None else None
    for hip in hips:
        foot = _named_below(clip, hip, _FOOT_BASES)
        if foot is None and rest is not None:  # the shape's own reading of the leg: its ankle
            leg = leg_chain(clip.skeleton, hip, rest)
            ankle = ankle_of(leg, rest)
            foot = leg[ankle] if ankle is not None else None
        if foot is None:
            below = clip.skeleton.descendants(hip)
            if not below:
                return None
            # The deepest joint of the leg: the end of its longest chain.
            foot = max(below, key=lambda j: _depth_below(clip, j, hip))
        feet.append(foot)
    head = None
    pelvis = _lowest_common_ancestor(clip, hips[0], hips[1])
    if pelvis is not None:
        head = _named_below(clip, pelvis, _HEAD_BASES)
        if head is not None and head in clip.skeleton.descendants(hips[0]) + clip.skeleton.descendants(
            hips[1]
        ):
            head = None
    return BodyJoints(hips=(hips[0], hips[1]), feet=(feet[0], feet[1]), head=head)


def _depth_below(clip: Clip, joint: int, ancestor: int) -> int:
    depth = 0
    while joint not in (ancestor, -1):
        joint = clip.skeleton.parents[joint]
        depth += 1
    return depth


def _chain_length(clip: Clip, world_pos: FloatArray, top: int, bottom: int) -> float:
    """Median over frames of the summed bone lengths from ``bottom`` up to ``top``: the limb's
    length whatever its pose, its place in the world or the up axis."""
    total = np.zeros(len(world_pos))
    joint = bottom
    parents = clip.skeleton.parents
    while joint != top and parents[joint] >= 0:
        parent = parents[joint]
        total += quat.vector_norm(world_pos[:, joint] - world_pos[:, parent])
        joint = parent
    return stats.median(total)


def detect_up(
    clip: Clip, world_pos: FloatArray, settings: RigSettings, *, legs_only: bool = False
) -> tuple[str, float, str] | None:
    """(signed up axis, confidence 0..1, evidence) from the body, or None without a body.

    The body's up is the feet-to-hips direction plus the hips-to-head direction, each a unit
    vector per frame, averaged over the take. Joints outside the body (a static top joint far
    away, props) play no part, nor does where the character stands or which way it faces; a
    T-pose, an A-pose or a mid-stride first frame all have the legs below and the head above.
    """
    body = body_joints(clip, settings)
    if body is None:
        return None
    hip_mid = 0.5 * (world_pos[:, body.hips[0]] + world_pos[:, body.hips[1]])
    feet_mid = 0.5 * (world_pos[:, body.feet[0]] + world_pos[:, body.feet[1]])
    parts = [hip_mid - feet_mid]
    if body.head is not None and not legs_only:
        parts.append(world_pos[:, body.head] - hip_mid)
    total = np.zeros(3)
    for part in parts:
        length = quat.vector_norm(part)[:, None]
        total += (part / np.where(length > 0.0, length, 1.0)).mean(axis=0)
    norm = float(np.linalg.norm(total))
    if norm <= 1e-9:
        return None
    direction = total / norm
    axis = int(np.argmax(np.abs(direction)))
    sign = "" if direction[axis] > 0 else "-"
    name = sign + "xyz"[axis]
    confidence = float(abs(direction[axis]))
    angle = float(np.degrees(np.arccos(min(1.0, confidence))))
    names = clip.skeleton.names
    via = f"feet ({names[body.feet[0]]}) to hips" + (
        f" to {names[body.head]}" if body.head is not None and not legs_only else ""
    )
    return name, confidence, f"body up ({via}) is {angle:.0f} deg from {name.upper()}"


def resolve_up(clip: Clip, world_pos: FloatArray, settings: RigSettings) -> tuple[str, str | None]:
    """(signed up axis, note or None); see `resolve_up_guess` for the guess it may be."""
    up, note, _guess = resolve_up_guess(clip, world_pos, settings)
    return up, note


def resolve_up_guess(
    clip: Clip, world_pos: FloatArray, settings: RigSettings
) -> tuple[str, str | None, DetectionGuess | None]:
    if settings.up != "auto":
        confirmed = clip.up_axis == settings.up  # the file says so too (USD `upAxis`)
        return (
            settings.up,
            None,
            None if confirmed else _doubt_stated_up(clip, world_pos, settings, settings.up),
        )
    if clip.up_axis is not None:  # the file says (USD `upAxis`, glTF +Y, FBX axis settings)
        return clip.up_axis, None, _doubt_stated_up(clip, world_pos, settings, clip.up_axis, "file")
    found = detect_up(clip, world_pos, settings)
    if found is not None:
        up, confidence, evidence = found
        note = f"up axis detected as {up.upper()} from the body: {evidence}"
        if confidence >= _UP_CONFIDENT_COS:
            return up, note, None
        return up, note, DetectionGuess("up axis", up.upper(), evidence, "skeleton: {up: y} or {up: z}")
    # No recognisable body: a standing character is taller than it is deep (its extent along Y
    # and Z; arms in a T-pose lie along X in both conventions, so X is left out).
    frame = world_pos[min(1, len(world_pos) - 1)]
    extent = frame.max(axis=0) - frame.min(axis=0)
    up = "z" if extent[2] > extent[1] else "y"
    evidence = f"no hips or feet recognised; the joints spread most along {up.upper()}"
    return (
        up,
        f"up axis guessed as {up.upper()} from the joints' spread",
        DetectionGuess("up axis", up.upper(), evidence, "skeleton: {up: y} or {up: z}"),
    )


def _doubt_stated_up(
    clip: Clip, world_pos: FloatArray, settings: RigSettings, stated: str, whose: str = "manifest"
) -> DetectionGuess | None:
    """A guess when the up axis the manifest (`skeleton.up`) or the file states contradicts a
    body that stands clearly along another axis (a top-level `up: z` copied onto a Y-up take read
    a straight walk as 59.7 deg sideways; a GLB exported from Blender with "+Y Up" off read every
    walk at 0 m/s): the stated axis is still used, and the finding says what the body reads."""
    # A file's axis is doubted on the legs alone (feet below hips): a quadruped's head is ahead of
    # its hips, not above them (the Khronos Fox read Z up with its head counted).
    found = detect_up(clip, world_pos, replace(settings, up="auto"), legs_only=whose == "file")
    if found is None:
        return None
    up, confidence, evidence = found
    if confidence < _UP_CONFIDENT_COS or up == stated:
        return None
    return DetectionGuess(
        "up axis",
        f"{stated.upper()} (the {whose}'s)",
        f"the body reads {up.upper()} up: {evidence}",
        f"skeleton: {{up: {up}}}"
        if up in ("y", "z")
        else f"re-export it Y or Z up (the body stands along {up.upper()})",
        stated=True,
    )


def resolve_root(clip: Clip, settings: RigSettings, world_pos: FloatArray) -> RootPoint:
    """The point whose ground track is the root motion. ``world_pos``: the clip's forward
    kinematics (F, J, 3), to check a stated root and to find a fallback that moves."""
    if settings.root != "auto":
        joint = _joint(clip, settings.root, "root")
        return RootPoint(
            label=clip.skeleton.names[joint],
            positions=lambda p: p[:, joint],
            guess=_doubt_stated_root(clip, settings, world_pos, joint),
        )
    hips = hip_pair(clip, settings)
    if hips is not None:
        left, right = hips
        names = clip.skeleton.names
        return RootPoint(
            label=f"hip midpoint ({names[left]}, {names[right]})",
            positions=lambda p: 0.5 * (p[:, left] + p[:, right]),
        )
    joint = fallback_root_joint(clip, world_pos)
    name = clip.skeleton.names[joint]
    guess = None
    if clip.skeleton.has_hierarchy:  # a flat track set (Godot) has its root motion on that joint by design
        guess = DetectionGuess(
            "root",
            name,
            "no left/right hip joints recognised in the joint names",
            "skeleton: {left_hip: <joint>, right_hip: <joint>} or {root: <joint>}",
        )
    return RootPoint(
        label=name,
        positions=lambda p: p[:, joint],
        notes=[f"no hip joints recognised: root motion measured on joint {name!r}"],
        guess=guess,
    )


def named_root_joint(clip: Clip) -> int:
    """A joint literally called root if there is one, else the first root of the hierarchy: the
    joint whose axes a stated `skeleton.forward` names when `skeleton.root` is not set."""
    lowered = [name.lower() for name in clip.skeleton.names]
    named = next((lowered.index(c) for c in ("root", "root_jnt", "rootjoint") if c in lowered), None)
    return 0 if named is None else named


def fallback_root_joint(clip: Clip, world_pos: FloatArray) -> int:
    """Without hips: `named_root_joint`, unless that joint never moves while the body does (a
    static top joint at the origin: MikuMikuDance's `全ての親`, a MotionBuilder reference); then
    the highest joint that moves. A property of the rig, not of the take: a static reference is
    static in every take, so an idle or in-place take of the rig gets the same joint as a walk
    (a ground-level root-motion joint moves or turns in a take that goes anywhere)."""
    chosen = named_root_joint(clip)
    if not clip.skeleton.has_hierarchy or len(world_pos) < 2:
        return chosen
    extent = _extent(world_pos)
    still = 1e-4 * _body_size(world_pos)
    if extent[chosen] > still or not (extent > still).any():
        return chosen
    moving = [j for j in range(clip.skeleton.joint_count) if extent[j] > still]
    return min(moving, key=lambda j: (_depth_below(clip, j, -1), j))


def _extent(world_pos: FloatArray) -> FloatArray:
    """(J,) how far each joint gets from where it starts over the take (file units): what a
    walk's travel shows and an in-place take's sway and bob barely do."""
    extent: FloatArray = quat.vector_norm(world_pos - world_pos[:1]).max(axis=0)
    return extent


def _body_size(world_pos: FloatArray) -> float:
    frame = world_pos[len(world_pos) // 2]
    return float(np.max(frame.max(axis=0) - frame.min(axis=0)))


def _doubt_stated_root(
    clip: Clip, settings: RigSettings, world_pos: FloatArray, joint: int
) -> DetectionGuess | None:
    """A guess when the manifest's `skeleton.root` stays put while the hips (or the body) get
    somewhere (a dataset's static `joint_Root` at the origin read a 1.4 m/s walk as standing
    still): still used. An in-place take, whose hips only sway and bob, is not doubted."""
    if not clip.skeleton.has_hierarchy or len(world_pos) < 2:
        return None
    extent = _extent(world_pos)
    hips = hip_pair(clip, settings)
    body = float(np.mean(extent[list(hips)])) if hips is not None else float(np.median(extent))
    if body <= _TRAVELS * _body_size(world_pos) or extent[joint] >= 0.1 * body:
        return None
    name = clip.skeleton.names[joint]
    if hips is not None:
        via, override = (
            "the hips",
            "skeleton: {root: auto} (the hip midpoint), or the joint that carries the motion",
        )
    else:
        via, override = "the body", "skeleton: {root: <the joint that carries the motion>}"
    return DetectionGuess(
        "root",
        f"{name} (the manifest's)",
        f"{name} gets {100.0 * extent[joint] / body:.0f} % as far from where it starts as {via} over the take",
        override,
        stated=True,
    )


# A take gets somewhere when its hips get this share of the body's size from where they start:
# a 7 s walk gets metres, an in-place cycle's sway and bob a few centimetres.
_TRAVELS = 0.25


def _doubt_stated_hips(clip: Clip, hips: tuple[int, int]) -> DetectionGuess | None:
    """A guess when the manifest's `left_hip` / `right_hip` are the pair the joint names give,
    swapped: the hip line then faces backwards and a walk reads -1.2 m/s at 180 deg."""
    named = find_hips(clip.skeleton) if clip.skeleton.has_hierarchy else None
    if named is None or (hips[1], hips[0]) != named:
        return None
    names = clip.skeleton.names
    return DetectionGuess(
        "facing",
        f"backwards (left_hip {names[hips[0]]}, right_hip {names[hips[1]]}, the manifest's)",
        f"the joint names make {names[named[0]]} the left hip and {names[named[1]]} the right one",
        f"skeleton: {{left_hip: {names[named[0]]}, right_hip: {names[named[1]]}}}",
        stated=True,
    )


def resolve_facing(
    clip: Clip,
    settings: RigSettings,
    up_axis: str,
    posed: tuple[FloatArray, FloatArray],
    *,
    check_legs: bool = True,
) -> Facing:
    """Which way the character faces, per frame. ``posed``: the clip's forward kinematics
    (rotations, positions), against which the choice is checked: the feet point forward on every
    rig, so a hip line whose left and right are swapped (in the names, or by a mirrored export)
    is turned round, and a stated `forward:` that the body contradicts is doubted.
    ``check_legs=False``: not checked, when the up axis is itself in doubt (`measure` knows): the
    legs read along a wrong ground plane say nothing about left and right."""
    up = up_vector(up_axis)
    hips = hip_pair(clip, settings) if settings.forward == "auto" else None
    if hips is not None:
        return _hip_line_facing(clip, settings, up, posed[1], hips, check_legs)
    if settings.root != "auto":
        joint = _joint(clip, settings.root, "root")
    elif settings.forward != "auto":  # "the root joint's forward axis": the same joint in every take
        joint = named_root_joint(clip)
    else:
        joint = fallback_root_joint(clip, posed[1])
    name = clip.skeleton.names[joint]
    if settings.forward != "auto":
        axis_name = settings.forward
        vectors = _joint_axis(joint, axis_name)
        guess = _doubt_stated_forward(clip, settings, up, posed, joint, axis_name)
        return Facing(label=f"{name} axis {axis_name}", vectors=vectors, guess=guess)
    axis_name, vertical = _horizontal_axis(posed[0][:, joint], up, "-y" if up_axis == "z" else "+z")
    # A flat track set (Godot) too: its root track's forward axis is a convention the file does
    # not state, and left and right swap with it (a strafe's sign).
    evidence = (
        "no hip line to face by (no left/right hips recognised)"
        if clip.skeleton.has_hierarchy
        else "no hip line to face by (animation tracks without the skeleton's hierarchy)"
    )
    if vertical is not None:
        evidence += f"; its {vertical} axis, the usual forward, points along the up axis"
    return Facing(
        label=f"{name} axis {axis_name}",
        vectors=_joint_axis(joint, axis_name),
        notes=[
            f"facing taken from joint {name!r} axis {axis_name} (assumed); "
            "set `skeleton.forward` if the character faces another way"
        ],
        guess=DetectionGuess(
            "facing",
            f"{name} {axis_name}",
            evidence,
            "skeleton: {forward: +z} (the root joint's forward axis) or name the hips",
        ),
    )


# The legs contradict (or confirm) a facing when they agree with it, on average over the take,
# below minus (above) this cosine: 120 (60) degrees apart.
_LEGS_AGREE = 0.5


@dataclass(frozen=True)
class LegsSay:
    """How the legs agree with a facing (mean cosines, see `_agreement`); None where the take
    shows no such evidence. ``knees``: the way the knees stick out from their hip-to-ankle lines,
    forward on every human leg that bends, standing, walking, kneeling or sitting on the heels.
    ``toes``: ankle to toe, forward while the foot is on its sole (not when kneeling on the
    insteps): the witness when the knees stay straight, and a second one for stated values."""

    knees: float | None
    toes: float | None

    @property
    def main(self) -> float | None:
        return self.knees if self.knees is not None else self.toes

    def reversed(self) -> bool:
        """The legs say the facing points backwards (the toes do not say otherwise)."""
        main = self.main
        return (
            main is not None
            and main < -_LEGS_AGREE
            and not (self.toes is not None and self.toes > _LEGS_AGREE)
        )

    def contradicted(self) -> bool:
        """Strong enough to doubt a value the manifest states: bent knees say backwards, and the
        toes (when the rig has them) do not say forward."""
        return (
            self.knees is not None
            and self.knees < -_LEGS_AGREE
            and not (self.toes is not None and self.toes > 0)
        )

    def confirmed(self) -> bool:
        main = self.main
        return main is not None and main > _LEGS_AGREE


def legs_say(
    clip: Clip, settings: RigSettings, world_pos: FloatArray, up: FloatArray, facing: FloatArray
) -> LegsSay:
    """`LegsSay` of ``facing`` (F, 3) on the take ``world_pos`` (both sampled alike)."""
    knees = knees_forward(clip, settings, world_pos, up)
    toes = feet_forward(clip, settings, world_pos, up)
    return LegsSay(
        _agreement(knees, facing) if knees is not None else None,
        _agreement(toes, facing) if toes is not None else None,
    )


def _hip_line_facing(
    clip: Clip,
    settings: RigSettings,
    up: FloatArray,
    world_pos: FloatArray,
    hips: tuple[int, int],
    check_legs: bool = True,
) -> Facing:
    left, right = hips
    names = clip.skeleton.names
    stated = settings.left_hip != "auto" or settings.right_hip != "auto"
    sampled = _sampled(world_pos)
    hip_line = quat.cross(sampled[:, left] - sampled[:, right], up)
    legs = legs_say(clip, settings, sampled, up, hip_line) if check_legs else LegsSay(None, None)
    shaped = None if stated else shape_hips(clip, settings)
    if shaped is not None:
        return _shape_facing(clip, up, shaped, legs, check_legs)
    swapped = f"skeleton: {{left_hip: {names[right]}, right_hip: {names[left]}}}"
    if legs.reversed() and not stated:
        # The legs say the hip line faces backwards: the joint named left is on the character's
        # right. Measured facing the legs' way; a swapped pair in the manifest confirms it.
        def reversed_hip_line(_rot: FloatArray, pos: FloatArray) -> FloatArray:
            return quat.cross(pos[:, right] - pos[:, left], up)

        evidence = (
            f"the {_witness(legs)} point {_degrees(legs.main or 0.0):.0f} deg away from the way the hip line "
            f"faces: {names[left]} is on the character's right. Either the joint names swap left and right "
            "(now read right), or the export is mirrored (its turns and sidesteps then read with the "
            "wrong sign: check a turning clip)"
        )
        return Facing(
            label="hip line, reversed (the legs face the other way)",
            vectors=reversed_hip_line,
            notes=[f"facing: {evidence}; measured facing the way the legs do"],
            guess=DetectionGuess("facing", "the way the legs face", evidence, swapped),
        )

    def from_hip_line(_rot: FloatArray, pos: FloatArray) -> FloatArray:
        return quat.cross(pos[:, left] - pos[:, right], up)

    if not check_legs:  # the up axis is in doubt: nothing here is read, nothing doubted
        return Facing(label="hip line", vectors=from_hip_line)
    guess = None
    if stated and legs.contradicted():
        guess = DetectionGuess(
            "facing",
            f"backwards (left_hip {names[left]}, right_hip {names[right]}, the manifest's)",
            f"the {_witness(legs)} point {_degrees(legs.main or 0.0):.0f} deg away from the way this hip line faces",
            swapped,
            stated=True,
        )
    elif stated and not legs.confirmed():  # the body cannot settle it: the names can
        guess = _doubt_stated_hips(clip, hips)
    return Facing(label="hip line", vectors=from_hip_line, guess=guess)


def _shape_facing(clip: Clip, up: FloatArray, shaped: ShapeHips, legs: LegsSay, check_legs: bool) -> Facing:
    """The facing of hips found by the skeleton's shape (`body_shape`): the rest pose's toes tell
    left from right, or else the legs' motion; the knees over the take have the last word, as
    they have over joint names. A guess when neither tells, or when the two disagree."""
    names = clip.skeleton.names
    left, right = shaped.left, shaped.right
    by = "the toes of the rest pose" if shaped.sided else ""
    guess_evidence = ""
    if check_legs and legs.reversed():
        left, right = right, left
        by = f"the {_witness(legs)} over the take"
        if shaped.sided:
            guess_evidence = f"the rest pose's toes and the {_witness(legs)} over the take disagree"
    elif check_legs and not shaped.sided:
        if legs.confirmed():
            by = f"the {_witness(legs)} over the take"
        else:
            guess_evidence = "neither the rest pose's toes nor the legs' motion show which hip is the left"
    elif not shaped.sided:
        guess_evidence = "the rest pose has no toes to tell left from right, and the up axis is in doubt"
    note = (
        f"hips found by the skeleton's shape (no joint names say left and right): {names[left]} the left, "
        f"{names[right]} the right" + (f", told apart by {by}" if by and not guess_evidence else "")
    )
    if not shaped.sided:
        # The rig's order stands for every clip (each clip's knees decide its own facing only):
        # foot contacts and sync markers say left for the leg the file lists first.
        note += (
            f"; foot contacts and markers name {names[shaped.left]}'s foot left, as the file lists it "
            "first (the rest pose has no toes to tell)"
        )
    guess = None
    if guess_evidence:
        guess = DetectionGuess(
            "facing",
            f"left hip {names[left]}, right hip {names[right]}",
            guess_evidence,
            f"skeleton: {{left_hip: {names[left]}, right_hip: {names[right]}}} (or the other way round)",
        )

    def from_hip_line(_rot: FloatArray, pos: FloatArray) -> FloatArray:
        return quat.cross(pos[:, left] - pos[:, right], up)

    return Facing(
        label="hip line (hips by the skeleton's shape)", vectors=from_hip_line, notes=[note], guess=guess
    )


def _witness(legs: LegsSay) -> str:
    return "knees" if legs.knees is not None else "toes"


def _doubt_stated_forward(
    clip: Clip,
    settings: RigSettings,
    up: FloatArray,
    posed: tuple[FloatArray, FloatArray],
    joint: int,
    axis_name: str,
) -> DetectionGuess | None:
    """A guess when the manifest's `skeleton.forward` points away from where the body faces
    (`_body_forward`): LAFAN1's Hips +Z is the character's left, and `forward: +z` read a walk as
    a sidestep. Still used."""
    world_rot, world_pos = _sampled(posed[0]), _sampled(posed[1])
    body = _body_forward(clip, replace(settings, forward="auto"), up, world_pos)
    if body is None:
        return None
    forward, via = body
    # How each of the joint's axes agrees with the body (the stated one among them).
    scores = {
        candidate: _agreement(_along_ground(_joint_axis(joint, candidate)(world_rot, world_pos), up), forward)
        for candidate in _AXIS_VECTORS
    }
    agree = scores[axis_name]
    if agree is None or agree >= _LEGS_AGREE:
        return None
    best = max(scores, key=lambda candidate: scores[candidate] or -2.0)
    name = clip.skeleton.names[joint]
    override = (
        f"skeleton: {{forward: {best}}}"
        if (scores[best] or -2.0) > 1.0 - _LEGS_AGREE
        else "drop skeleton.forward (the hip line)"
    )
    return DetectionGuess(
        "facing",
        f"{name} {axis_name} (the manifest's)",
        f"the body ({via}) faces {_degrees(agree):.0f} deg away from the {axis_name} axis of {name}",
        override,
        stated=True,
    )


def _body_forward(
    clip: Clip, settings: RigSettings, up: FloatArray, world_pos: FloatArray
) -> tuple[FloatArray, str] | None:
    """(F, 3) where the body faces along the ground, and what says so: the hip line (reversed
    when bent knees contradict it, see `LegsSay.contradicted`); None without recognisable hips.
    What a stated value is checked against: the toes alone never doubt one."""
    hips = hip_pair(clip, settings)
    if hips is None:
        return None
    hip_line = _along_ground(quat.cross(world_pos[:, hips[0]] - world_pos[:, hips[1]], up), up)
    if legs_say(clip, settings, world_pos, up, hip_line).contradicted():
        return -hip_line, "the hip line, reversed by the legs"
    return hip_line, "the hip line"


def knees_forward(
    clip: Clip, settings: RigSettings, world_pos: FloatArray, up: FloatArray
) -> FloatArray | None:
    """(F, 3) how far the knees stick out from their hip-to-ankle lines, both legs summed, along
    the ground (file units; a straight leg adds nothing, a twist joint on the line neither); None
    for a rig without recognisable legs or without a joint between hip and ankle."""
    body = body_joints(clip, settings)
    if body is None:
        return None
    parents = clip.skeleton.parents
    total = np.zeros((len(world_pos), 3))
    found = False
    for hip, foot in zip(body.hips, body.feet, strict=True):
        chain = []
        joint = parents[foot]
        while joint >= 0 and joint != hip:
            chain.append(joint)
            joint = parents[joint]
        if joint != hip or not chain:
            continue
        line = world_pos[:, foot] - world_pos[:, hip]
        length = quat.vector_norm(line)[:, None]
        line = line / np.where(length > 0.0, length, 1.0)
        for knee in chain:
            out = world_pos[:, knee] - world_pos[:, hip]
            total += out - (out * line).sum(axis=1)[:, None] * line
        found = True
    return _along_ground(total, up) if found else None


def toe_of(clip: Clip, foot: int) -> int | None:
    """The joint the foot points to: a child named toe (or ball), else its child that is not a
    heel (of several, the one reaching farthest in the rest pose); None when the foot ends the
    chain (its toe is only a BVH End Site)."""
    names = clip.skeleton.names
    below = [c for c in clip.skeleton.children(foot) if "heel" not in split_side(names[c])[1]]
    toes = [c for c in below if any(t in split_side(names[c])[1] for t in ("toe", "ball"))]
    if toes or len(below) < 2:
        found = toes or below
        return found[0] if found else None
    # Names that say nothing (`Bone.012`): the child reaching farthest from the ankle in the rest
    # pose; a heel bone listed first had been taken for the toe, and the toes then vetoed the knees.
    rest = rest_positions(clip.skeleton)
    skeleton = clip.skeleton
    return max(
        below,
        key=lambda c: float(np.linalg.norm(rest[[c, *skeleton.descendants(c)]] - rest[foot], axis=1).max()),
    )


def feet_forward(
    clip: Clip, settings: RigSettings, world_pos: FloatArray, up: FloatArray
) -> FloatArray | None:
    """(F, 3) the two feet's ankle-to-toe vectors summed, along the ground (file units); None
    for a rig without recognisable legs or without toe joints."""
    body = body_joints(clip, settings)
    if body is None or body.feet[0] == body.feet[1]:
        return None
    toes = [toe_of(clip, foot) for foot in body.feet]
    if toes[0] is None or toes[1] is None:
        return None
    total = sum(world_pos[:, toe] - world_pos[:, foot] for toe, foot in zip(toes, body.feet, strict=True))
    return _along_ground(np.asarray(total), up)


def _sampled(world_pos: FloatArray) -> FloatArray:
    """About 200 frames of the take, evenly spaced: which way the feet point is a take's average
    (a 7 s take at 120 fps: 0.28 ms per clip on every frame, a fifth of that on these)."""
    return world_pos[:: max(1, len(world_pos) // 200)]


def _along_ground(vectors: FloatArray, up: FloatArray) -> FloatArray:
    flat: FloatArray = vectors - (vectors @ up)[:, None] * up
    return flat


def _agreement(a: FloatArray, b: FloatArray) -> float | None:
    """Mean cosine between ``a`` and ``b`` (F, 3) over the frames, weighted by ``a``'s length;
    None when ``a`` or ``b`` vanishes on most frames (a foot seen end-on, no hip line)."""
    la, lb = quat.vector_norm(a), quat.vector_norm(b)
    scale = max(float(la.max(initial=0.0)), 1e-12)
    valid = (la > 1e-3 * scale) & (lb > 1e-12)
    if valid.sum() < max(2, len(a) // 2):
        return None
    cosines = np.einsum("ij,ij->i", a[valid], b[valid]) / (la[valid] * lb[valid])
    return float(np.sum(cosines * la[valid]) / np.sum(la[valid]))


def _degrees(cosine: float) -> float:
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def _joint_axis(joint: int, axis_name: str) -> Callable[[FloatArray, FloatArray], FloatArray]:
    axis = np.array(_AXIS_VECTORS[axis_name])

    def from_joint_axis(rot: FloatArray, _pos: FloatArray) -> FloatArray:
        return quat.rotate(rot[:, joint], np.broadcast_to(axis, (len(rot), 3)))

    return from_joint_axis


# The joint axes tried, in order, when the usual forward of a joint (+Z in Y-up files, -Y in
# Z-up ones) points up: a Z-up file whose root keeps Y-up axes (CMU's ASF-named exports).
_FORWARD_ORDER = ("+z", "-y", "+x", "-x", "+y", "-z")


def _horizontal_axis(rotations: FloatArray, up: FloatArray, usual: str) -> tuple[str, str | None]:
    """(the joint axis taken as forward, the usual axis when it had to be passed over as vertical)."""

    def upright(name: str) -> float:
        along = quat.rotate(rotations, np.broadcast_to(_AXIS_VECTORS[name], (len(rotations), 3)))
        return float(np.mean(np.abs(along @ up)))

    if upright(usual) < 0.7:
        return usual, None
    for name in _FORWARD_ORDER:
        if name != usual and upright(name) < 0.5:
            return name, usual
    return usual, None


def hip_height(clip: Clip, world_pos: FloatArray, up_axis: str, root: RootPoint) -> float:
    """Upright height of the root point above the lowest joint (the feet), in file units."""
    up = up_vector(up_axis)
    heights = root.positions(world_pos) @ up - (world_pos @ up).min(axis=1)
    return stats.percentile(heights, _UPRIGHT_PERCENTILE)


def resolve_units(
    clip: Clip,
    world_pos: FloatArray,
    settings: RigSettings,
    up_axis: str,
    root: RootPoint,
) -> tuple[float, str, bool]:
    """(metres per unit, where it came from, whether it is a guess); see `resolve_units_guess`."""
    scale, source, guess = resolve_units_guess(clip, world_pos, settings, up_axis, root)
    return scale, source, guess is not None


def resolve_units_guess(
    clip: Clip,
    world_pos: FloatArray,
    settings: RigSettings,
    up_axis: str,
    root: RootPoint,
) -> tuple[float, str, DetectionGuess | None]:
    """(metres per unit, where it came from, the guess when it is one).

    In order: the manifest, the file (USD `metersPerUnit`, glTF metres), then the body: the leg
    (hip socket to ankle, summed bone lengths, so neither pose nor up axis nor a far-away top
    joint matters) read in each conventional unit (m, cm, mm, inches, CMU's 1/0.45 inch); the
    unit that makes it a human leg wins. Pass the whole, untrimmed clip: a unit estimated per
    range would differ between ranges of one file.
    """
    override = "skeleton: {units: <m|cm|mm|in or metres per unit>}"
    stated = None
    if isinstance(settings.units, float | int) and not isinstance(settings.units, bool):
        stated = float(settings.units), "manifest"
    elif settings.units in UNIT_METERS:
        stated = UNIT_METERS[str(settings.units)], "manifest"
    elif clip.meters_per_unit is not None:
        stated = clip.meters_per_unit, "file"
    body = body_joints(clip, settings)
    if stated is not None:
        # The manifest repeating the file's unit confirms it: that is how a doubt is settled.
        confirmed = (
            stated[1] == "manifest"
            and clip.meters_per_unit is not None
            and (abs(stated[0] / clip.meters_per_unit - 1.0) < 1e-6)
        )
        doubt = None if confirmed else _doubt_stated_unit(clip, world_pos, body, *stated, override)
        return stated[0], stated[1], doubt
    if body is not None:
        leg = _leg_length(clip, world_pos, body)
        if leg > 0.0:
            found = _unit_from_length(leg, REFERENCE_LEG, _PLAUSIBLE_LEG, "leg (hip to ankle)", override)
            return found[0], found[1], found[2] or _doubt_detected_unit(leg, found[0], override)
    if not clip.skeleton.has_hierarchy:
        return 1.0, "assumed metres", DetectionGuess("units", "m", "no skeleton hierarchy to size", override)
    height = hip_height(clip, world_pos, up_axis, root)
    if height <= 0:
        return 1.0, "assumed metres", DetectionGuess("units", "m", "no body to size", override)
    reference = REFERENCE_HIP_HEIGHT - _LOWEST_JOINT_HEIGHT
    return _unit_from_length(height, reference, _PLAUSIBLE_HIP_HEIGHT, "hip height", override)


# A unit read from the legs with less confidence than this (`_unit_from_length`: 0 at the edge of
# an adult's legs in that unit) is a guess: a child's legs in centimetres (0.3 m) read as an
# adult's in inches with confidence 0.3, and its walk at 2.5 times its speed, without a word.
_UNIT_CONFIDENT = 0.5


def _doubt_detected_unit(leg: float, scale: float, override: str) -> DetectionGuess | None:
    """A guess when the legs (``leg`` file units, read as ``scale`` m per unit) are an adult's
    only near the edge of adult legs, or in inches, where centimetres make them a child's or a
    goblin's (`_NO_ADULT_LEG`): a character of half an adult's size in centimetres reads as an
    adult in inches, confidently. Inches are rare in game animation; centimetres are common."""
    metres = leg * scale
    confidence = _confidence(metres, REFERENCE_LEG, _PLAUSIBLE_LEG)
    unit = next((name for name, value in _CONVENTIONS.items() if abs(value / scale - 1.0) < 1e-9), None)
    in_cm = leg * UNIT_METERS["cm"]
    if unit == "in" and in_cm >= _NO_ADULT_LEG[0]:
        return DetectionGuess(
            "units",
            "in",
            f"the legs are {metres:.2f} m long in inches, or {in_cm:.2f} m (a child's) in centimetres",
            "skeleton: {units: in} or {units: cm}",
        )
    if confidence < _UNIT_CONFIDENT:
        return DetectionGuess(
            "units",
            unit or f"{scale:.4g} m per unit",
            f"the legs are {metres:.2f} m long in {unit or 'that unit'}, near the edge of an adult's "
            f"{_PLAUSIBLE_LEG[0]:g}-{_PLAUSIBLE_LEG[1]:g} m (confidence {confidence:.2f})",
            override,
        )
    return None


def _leg_length(clip: Clip, world_pos: FloatArray, body: BodyJoints) -> float:
    """Mean hip socket to ankle length over both legs, in file units (summed bone lengths)."""
    legs = [_chain_length(clip, world_pos, h, f) for h, f in zip(body.hips, body.feet, strict=True)]
    return float(np.mean(legs))


# The file's unit stands unless it makes the legs this far from any body's (toddler to giant
# creature, 0.1-5 m): a DCC export whose scale was applied twice or not at all (100x) is.
_POSSIBLE_LEG = (0.1, 5.0)
# ... or makes them a toddler's or a giant's while a conventional unit makes them an adult's
# (`units: cm` on a CMU take: legs 0.145 m, walks at 0.25 m/s). Between these and `_ADULT_LEG`
# (`units: in` on a CMU take: 0.37 m; inches read as centimetres: 0.32 m) the character may be
# a child or a goblin in its true unit: the clip gets a note (`stated_unit_note`), not a doubt.
_NO_ADULT_LEG = (0.25, 2.5)
_ADULT_LEG = (0.4, 2.0)


def _doubt_stated_unit(
    clip: Clip, world_pos: FloatArray, body: BodyJoints | None, unit: float, whose: str, override: str
) -> DetectionGuess | None:
    """A guess when the unit the manifest or the file states (USD `metersPerUnit`, glTF metres)
    makes the legs no body's: it is still used, and the finding names what the body reads (`cm`
    on a rig in metres, a DCC scale applied twice)."""
    if body is None:
        return None
    leg = _leg_length(clip, world_pos, body) * unit
    if leg <= 0.0:
        return None
    bodily = _unit_from_length(leg / unit, REFERENCE_LEG, _PLAUSIBLE_LEG, "leg", override)
    adult = bodily[2] is None and abs(bodily[0] / unit - 1.0) > 1e-6
    possible = _POSSIBLE_LEG[0] <= leg <= _POSSIBLE_LEG[1]
    if possible and (_NO_ADULT_LEG[0] <= leg <= _NO_ADULT_LEG[1] or not adult):
        return None
    reads = f"; the body reads {bodily[0]:.4g} m per unit" if bodily[2] is None else ""
    if possible:  # an adult's legs in another unit (see `_HUMAN_LEG`): that unit is the advice
        named = next(
            (name for name, scale in UNIT_METERS.items() if abs(scale / bodily[0] - 1.0) < 1e-9), None
        )
        override = f"skeleton: {{units: {named or format(bodily[0], '.6g')}}}"
    return DetectionGuess(
        "units",
        f"{unit:.4g} m per unit (the {whose}'s)",
        f"the {whose}'s unit makes the legs {leg:.3g} m long{reads}",
        override,
        stated=True,
    )


# Faster than any body runs (sprinters peak near 12 m/s): root motion at this speed on legs of an
# adult's length is in another unit than the skeleton (a DCC scale applied to one of them only).
_FASTEST_BODY = 15.0


def root_speed_doubt(
    clip: Clip, world_pos: FloatArray, settings: RigSettings, meters_per_unit: float, speed: float
) -> DetectionGuess | None:
    """A doubt when the root travels faster than any body on legs of an adult's length: Blender's
    "apply transform" on a Mixamo-style armature left its location keys in centimetres under
    bones in metres, and a walk read 140 m/s with 0.82 m legs, with no word but `outside-axis-range`."""
    if abs(speed) <= _FASTEST_BODY:
        return None
    body = body_joints(clip, settings)
    if body is None:
        return None
    leg = _leg_length(clip, world_pos, body) * meters_per_unit
    if not _PLAUSIBLE_LEG[0] <= leg <= _PLAUSIBLE_LEG[1]:
        return None  # the whole clip is off: the unit's own doubt says so
    return DetectionGuess(
        "root",
        f"{abs(speed):.3g} m/s of root motion (the file's)",
        f"no body travels {abs(speed):.3g} m/s on legs {leg:.2f} m long: the root motion is in another unit "
        "than the skeleton (a scale applied to one of them only)",
        "re-export with the scale applied to the animation too",
        stated=True,
    )


def stated_unit_note(clip: Clip, world_pos: FloatArray, settings: RigSettings, unit: float) -> str | None:
    """A note when the manifest's unit makes the legs a child's or a giant's (`_ADULT_LEG`) and
    a conventional unit would make them an adult's: not doubted (a child in its true unit reads
    the same), but said, with the numbers to check."""
    body = body_joints(clip, settings)
    if body is None:
        return None
    leg = _leg_length(clip, world_pos, body) * unit
    if leg <= 0.0 or _ADULT_LEG[0] <= leg <= _ADULT_LEG[1]:
        return None
    scale, _source, guess = _unit_from_length(leg / unit, REFERENCE_LEG, _PLAUSIBLE_LEG, "leg", "")
    if guess is not None or abs(scale / unit - 1.0) < 1e-6:
        return None
    return (
        f"`skeleton.units` makes the legs {leg:.2f} m long; {scale:.4g} m per unit would make them "
        f"{leg / unit * scale:.2f} m (an adult's): check the unit if this is not a child or a giant"
    )


def _confidence(metres: float, reference: float, plausible: tuple[float, float]) -> float:
    """1 at the reference length, falling to 0 at the plausible range's edge (in log scale, where
    the next convention's range begins 2.2x or more away)."""
    low, high = plausible
    edge = np.log(high / reference) if metres >= reference else np.log(reference / low)
    return max(0.0, 1.0 - abs(float(np.log(metres / reference))) / float(edge))


def _unit_from_length(
    length: float, reference: float, plausible: tuple[float, float], what: str, override: str
) -> tuple[float, str, DetectionGuess | None]:
    """The conventional unit that makes ``length`` (file units) a plausible human ``what``.

    Neighbouring conventions differ by at least 2.2x (inch to CMU unit) and adult legs by less
    than that, so at most one unit is plausible; none is a guess (the reference's scale).
    """
    low, high = plausible
    fits = {unit: scale for unit, scale in _CONVENTIONS.items() if low <= length * scale <= high}
    if fits:
        unit = min(fits, key=lambda u: abs(np.log(length * fits[u] / reference)))
        metres = length * fits[unit]
        confidence = _confidence(metres, reference, plausible)
        return fits[unit], f"detected ({unit}: {what} {metres:.2f} m, confidence {confidence:.2f})", None
    scale = reference / length
    override = f"skeleton: {{units: {scale:.4g}}}"
    evidence = (
        f"the {what} is {length:.4g} units: no unit of m, cm, mm, in or CMU makes it "
        f"{low:g}-{high:g} m; assumed {reference:g} m"
    )
    # A giant's or a child's legs in a conventional unit are likelier than an unconventional unit:
    # the advice names that unit first (a 2.5 m ogre in metres was told `units: 0.6667`).
    sized = [
        (name, length * metres)
        for name, metres in UNIT_METERS.items()
        if _NO_ADULT_LEG[0] <= length * metres <= _NO_ADULT_LEG[1] and what.startswith("leg")
    ]
    if sized:
        name, metres = sized[0]
        override = (
            f"skeleton: {{units: {name}}} (legs {metres:.2f} m long) or {{units: {scale:.4g}}} (an adult's)"
        )

    return (
        scale,
        f"guessed from the {what}",
        DetectionGuess("units", f"{scale:.4g} m per unit", evidence, override),
    )


def _pose_joints(clip: Clip, body: BodyJoints | None) -> list[int] | slice | None:
    """The pelvis (the hips' lowest common ancestor) and every joint below it, or None; as a
    slice when they are consecutive (most rigs: the pelvis is the root), which indexes the
    positions without copying them."""
    pelvis = _lowest_common_ancestor(clip, *body.hips) if body is not None else None
    if pelvis is None:
        return None
    joints = [pelvis, *clip.skeleton.descendants(pelvis)]  # ascending: parents come first
    return slice(pelvis, joints[-1] + 1) if joints == list(range(pelvis, joints[-1] + 1)) else joints


def _length(components: FloatArray) -> FloatArray:
    """Lengths of vectors stored component-major ((3, ...) arrays): `quaternions.vector_norm`'s
    sum in the same order."""
    x, y, z = components
    length: FloatArray = np.sqrt(x * x + y * y + z * z)
    return length


def detect_tpose_frame(clip: Clip, world_pos: FloatArray, settings: RigSettings) -> bool:
    """True when the first frame should be dropped as a rest/T-pose frame.

    A rest frame stands out as a jump: the pose (the body's joints relative to the hips)
    changes far more between frames 0 and 1 than between any later consecutive frames. Joints
    above the pelvis (a static top joint, perhaps metres away) are no part of the pose.
    """
    if settings.tpose == "keep" or clip.frame_count < 4:
        return False
    if settings.tpose == "drop":
        return True
    if not clip.skeleton.has_hierarchy:
        return False
    body = body_joints(clip, settings)
    joints = rig_memo("pose_joints", clip, settings, lambda: _pose_joints(clip, body))
    # Component-major (3, F, J): every step below works on whole contiguous arrays; numpy's
    # loops over an inner axis of 3 cost several times the arithmetic (same values either way).
    if body is not None and joints is not None:
        anchor = 0.5 * (world_pos[:, body.hips[0]] + world_pos[:, body.hips[1]])
        points, origin = world_pos[:, joints], anchor[:, None]
    else:
        points, origin = world_pos, world_pos[:, :1]
    local = np.empty((3, *points.shape[:2]))
    np.subtract(np.moveaxis(points, 2, 0), np.moveaxis(origin, 2, 0), out=local)
    change = _length(np.diff(local, axis=1)).mean(axis=1)
    typical = stats.median(change[1:])
    scale = float(_length(local[:, 1]).max()) or 1.0
    if change[0] > max(8.0 * typical, 0.05 * scale):
        return True
    # Heading-free pose: each body joint's distance from the hips. A rest pose (arms out, legs
    # straight) is unlike every frame of the take, however fast the take moves or turns and
    # however the mocap jitters; a take's own first frame is as close to its next as any frame.
    shape = _length(local)  # (F, J)
    steps = np.abs(np.diff(shape, axis=0)).mean(axis=1)
    nearest = float(np.abs(shape[1:] - shape[0]).mean(axis=1).min())
    if nearest > max(5.0 * stats.median(steps[1:]), 0.02 * scale):
        return True
    if clip.frame_count < 8 or change[0] <= 0.02 * scale:
        return False
    # Fast motion (a dash: a stride in 18 frames) moves the limbs almost as far per frame as a
    # T-pose jump, but smoothly: each frame follows from the next three (third differences are
    # tiny) except a rest frame, which does not.
    residual = _length(local[:, :-3] - 3.0 * local[:, 1:-2] + 3.0 * local[:, 2:-1] - local[:, 3:]).mean(
        axis=1
    )
    return bool(residual[0] > 5.0 * stats.percentile(residual[1:], 99))


# A pose counts as held when no joint moves more than this fraction of the body's extent (3 um on
# an adult; float32 storage of a held key varies it by 0.1 um): the same key evaluated again (a
# DCC's constant extrapolation past the last key, a scene range longer than the action), not an
# actor standing still (mocap noise is ~1 mm). A breathing idle that starts at the top of a breath
# still loses its first few frames at 120 fps (a few um each): harmless, and said.
_HELD_TOLERANCE = 2e-6


# Blender's FBX export simplifies curves by default: a hold becomes a slow straight ramp towards the
# action's first key (0.4 mm a frame on the toes, the same every frame). Frames that move less than
# this fraction of the body's extent a frame (1.7 mm on an adult), and less than `_NEAR_SHARE` of
# the take's moving frames' median step, along a straight line (second differences under
# `_NEAR_BEND` of the extent: 17 um, where mocap jitter is a millimetre) are held too.
_NEAR_STEP = 1e-3
_NEAR_SHARE = 0.02
_NEAR_BEND = 1e-5
# The step out of a ramp is this many times its largest step at least: the action starts at once.
_ABRUPT = 10.0


def held_ends(world_pos: FloatArray) -> tuple[int, int] | None:
    """Frames to leave out at the start and at the end of a take because they repeat the pose
    next to them: ``(leading, trailing)``. The first frame of motion and the last stay (the hold
    starts from, or ends on, that pose). None when every frame holds one pose (a still pose, not
    an animation: nothing is left out).

    Blender exports the scene's frame range, and a 100-frame walk in a 250-frame scene ends in
    6 s of its last pose held; the walk read at 40 % of its speed without a word, and `range:
    auto` kept part of the hold. Even two frames held at each end of a 2 s take at 24 fps read it
    8 % slow, so every held frame goes. A locomotion frame moves far more than the tolerance; the
    slowest motion (an idle's breath at its turning point, at 120 fps) can stay within it for a
    few frames, and those go too (harmless: they hardly move). A hold that Blender's FBX curve
    simplification turned into a slow ramp counts too (`_NEAR_STEP`)."""
    count = len(world_pos)
    if count < 3:
        return 0, 0
    scale = float(np.ptp(world_pos[0], axis=0).max()) or 1.0
    exact, near = _HELD_TOLERANCE * scale, _NEAR_STEP * scale

    def step(a: int, b: int) -> float:
        return float(np.abs(world_pos[a] - world_pos[b]).max())

    # Most takes move more than a near hold between their first two frames and their last two.
    if step(0, 1) > near and step(count - 1, count - 2) > near:
        return 0, 0

    def run(flags: np.ndarray) -> int:
        return int(np.argmin(flags)) if not flags.all() else len(flags)

    # Exact holds: frames that repeat the end frame's pose (measured from it, not frame to frame,
    # so a slow motion's turning point cannot creep along in steps under the tolerance).
    lead = run(np.abs(world_pos[1:] - world_pos[0]).max(axis=(1, 2)) <= exact)
    if lead == count - 1:
        return None
    tail = run(np.abs(world_pos[-2::-1] - world_pos[-1]).max(axis=(1, 2)) <= exact)
    steps = np.abs(np.diff(world_pos, axis=0)).max(axis=(1, 2))  # frame i to i + 1
    moving = steps[steps > near]
    limit = min(near, _NEAR_SHARE * float(np.median(moving))) if len(moving) else 0.0
    if limit > exact:  # a ramp: small steps along a straight line (the bend at each inner frame)
        straight = np.abs(world_pos[2:] - 2.0 * world_pos[1:-1] + world_pos[:-2]).max(axis=(1, 2)) <= (
            _NEAR_BEND * scale
        )
        small = steps <= limit

        def ramp(held: int, ordered: np.ndarray) -> int:
            """``held`` steps of a ramp count when the motion after it starts at once (the
            action's first key); a filtered mocap stand speeds up gradually and stays in."""
            if held == 0 or held >= len(ordered):
                return 0
            return held if ordered[held] >= _ABRUPT * max(float(ordered[:held].max()), exact) else 0

        lead = max(lead, ramp(run(small & np.concatenate([[True], straight])), steps))
        tail = max(tail, ramp(run((small & np.concatenate([straight, [True]]))[::-1]), steps[::-1]))
    if lead + tail >= count - 1:
        return 0, 0  # slow straight motion all along (a drift, no hold to cut it from)
    return lead, tail


@dataclass(frozen=True)
class MotionPart:
    """The frames of a take that `measure` reads: ``first`` to ``stop`` (exclusive), after held
    keys (``held``: the (first, stop) frame spans left out that repeat their neighbour's pose) and
    a leading rest/T-pose frame (``rest_frame``) are left out. ``still``: every frame measured
    holds one pose (nothing left out for it)."""

    first: int
    stop: int
    held: tuple[tuple[int, int], ...] = ()
    rest_frame: bool = False
    still: bool = False

    def notes(self, fps: float) -> list[str]:
        notes = [STILL_NOTE] if self.still else []
        if self.held:
            notes.append(held_note(self.held, fps))
        if self.rest_frame:
            notes.append(REST_FRAME_NOTE)
        return notes


def motion_part(
    clip: Clip, world_pos: FloatArray, settings: RigSettings, *, rest: bool = True, held: bool = True
) -> MotionPart:
    """Which frames of ``clip`` (posed as ``world_pos``) hold its motion (see `MotionPart`);
    ``rest=False``: no rest frame is looked for (a `range:` that starts inside the take);
    ``held=False``: held keys stay (a `range:` the manifest states is measured as stated).

    Held keys are found first: a T-pose held for some frames before the action leaves one rest
    frame, which goes too; a take that stands still after its rest frame (its first key held)
    loses that hold as well."""
    count = clip.frame_count
    if not held:
        rest_frame = rest and detect_tpose_frame(clip, world_pos, settings)
        return MotionPart(int(rest_frame), count, rest_frame=rest_frame)
    ends = held_ends(world_pos)
    if ends is None:
        return MotionPart(0, count, still=True)
    first = ends[0]
    spans = [(0, first)]
    # The rest frame is looked for before a held end is cut: a rest frame followed by one pose held
    # (a pose asset with its bind frame) left two frames, too few to tell, and read a 104 deg/s turn.
    rest_frame = rest and detect_tpose_frame(clip.trimmed(first, count), world_pos[first:], settings)
    if rest_frame:
        first += 1
        after = held_ends(world_pos[first:])
        if after is None:  # the rest frame, then one pose held: a still pose
            return MotionPart(first, count, _spans(spans), True, still=True)
        spans.append((first, first + after[0]))
        first, stop = first + after[0], count - after[1]
    else:
        stop = count - ends[1]
    spans.append((stop, count))
    return MotionPart(first, stop, _spans(spans), rest_frame)


def _spans(spans: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    return tuple(span for span in spans if span[1] > span[0])
