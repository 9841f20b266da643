"""Mirroring a clip across the character's sagittal plane, in world space.

Left and right joints swap (pairs from their names, or given), and every joint's motion is
reflected across the vertical plane through the character's initial position and facing. The
reflection works on world transforms relative to the rest pose, not on local joint axes, so rigs
whose left and right joint axes are not mirror images of each other (Mixamo, many game rigs)
mirror correctly: joint j takes its partner k's world deviation from rest, reflected,
``W'_j = M (W_k B_k^-1) M B_j``, and sits at k's reflected position.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.body_shape import mirror_partners
from blendspace_pipeline.motion.clip import Clip, Skeleton, forward_kinematics, rest_positions
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.root_motion import decompose, ground_basis
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.file_names import safe_file_stem
from blendspace_pipeline.motion.joint_names import find_hips, letter_partner, split_side
from blendspace_pipeline.motion.quaternions import FloatArray

_TRAILING_INDEX = re.compile(r"_\d+$")


# Each pattern's group "side" is the token that names the side; it is swapped, nothing else.
_SIDE_PATTERNS = (
    re.compile(r"(?P<side>Left|Right)"),
    re.compile(r"(?P<side>left|right)"),
    re.compile(r"(?P<side>LEFT|RIGHT)"),
    # Single letters only as a separated token (thigh.L, L_Thigh, hand_r) or a camel prefix (LHand).
    re.compile(r"(?:^|(?<=[._\-\s:|]))(?P<side>[LRlr])(?=$|[._\-\s:|\d])"),
    re.compile(r"^(?:[a-z]+_)?(?P<side>[LR])(?=[A-Z])"),
    re.compile(r"^(?:[A-Za-z0-9]+_)?(?P<side>[LRlr])(?=[A-Z][a-z])"),  # DAZ's lThigh, Skeleton1_LThigh
    re.compile(r"(?P<side>左|右)"),  # MikuMikuDance
)
_OPPOSITE = {
    "Left": "Right", "Right": "Left", "left": "right", "right": "left", "LEFT": "RIGHT", "RIGHT": "LEFT",
    "L": "R", "R": "L", "l": "r", "r": "l", "左": "右", "右": "左",
}  # fmt: skip


def _swapped(name: str) -> list[str]:
    """Candidate partner names: the side token swapped, most specific convention first."""
    found = []
    for pattern in _SIDE_PATTERNS:
        match = pattern.search(name)
        if match:
            start, end = match.span("side")
            found.append(name[:start] + _OPPOSITE[match.group("side")] + name[end:])
    return found


def mirror_pairs(skeleton: Skeleton, overrides: Mapping[str, str] | None = None) -> list[int]:
    """For every joint, the index of its mirror partner (itself for centre joints).

    ``overrides`` maps joint names to partners (from `skeleton.mirror` tokens); otherwise the
    partner is the joint whose name has the side token swapped (`b_LeftLeg01_015` pairs with
    `b_RightLeg01_019`'s sibling only if the names match once swapped, so index suffixes that
    differ by side are matched on the name without its trailing index).
    """
    names = skeleton.names
    index = {n: i for i, n in enumerate(names)}
    partner = list(range(len(names)))
    if overrides:
        for left, right in overrides.items():
            if left in index and right in index:
                partner[index[left]], partner[index[right]] = index[right], index[left]
        return partner
    stripped: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        stripped.setdefault(_TRAILING_INDEX.sub("", name), []).append(i)
    unpaired = []
    known = frozenset(names)
    for i, name in enumerate(names):
        side, _ = split_side(name)
        if not side:
            by_letter = letter_partner(name, known)  # CMU ASF's lfemur / rfemur
            if by_letter is not None:
                partner[i] = index[by_letter]
            continue
        match = next((index[c] for c in _swapped(name) if c in index and c != name), None)
        if match is None:
            # Exporters number joints in hierarchy order (b_LeftLeg01_015 / b_RightLeg01_019).
            base = _TRAILING_INDEX.sub("", name)
            candidates = [j for c in _swapped(base) for j in stripped.get(c, []) if c != base]
            match = candidates[0] if len(candidates) == 1 else None
        # A root joint is the body's centre whatever its name says: Blender names an imported
        # armature after its file (`walk_turn_left`), and the mirror had been refused for it.
        if match is None and skeleton.parents[i] >= 0:
            unpaired.append(name)
        elif match is not None:
            partner[i] = match
    # A joint with no side in its name under a sided parent (CMU's `lhand` under `LeftWrist`)
    # takes the same place under the parent's partner: the hierarchy is symmetric even when the
    # names are not.
    for i, parent in enumerate(skeleton.parents):
        if partner[i] == i and parent >= 0 and partner[parent] != parent:
            mine, theirs = skeleton.children(parent), skeleton.children(partner[parent])
            if len(mine) == len(theirs):
                partner[i] = theirs[mine.index(i)]
    if unpaired:
        raise IncompatibleClips(
            f"no mirror partner for joint(s) {', '.join(sorted(unpaired)[:6])}; "
            "set `skeleton.mirror: {left: TOKEN, right: TOKEN}` in the manifest"
        )
    if skeleton.has_hierarchy and find_hips(skeleton) is None:
        # No name says which leg is which (`joint_07`, `Bone.007`; perhaps a few helper bones named
        # `ik_target_L`): every unnamed joint kept its own motion, and a mirrored walk came out with
        # its legs crossed. The rest pose's symmetry pairs them; a side in a name still decides.
        by_shape = mirror_partners(skeleton, rest_positions(skeleton))
        # Names that pair fewer joints than two legs have (a few IK helpers) leave the legs
        # unpaired: no mirror then, rather than one with crossed legs.
        if by_shape is None and sum(p != j for j, p in enumerate(partner)) < 6:
            raise IncompatibleClips(
                "no joint name says left or right, and the rest pose is no mirror image of itself "
                "across the hips: no joint can be paired with its mirror partner; name the joints' "
                "sides (e.g. LeftUpLeg / RightUpLeg) to mirror this rig"
            )
        if by_shape is not None:
            merged = [
                mine if mine != joint else theirs
                for joint, (mine, theirs) in enumerate(zip(partner, by_shape, strict=True))
            ]
            if any(merged[merged[joint]] != joint for joint in range(len(merged))):
                raise IncompatibleClips(
                    "the joints' names and the rest pose's symmetry pair them differently; name the "
                    "joints' sides (e.g. LeftUpLeg / RightUpLeg) to mirror this rig"
                )
            return merged
    return partner


def _reflect_rotation(q: FloatArray, normal: FloatArray) -> FloatArray:
    """M R M for the reflection M across the plane with unit ``normal``: (v, w) -> (-(M v), w)."""
    v = q[..., :3]
    reflected = v - 2.0 * (v @ normal)[..., None] * normal
    return np.concatenate([-reflected, q[..., 3:]], axis=-1)


def bind_rotations(clip: Clip, settings: RigSettings, up_axis: str) -> FloatArray:
    """World rest rotations, expressed in the rest pose's own facing frame.

    The rest pose may face anywhere (a root joint turned 90 degrees, a Z-up export); only the
    joints' orientation relative to the character matters for telling a rig's left axes from its
    right ones.
    """
    skeleton = clip.skeleton
    rest = replace(
        clip,
        rotations=skeleton.rest_rotations[None].copy(),
        translations=skeleton.rest_translations[None].copy(),
    )
    rotations, _ = forward_kinematics(rest)
    # The clip's own up axis, not one read from the rest pose: a Z-up BVH whose hierarchy stands
    # along Y (its root's rotation lays it into Z) has a rest pose that reads Y-up, and the mirror
    # came out upside down and unmirrored.
    rest_motion = decompose(rest, replace(settings, up=up_axis))
    heading = float(rest_motion.heading[0])
    unturn = quat.conjugate(quat.from_axis_angle(rest_motion.up, heading))
    return quat.multiply(unturn[None], rotations[0])


def mirror_clip(
    clip: Clip, *, settings: RigSettings, name: str, pairs: Mapping[str, str] | None = None
) -> Clip:
    skeleton = clip.skeleton
    partner = mirror_pairs(skeleton, pairs)
    world_rot, world_pos = forward_kinematics(clip)
    motion = decompose(clip, settings)
    basis = ground_basis(motion.up_axis)
    h0 = float(motion.heading[0])
    normal = -np.sin(h0) * basis[0] + np.cos(h0) * basis[1]  # the character's left at frame 0
    centre = motion.trajectory_points()[0]
    # The bind pose turned to face where the character faces at frame 0, so its own sagittal
    # plane is the plane of the reflection.
    bind_rot = quat.multiply(
        quat.from_axis_angle(motion.up, h0)[None], bind_rotations(clip, settings, motion.up_axis)
    )

    source_rot = world_rot[:, partner]
    deviation = quat.multiply(source_rot, quat.conjugate(bind_rot[partner])[None])
    mirrored_rot = quat.normalize(quat.multiply(_reflect_rotation(deviation, normal), bind_rot[None]))
    source_pos = world_pos[:, partner] - centre
    mirrored_pos = source_pos - 2.0 * (source_pos @ normal)[..., None] * normal + centre

    rotations = np.empty_like(clip.rotations)
    translations = np.empty_like(clip.translations)
    animated = np.abs(clip.translations - skeleton.rest_translations[None]).max(axis=0).max(axis=1) > 1e-6 * (
        1.0 + np.abs(skeleton.rest_translations).max()
    )
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0 or not skeleton.has_hierarchy:
            rotations[:, joint] = mirrored_rot[:, joint]
            translations[:, joint] = mirrored_pos[:, joint]
            continue
        inverse_parent = quat.conjugate(mirrored_rot[:, parent])
        rotations[:, joint] = quat.normalize(quat.multiply(inverse_parent, mirrored_rot[:, joint]))
        if animated[partner[joint]] or animated[joint]:
            offset = mirrored_pos[:, joint] - mirrored_pos[:, parent]
            translations[:, joint] = quat.rotate(inverse_parent, offset)
        else:
            # Bone lengths stay the joint's own: a mocap rig's sides differ by millimetres, and
            # formats without per-frame translation (BVH rotation-only joints) need the rest offset.
            translations[:, joint] = skeleton.rest_translations[joint]
    return replace(
        clip,
        name=name,
        source=clip.source.with_name(f"{safe_file_stem(name)}.generated"),
        rotations=rotations,
        translations=translations,
        notes=[f"mirror of {clip.name} across the sagittal plane (left/right joints swapped)"],
    )
