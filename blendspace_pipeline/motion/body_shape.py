"""The legs found by the skeleton's shape, for rigs whose joint names say nothing.

Hand-built rigs (Blender's `Bone`, `Bone.001`...), exports that number their joints, and names in
a language `joint_names` does not know give no left and right hip. Without them the facing came
from an assumed root axis (a walk read 90 deg sideways on a rig facing +X) and the unit from a
guess. The legs are still there in the hierarchy: two sibling chains of three or more joints,
mirror images of each other in the rest pose, the pair nearest the root (arms hang from the
chest, further down the hierarchy; a quadruped's hind legs come first).

Which of the two is the left one: in the rest pose, the toes point forward from the ankles, and
forward is (left hip - right hip) x up, up being from the feet to the hips. Without toes (a chain
of hip, knee and ankle), or with feet that point nowhere clear, the sides stay open and the legs'
motion decides (`detect._hip_line_facing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray

_LENGTH_TOLERANCE = 0.1  # bones of the two legs agree within this fraction of the longer one
_MIRROR_TOLERANCE = 0.1  # each joint within this fraction of the leg's length of its mirror image
_SIDES_COS = 0.5  # the toes tell the sides when they point within 60 deg of one way


@dataclass(frozen=True)
class ShapeHips:
    """Hips found by shape: ``left`` and ``right`` when ``sided`` (the rest pose's toes told them
    apart), else in file order with the sides open."""

    left: int
    right: int
    sided: bool


def hips_by_shape(skeleton: Skeleton, rest_pos: FloatArray) -> ShapeHips | None:
    """The hip joints of the mirrored pair of leg chains nearest the root, or None.
    ``rest_pos``: the rest pose's world joint positions (J, 3)."""
    if not skeleton.has_hierarchy:
        return None
    depth = _depths(skeleton.parents)
    best: tuple[tuple[int, float], list[int], list[int]] | None = None
    for parent in range(skeleton.joint_count):
        children = skeleton.children(parent)
        for i, a in enumerate(children):
            chain_a = leg_chain(skeleton, a)
            for b in children[i + 1 :]:
                chain_b = leg_chain(skeleton, b)
                found = _mirrored_legs(skeleton, rest_pos, chain_a, chain_b)
                if found is None:
                    continue
                length, hip = found
                rank = (depth[chain_a[hip]], -length)
                if best is None or rank < best[0]:
                    best = (rank, chain_a[hip:], chain_b[hip:])
    if best is None:
        return None
    _, leg_a, leg_b = best
    side = _sides(rest_pos, leg_a, leg_b)
    if side is None:
        return ShapeHips(leg_a[0], leg_b[0], sided=False)
    return (
        ShapeHips(leg_a[0], leg_b[0], sided=True) if side > 0 else ShapeHips(leg_b[0], leg_a[0], sided=True)
    )


def _depths(parents: tuple[int, ...] | list[int]) -> list[int]:
    depth: list[int] = []
    for parent in parents:  # parents come before their children
        depth.append(0 if parent < 0 else depth[parent] + 1)
    return depth


def leg_chain(skeleton: Skeleton, top: int) -> list[int]:
    """``top`` and down its deepest line of descendants (the first such child on a tie)."""
    heights: dict[int, int] = {}

    def height(joint: int) -> int:
        if joint not in heights:
            heights[joint] = 1 + max((height(c) for c in skeleton.children(joint)), default=0)
        return heights[joint]

    chain = [top]
    while children := skeleton.children(chain[-1]):
        chain.append(max(children, key=height))
    return chain


def _mirrored_legs(
    skeleton: Skeleton, rest_pos: FloatArray, chain_a: list[int], chain_b: list[int]
) -> tuple[float, int] | None:
    """(the legs' length, how many joints of each chain come before its hip) when the two chains
    are legs of one body: bone for bone the same lengths, mirror images across the plane between
    their hips, three joints or more from the hip down. The hips are where the chains part: CMU's
    `LHipJoint` sits on the pelvis, its `LeftUpLeg` at the hip. None otherwise."""
    if len(chain_a) != len(chain_b) or len(chain_a) < 3:
        return None
    rest = np.asarray(skeleton.rest_translations)
    bones_a, bones_b = quat.vector_norm(rest[chain_a]), quat.vector_norm(rest[chain_b])
    if np.any(np.abs(bones_a - bones_b) > _LENGTH_TOLERANCE * np.maximum(bones_a, bones_b) + 1e-12):
        return None
    total = float(bones_a.sum())
    apart = quat.vector_norm(rest_pos[chain_a] - rest_pos[chain_b])
    parted = np.flatnonzero(apart >= 0.05 * total)
    if total <= 0.0 or not len(parted) or len(chain_a) - int(parted[0]) < 3:
        return None  # the two chains never part, or part below the knee: not two legs
    hip = int(parted[0])
    length = float(bones_a[hip + 1 :].sum())
    normal = (rest_pos[chain_a[hip]] - rest_pos[chain_b[hip]]) / apart[hip]
    middle = 0.5 * (rest_pos[chain_a[hip]] + rest_pos[chain_b[hip]])
    points = rest_pos[chain_a[hip:]]
    mirrored = points - 2.0 * ((points - middle) @ normal)[:, None] * normal
    if float(np.linalg.norm(mirrored - rest_pos[chain_b[hip:]], axis=1).max()) > _MIRROR_TOLERANCE * length:
        return None
    if not _hang_lowest(rest_pos, chain_a[hip:], chain_b[hip:], length):
        return None
    return length, hip


