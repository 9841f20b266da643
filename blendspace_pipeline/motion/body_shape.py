"""The legs found by the skeleton's shape, for rigs whose joint names say nothing.

Hand-built rigs (Blender's `Bone`, `Bone.001`...), exports that number their joints, and names in
a language `joint_names` does not know give no left and right hip. Without them the facing came
from an assumed root axis (a walk read 90 deg sideways on a rig facing +X) and the unit from a
guess. The legs are still there in the hierarchy: two sibling chains, mirror images of each other
in the rest pose, that hang down to the floor with a knee between hip and ankle. Among such pairs
the one reaching the floor wins (cloth and coat chains end above it, arms hang from the chest),
then the one nearest the root (a quadruped's hind legs).

Which of the two is the left one: in the rest pose, the toes point forward from the ankles, and
forward is (left hip - right hip) x up, up being from the ankles to the hips. Without toes (a chain
of hip, knee and ankle), or with feet that point nowhere clear, the sides stay open and the legs'
motion decides (`detect._shape_facing`).

Some files keep no rest pose but the exported frame's (an armature-only FBX, Blender's USD): a
stride, no mirror image of itself. Given the take's still joints, the legs are then looked for
again without the mirror image: two chains of the same bones that the take moves (`find_legs`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray

_LENGTH_TOLERANCE = 0.1  # bones of the two legs agree within this fraction of the longer one
_MIRROR_TOLERANCE = 0.1  # each joint within this fraction of the leg's length of its mirror image
_SIDES_COS = 0.5  # the toes tell the sides when they point within 60 deg of one way
# Degrees the leg turns at its ankle at least, from the shin to the foot (about 70 in a rest pose).
_ANKLE_TURN = 40.0
# Pairs are ranked first by how far their lowest joint is above the body's lowest, in steps of
# this fraction of their length (legs reaching the floor are in the first step, the nearest to
# the root then wins); a coat's hem 3 cm above the floor is in a later step.
_FLOOR_STEP = 0.02


@dataclass(frozen=True)
class ShapeHips:
    """Hips found by shape: ``left`` and ``right`` when ``sided`` (the rest pose's toes told them
    apart), else in file order with the sides open."""

    left: int
    right: int
    sided: bool


@dataclass(frozen=True)
class _Legs:
    a: list[int]  # hip to the far end, each
    b: list[int]
    ankle: int  # index of the ankle in both
    length: float
    gap: float = 0.0  # how far the legs' lowest joint is above the body's lowest (`_hanging`)
    mirrored: bool = True  # mirror images of each other in the rest pose (see `_leg_pair`)


def hips_by_shape(
    skeleton: Skeleton, rest_pos: FloatArray, tree: _Tree | None = None, still: frozenset[int] | None = None
) -> ShapeHips | None:
    """The hip joints of the pair of leg chains `find_legs` finds, or None. ``rest_pos``: the rest
    pose's world joint positions (J, 3); ``still``: the joints the take never moves (None: no
    take, the rest pose alone decides)."""
    legs = find_legs(skeleton, rest_pos, tree, still)
    if legs is None:
        return None
    side = _sides(rest_pos, legs)
    if side is None:
        return ShapeHips(legs.a[0], legs.b[0], sided=False)
    return (
        ShapeHips(legs.a[0], legs.b[0], sided=True)
        if side > 0
        else ShapeHips(legs.b[0], legs.a[0], sided=True)
    )


class _Tree:
    """A skeleton's hierarchy walked once: children, subtrees and heights of every joint (a rig
    with hair or cloth has hundreds of joints; `Skeleton.children` scans them all per call)."""

    def __init__(self, skeleton: Skeleton) -> None:
        count = skeleton.joint_count
        self.children: list[list[int]] = [[] for _ in range(count)]
        for joint, parent in enumerate(skeleton.parents):
            if parent >= 0:
                self.children[parent].append(joint)
        self.subtree: list[list[int]] = [[] for _ in range(count)]
        self.height = [1] * count
        self.depth = _depths(skeleton.parents)
        for joint in reversed(range(count)):  # children come after their parents
            below = [joint]
            for child in self.children[joint]:
                below += self.subtree[child]
                self.height[joint] = max(self.height[joint], 1 + self.height[child])
            self.subtree[joint] = below

    def chain(self, top: int, rest_pos: FloatArray) -> list[int]:
        """``top`` and down its deepest line of descendants; on a tie, the child whose subtree
        reaches farthest from ``top`` (a foot's toe, not the heel bone beside it)."""
        chain = [top]
        while children := self.children[chain[-1]]:
            tallest = max(self.height[c] for c in children)
            tied = [c for c in children if self.height[c] == tallest]
            if len(tied) > 1:
                reach = [
                    float(np.linalg.norm(rest_pos[self.subtree[c]] - rest_pos[top], axis=1).max())
                    for c in tied
                ]
                tied = [tied[int(np.argmax(reach))]]
            chain.append(tied[0])
        return chain


def find_legs(
    skeleton: Skeleton, rest_pos: FloatArray, tree: _Tree | None = None, still: frozenset[int] | None = None
) -> _Legs | None:
    """The mirrored pair of leg chains that reaches the floor, nearest the root among those.
    ``tree``: the skeleton's `_Tree`, when the caller has one. ``still``: joints the take never
    moves (None: the caller has no take); of two pairs as near the root, one that moves wins (a
    rig's static copies of its legs, IK or ORG helpers an unbaked export leaves in their rest,
    had been taken for the legs when the exported frame stood for the rest pose: a walk read
    backwards).

    The "rest pose" of an armature-only FBX or a Blender USD is the exported frame: a stride, no
    mirror image of itself. A caller with the take gets a second look that asks no mirror image:
    two chains of the same bones, parting at the hips, one on the floor, hanging below them, both
    moved by the take. Pairs rank by how near the floor they reach, then the nearest the root,
    moving before static, with feet before without (a coat's chains hang straight), mirror images
    before the others, the longest."""
    if not skeleton.has_hierarchy:
        return None
    tree = tree or _Tree(skeleton)
    found = _leg_pairs(skeleton, rest_pos, tree, strict=True)
    if still is not None:
        # The second look, beside the first: a posed frame's legs (on the floor, no mirror image)
        # outrank a moving coat's front and back chains (mirror images, their hem above it).
        mirrored = {(legs.a[0], legs.b[0]) for legs in found}
        found += [
            legs
            for legs in _leg_pairs(skeleton, rest_pos, tree, strict=False)
            if (legs.a[0], legs.b[0]) not in mirrored and _moves(legs, still)
        ]
    if not found:
        return None

    def rank(legs: _Legs) -> tuple[int, int, bool, bool, bool, float]:
        static = still is not None and not _moves(legs, still)
        bucket = int(legs.gap / (_FLOOR_STEP * legs.length))
        footless = legs.ankle == len(legs.a) - 1  # no turn into a foot: a coat's straight chains
        return bucket, tree.depth[legs.a[0]], static, footless, not legs.mirrored, -legs.length

    return min(found, key=rank)


def _leg_pairs(skeleton: Skeleton, rest_pos: FloatArray, tree: _Tree, *, strict: bool) -> list[_Legs]:
    """Every pair of sibling chains that `_leg_pair` takes for legs (``strict``: both reach the
    floor and are mirror images; else one reaches it, see `find_legs`)."""
    found: list[_Legs] = []
    for children in tree.children:
        # Each child's chain once; only chains of one length (three joints or more) that hang
        # down to the body's lowest point can pair (hair and cloth chains by the hundred do not).
        by_length: dict[int, list[tuple[list[int], bool]]] = {}
        for child in children:
            if tree.height[child] >= 3:
                chain = tree.chain(child, rest_pos)
                floor = _reaches_floor(rest_pos, chain)
                if floor or not strict:
                    by_length.setdefault(len(chain), []).append((chain, floor))
        for chains in by_length.values():
            for i, (chain_a, floor_a) in enumerate(chains):
                for chain_b, floor_b in chains[i + 1 :]:
                    if not (floor_a or floor_b):
                        continue
                    legs = _leg_pair(skeleton, rest_pos, chain_a, chain_b, mirror=strict)
                    if legs is not None:
                        found.append(legs)
    return found


def _moves(legs: _Legs, still: frozenset[int]) -> bool:
    """Whether the take moves both legs (a joint of each): a moving leg beside its static copy is
    no pair."""
    return any(j not in still for j in legs.a) and any(j not in still for j in legs.b)


def _reaches_floor(rest_pos: FloatArray, chain: list[int]) -> bool:
    """Whether ``chain`` reaches within `_MIRROR_TOLERANCE` of its length of the body's lowest
    point, along the way it hangs (top to end): what every leg does in a rest pose. Its lowest
    joint counts, not its end: an FBX has no rest pose but the exported frame's, and there the
    toes' end may be lifted off the floor (a heel-strike pose: 10 cm above the toe joint)."""
    drop = rest_pos[chain[0]] - rest_pos[chain[-1]]
    length = float(np.linalg.norm(drop))
    if not length > 0.0:
        return False
    heights = rest_pos @ (drop / length)
    return bool(heights[chain].min() - heights.min() <= _MIRROR_TOLERANCE * length)


def _depths(parents: tuple[int, ...] | list[int]) -> list[int]:
    depth: list[int] = []
    for parent in parents:  # parents come before their children
        depth.append(0 if parent < 0 else depth[parent] + 1)
    return depth


def leg_chain(skeleton: Skeleton, top: int, rest_pos: FloatArray) -> list[int]:
    """``top`` and down its deepest line of descendants (see `_Tree.chain`)."""
    return _Tree(skeleton).chain(top, rest_pos)


def ankle_of(leg: list[int], rest_pos: FloatArray) -> int | None:
    """Index in ``leg`` (hip first) of the ankle: where the leg turns most sharply (at least
    `_ANKLE_TURN`) from the shin to the foot, with a joint (the knee) between it and the hip; the
    leg's last joint when it never turns that much (a leg that ends at its ankle); None for a
    chain too short. A twist joint does not turn; a knee bends less than an ankle in any rest
    pose short of a deep crouch, whatever the feet's size (a reach-based ankle took a 25 cm
    foot's ankle for its toe, and the whole set read backwards)."""
    if len(leg) < 3:
        return None
    bones = np.diff(rest_pos[leg], axis=0)
    lengths = np.linalg.norm(bones, axis=1)
    turns = np.zeros(len(leg))
    for joint in range(1, len(leg) - 1):
        before, after = bones[joint - 1], bones[joint]
        if lengths[joint - 1] > 0.0 and lengths[joint] > 0.0:
            cosine = float(before @ after) / float(lengths[joint - 1] * lengths[joint])
            turns[joint] = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    turns[:2] = 0.0  # the hip and the knee below it are no ankle
    if turns.max() >= _ANKLE_TURN:
        return int(np.argmax(turns))
    return len(leg) - 1


def _leg_pair(
    skeleton: Skeleton, rest_pos: FloatArray, chain_a: list[int], chain_b: list[int], *, mirror: bool = True
) -> _Legs | None:
    """The two chains as a body's legs: bone for bone the same lengths, mirror images across the
    plane between their hips (unless not ``mirror``: a posed frame), hanging lowest with a knee
    above the ankle (`_hanging`). The hips are where the chains part: CMU's `LHipJoint` sits on
    the pelvis, its `LeftUpLeg` at the hip. None when they are not legs."""
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
    leg_a, leg_b = chain_a[hip:], chain_b[hip:]
    length = float(bones_a[hip + 1 :].sum())
    normal = (rest_pos[leg_a[0]] - rest_pos[leg_b[0]]) / apart[hip]
    middle = 0.5 * (rest_pos[leg_a[0]] + rest_pos[leg_b[0]])
    points = rest_pos[leg_a]
    mirrored = points - 2.0 * ((points - middle) @ normal)[:, None] * normal
    images = float(np.linalg.norm(mirrored - rest_pos[leg_b], axis=1).max()) <= _MIRROR_TOLERANCE * length
    if mirror and not images:
        return None
    ankle = ankle_of(leg_a, rest_pos)
    if ankle is None or ankle != ankle_of(leg_b, rest_pos):
        return None
    return _hanging(rest_pos, _Legs(leg_a, leg_b, ankle, length, mirrored=images))


def _up(rest_pos: FloatArray, legs: _Legs) -> tuple[FloatArray, float]:
    """The legs' up (ankles to hips, unit) and how far the ankles hang below the hips."""
    hips = 0.5 * (rest_pos[legs.a[0]] + rest_pos[legs.b[0]])
    ankles = 0.5 * (rest_pos[legs.a[legs.ankle]] + rest_pos[legs.b[legs.ankle]])
    drop = float(np.linalg.norm(hips - ankles))
    return ((hips - ankles) / drop if drop > 0.0 else hips - ankles), drop


def _hanging(rest_pos: FloatArray, legs: _Legs) -> _Legs | None:
    """``legs`` with their floor gap, when the two chains hang down from their tops (ankles at
    least half the leg's length below the hips, as legs stand in any rest pose) and no joint of
    the body is lower than their ends: arms held out in a T-pose do not hang, arms in an A-pose
    end above the feet. None otherwise."""
    up, drop = _up(rest_pos, legs)
    if drop < 0.5 * legs.length:
        return None
    heights = rest_pos @ up
    gap = float(min(heights[legs.a].min(), heights[legs.b].min()) - heights.min())
    return replace(legs, gap=gap) if gap <= 0.1 * legs.length else None


def _sides(rest_pos: FloatArray, legs: _Legs) -> float | None:
    """> 0 when ``legs.a`` is the left leg, < 0 when the right, None when the rest pose cannot
    tell (no toes: the leg ends at its ankle; feet that point nowhere clear)."""
    if legs.ankle == len(legs.a) - 1:
        return None
    up, drop = _up(rest_pos, legs)
    if not drop > 0.0:
        return None
    a, b, ankle = legs.a, legs.b, legs.ankle
    toes = (rest_pos[a[-1]] - rest_pos[a[ankle]]) + (rest_pos[b[-1]] - rest_pos[b[ankle]])
    toes = toes - (toes @ up) * up
    facing = np.cross(rest_pos[a[0]] - rest_pos[b[0]], up)
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
    tree = _Tree(skeleton)
    hips = hips_by_shape(skeleton, rest_pos, tree)
    if hips is None:
        return None
    a, b = rest_pos[hips.left], rest_pos[hips.right]
    normal = (a - b) / np.linalg.norm(a - b)
    middle = 0.5 * (a + b)
    reflected = rest_pos - 2.0 * ((rest_pos - middle) @ normal)[:, None] * normal
    foot = tree.chain(hips.left, rest_pos)[-1]
    tolerance = _PARTNER_TOLERANCE * float(np.linalg.norm(rest_pos[hips.left] - rest_pos[foot]))

    def distance(joint: int, other: int) -> float:
        mine, theirs = tree.subtree[joint], tree.subtree[other]
        if len(mine) != len(theirs):
            return np.inf
        return _subtree_distance(reflected[mine], rest_pos[theirs])

    partner = [-1] * skeleton.joint_count

    def pair(mine: list[int], theirs: list[int]) -> bool:
        same_order = mine != theirs and len(mine) == len(theirs)
        if same_order and all(distance(j, k) <= tolerance for j, k in zip(mine, theirs, strict=True)):
            for j, k in zip(mine, theirs, strict=True):
                partner[j] = k
            return True
        if not theirs:
            return not mine
        tops = rest_pos[theirs]
        for joint in mine:
            if joint in theirs and distance(joint, joint) <= tolerance:
                partner[joint] = joint  # on the centre line (two control bones on one spot too)
                continue
            # Only the joints whose own position mirrors this one's can hold a mirrored subtree.
            near = np.flatnonzero(np.linalg.norm(tops - reflected[joint], axis=1) <= tolerance)
            gaps = [distance(joint, theirs[i]) for i in near]
            if not gaps or min(gaps) > tolerance:
                return False
            partner[joint] = theirs[int(near[int(np.argmin(gaps))])]
        return True

    roots = [joint for joint, parent in enumerate(skeleton.parents) if parent < 0]
    if not pair(roots, roots):
        return None
    for joint in range(skeleton.joint_count):
        children = tree.children[joint]
        if children and not pair(children, tree.children[partner[joint]]):
            return None
    return partner if all(partner[partner[joint]] == joint for joint in range(len(partner))) else None


def _subtree_distance(mine: FloatArray, theirs: FloatArray) -> float:
    """The largest distance from a point of either set to the nearest point of the other."""
    if len(mine) * len(theirs) > 4096:  # a pelvis's or a head's subtree on a rig with hair or cloth
        from scipy.spatial import cKDTree

        there, here = cKDTree(theirs).query(mine)[0], cKDTree(mine).query(theirs)[0]
        return float(max(there.max(), here.max()))
    gaps = np.linalg.norm(mine[:, None, :] - theirs[None, :, :], axis=2)
    return float(max(gaps.min(axis=1).max(), gaps.min(axis=0).max()))