def _hang_lowest(rest_pos: FloatArray, leg_a: list[int], leg_b: list[int], length: float) -> bool:
    """Whether the two chains hang down from their tops (ankles at least half the leg's length
    below the hips, as legs stand in any rest pose) and no joint of the body is lower than their
    ends: arms held out in a T-pose do not hang, arms in an A-pose end above the feet."""
    hips = 0.5 * (rest_pos[leg_a[0]] + rest_pos[leg_b[0]])
    ankles = 0.5 * (rest_pos[leg_a[2]] + rest_pos[leg_b[2]])
    drop = float(np.linalg.norm(hips - ankles))
    if drop < 0.5 * length:
        return False
    up = (hips - ankles) / drop
    heights = rest_pos @ up
    lowest_end = min(float(heights[leg_a].min()), float(heights[leg_b].min()))
    return bool(heights.min() >= lowest_end - 0.1 * length)


def _sides(rest_pos: FloatArray, chain_a: list[int], chain_b: list[int]) -> float | None:
    """> 0 when ``chain_a`` is the left leg, < 0 when the right, None when the rest pose cannot
    tell (no toes: hip, knee and ankle only; feet that point nowhere clear)."""
    if len(chain_a) < 4:
        return None
    hips = 0.5 * (rest_pos[chain_a[0]] + rest_pos[chain_b[0]])
    ankles = 0.5 * (rest_pos[chain_a[2]] + rest_pos[chain_b[2]])
    up = hips - ankles
    if not np.linalg.norm(up) > 0.0:
        return None
    up = up / np.linalg.norm(up)
    toes = (rest_pos[chain_a[-1]] - rest_pos[chain_a[2]]) + (rest_pos[chain_b[-1]] - rest_pos[chain_b[2]])
    toes = toes - (toes @ up) * up
    facing = np.cross(rest_pos[chain_a[0]] - rest_pos[chain_b[0]], up)
    norms = float(np.linalg.norm(toes) * np.linalg.norm(facing))
    if not norms > 0.0:
        return None
    cosine = float(toes @ facing) / norms
    return cosine if abs(cosine) >= _SIDES_COS else None


# Of the leg's length (4 cm on an adult): CMU's calibrated skeletons are 3 cm off symmetric.
_PARTNER_TOLERANCE = 0.05


def mirror_partners(skeleton: Skeleton, rest_pos: FloatArray) -> list[int] | None:
    """For every joint, its mirror partner (itself on the centre line) across the plane between
    the hips found by shape, or None when the rig is no mirror image of itself there.

    Partners are matched parent by parent: the children of a joint pair with the children of its
    partner, in the order the file lists them when each pair's subtrees are mirror images within
    `_PARTNER_TOLERANCE` (a hand's fingers and thumb, a few centimetres apart, keep their order),
    else each with the one whose subtree is nearest its own reflected. Below a centre joint the
    children pair among themselves (CMU's `LHipJoint`, on the pelvis like `LowerBack`, pairs
    with `RHipJoint`)."""
    hips = hips_by_shape(skeleton, rest_pos)
    if hips is None:
        return None
    a, b = rest_pos[hips.left], rest_pos[hips.right]
    normal = (a - b) / np.linalg.norm(a - b)
    middle = 0.5 * (a + b)
    reflected = rest_pos - 2.0 * ((rest_pos - middle) @ normal)[:, None] * normal
    foot = leg_chain(skeleton, hips.left)[-1]
    tolerance = _PARTNER_TOLERANCE * float(np.linalg.norm(rest_pos[hips.left] - rest_pos[foot]))
    subtrees = [[joint, *skeleton.descendants(joint)] for joint in range(skeleton.joint_count)]

    def distance(joint: int, other: int) -> float:
        if len(subtrees[joint]) != len(subtrees[other]):
            return np.inf
        return _subtree_distance(reflected[subtrees[joint]], rest_pos[subtrees[other]])

    partner = [-1] * skeleton.joint_count

    def pair(mine: list[int], theirs: list[int]) -> bool:
        if mine != theirs and len(mine) == len(theirs):
            gaps = [distance(j, k) for j, k in zip(mine, theirs, strict=True)]
            if max(gaps) <= tolerance:
                for j, k in zip(mine, theirs, strict=True):
                    partner[j] = k
                return True
        for joint in mine:
            gaps = [distance(joint, other) for other in theirs]
            if not gaps or min(gaps) > tolerance:
                return False
            partner[joint] = theirs[int(np.argmin(gaps))]
        return True

    if not pair(*[[j for j, p in enumerate(skeleton.parents) if p < 0]] * 2):
        return None
    for joint in range(skeleton.joint_count):
        children = skeleton.children(joint)
        if children and not pair(children, skeleton.children(partner[joint])):
            return None
    return partner if all(partner[partner[joint]] == joint for joint in range(len(partner))) else None


def _subtree_distance(mine: FloatArray, theirs: FloatArray) -> float:
    """The largest distance from a point of either set to the nearest point of the other."""
    gaps = np.linalg.norm(mine[:, None, :] - theirs[None, :, :], axis=2)
    return float(max(gaps.min(axis=1).max(), gaps.min(axis=0).max()))
