"""The format-neutral clip model and vectorised forward kinematics.

Every reader produces `Clip` objects and every writer consumes them, so measurement, fixes and
exports never see a file format. Quaternions are scalar-last ``(x, y, z, w)`` (see
`quaternions`). Lengths are in the file's own units; `Clip.meters_per_unit` says what one unit
is when the file says so (USD, glTF), and is ``None`` when the format does not know (BVH).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline import native
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.quaternions import FloatArray

UpAxis = Literal["y", "z"]


@dataclass(frozen=True)
class Skeleton:
    """Joint hierarchy. Joints are ordered so that every parent comes before its children."""

    names: tuple[str, ...]
    parents: tuple[int, ...]  # -1 for a root joint
    rest_translations: FloatArray  # (J, 3) local offset from the parent, file units
    rest_rotations: FloatArray  # (J, 4) local rest rotation, scalar-last
    # False when the file carries animation tracks but not the hierarchy (Godot Animation
    # resources keep the rest pose in the model file): forward kinematics is then meaningless
    # and measurement must use a single joint's own track.
    has_hierarchy: bool = True

    def __post_init__(self) -> None:
        count = len(self.names)
        if len(self.parents) != count:
            raise ValueError("skeleton: one parent per joint expected")
        for index, parent in enumerate(self.parents):
            if parent >= index:
                raise ValueError(f"skeleton: joint {self.names[index]!r} comes before its parent")

    @property
    def joint_count(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, joint: int) -> list[int]:
        return [j for j, p in enumerate(self.parents) if p == joint]

    def descendants(self, joint: int) -> list[int]:
        inside = {joint}
        for j, p in enumerate(self.parents):
            if p in inside:
                inside.add(j)
        inside.discard(joint)
        return sorted(inside)

    def same_layout(self, other: Skeleton) -> bool:
        """Same joint names in the same hierarchy (what blending and mirroring require)."""
        return self.names == other.names and self.parents == other.parents


@dataclass
class Clip:
    """One animation: per-frame local joint transforms sampled at a constant rate."""

    name: str
    source: Path
    skeleton: Skeleton
    rotations: FloatArray  # (F, J, 4) local rotations, scalar-last
    translations: FloatArray  # (F, J, 3) local translations, file units
    fps: float
    meters_per_unit: float | None = None  # None: the format does not say (BVH)
    up_axis: UpAxis | None = None  # None: the format does not say
    notes: list[str] = field(default_factory=list)

    @property
    def frame_count(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def duration(self) -> float:
        return (self.frame_count - 1) / self.fps

    def trimmed(self, start: int, stop: int) -> Clip:
        """Frames ``start`` to ``stop`` (exclusive), as a new clip."""
        return replace(
            self,
            rotations=self.rotations[start:stop],
            translations=self.translations[start:stop],
            notes=list(self.notes),
        )


def validate_clip(clip: Clip) -> Clip:
    """Reject what no measurement can use: no frames, a bad rate, NaN or infinite values."""
    frames, joints = clip.rotations.shape[:2]
    if clip.rotations.shape != (frames, clip.skeleton.joint_count, 4) or clip.translations.shape != (
        frames,
        joints,
        3,
    ):
        raise ClipReadError(
            f"clip {clip.name!r}: animation arrays do not match the skeleton "
            f"({clip.skeleton.joint_count} joints)",
            path=clip.source,
        )
    if frames == 0:
        raise ClipReadError(
            f"clip {clip.name!r} has no frames", path=clip.source, hint="export the animation with its keys"
        )
    if not (np.isfinite(clip.fps) and clip.fps > 0):
        raise ClipReadError(
            f"clip {clip.name!r} has an invalid frame rate ({clip.fps})",
            path=clip.source,
            hint="the frame time / time codes per second must be a positive number",
        )
    for label, values in (("rotation", clip.rotations), ("translation", clip.translations)):
        # A NaN or inf makes the sum non-finite, so a finite sum clears the array in one pass
        # without a boolean copy of it; a non-finite sum (or finite values that overflow it) is
        # looked at value by value.
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(np.sum(values)):
                continue
        bad = ~np.isfinite(values)
        if bad.any():
            frame, joint = (int(i) for i in np.argwhere(bad)[0][:2])
            raise ClipReadError(
                f"clip {clip.name!r}: non-finite {label} value (NaN or inf) at frame {frame}, "
                f"joint {clip.skeleton.names[joint]!r}",
                path=clip.source,
                hint="re-export the clip; NaN usually comes from a broken constraint or a division by zero in the DCC",
            )
    return clip


def forward_kinematics(clip: Clip) -> tuple[FloatArray, FloatArray]:
    """World rotations (F, J, 4) and positions (F, J, 3) of every joint on every frame.

    Vectorised over frames and over the joints of one depth of the hierarchy: all joints whose
    parents are done are composed in one numpy operation per term. The work runs on
    component-major copies ((4, J, F): each joint's frames contiguous) with the joints in depth
    order, so a depth's joints are one slice, written in place; every term goes into kept scratch
    rows (`out=`), so no temporary is allocated. The terms are `quaternions.multiply` and
    `quaternions.rotate`'s, in their order, element by element, so the result is
    `forward_kinematics_by_joint`'s to the bit (tested); a 19-joint rig takes 5 steps instead of
    18, on contiguous rows instead of strided columns. The compiled kernel (`native`), when built,
    does the same terms frame by frame in C, ~5x faster, to the same bits.
    """
    skeleton = clip.skeleton
    local_rot, local_pos = clip.rotations, clip.translations
    if (
        not skeleton.has_hierarchy
        or local_rot.dtype != np.float64
        or local_pos.dtype != np.float64
        or local_rot.ndim != 3
        or local_pos.ndim != 3
    ):
        return forward_kinematics_by_joint(clip)
    kernels = native.kernels
    if kernels is not None and local_rot.flags.c_contiguous and local_pos.flags.c_contiguous:
        world_rot, world_pos = np.empty_like(local_rot), np.empty_like(local_pos)
        parents = _parents_array(tuple(skeleton.parents))
        if kernels.forward_kinematics(local_rot, local_pos, parents, world_rot, world_pos, len(local_rot)):
            return world_rot, world_pos
    frames, count = local_rot.shape[:2]
    plan = _plan(tuple(skeleton.parents))
    work = _work(count, frames, plan.widest)
    rot_in, pos_in, rot, pos = work.rot_in, work.pos_in, work.rot, work.pos
    # Local transforms, component-major, joints in depth order (one pass each).
    np.take(local_rot, plan.order, axis=1, out=rot_in.transpose(2, 1, 0), mode="clip")
    np.take(local_pos, plan.order, axis=1, out=pos_in.transpose(2, 1, 0), mode="clip")
    roots = plan.roots
    rot[:, :roots] = rot_in[:, :roots]
    pos[:, :roots] = pos_in[:, :roots]
    mul, add, sub = np.multiply, np.add, np.subtract
    for low, high, parents in plan.levels:
        n = high - low
        # The parents' world transforms, (4, n, F) and (3, n, F), gathered into scratch.
        a, base = work.rot_parent[:, :n], work.pos_parent[:, :n]
        np.take(rot, parents, axis=1, out=a, mode="clip")
        np.take(pos, parents, axis=1, out=base, mode="clip")
        ax, ay, az, aw = a
        bx, by, bz, bw = rot_in[:, low:high]
        out = rot[:, low:high]
        t1, t2, t3 = work.t1[:n], work.t2[:n], work.t3[:n]
        # out[0] = aw * bx + ax * bw + ay * bz - az * by, left to right.
        add(mul(aw, bx, out=t1), mul(ax, bw, out=t2), out=t1)
        add(t1, mul(ay, bz, out=t2), out=t1)
        sub(t1, mul(az, by, out=t2), out=out[0])
        # out[1] = aw * by - ax * bz + ay * bw + az * bx
        sub(mul(aw, by, out=t1), mul(ax, bz, out=t2), out=t1)
        add(t1, mul(ay, bw, out=t2), out=t1)
        add(t1, mul(az, bx, out=t2), out=out[1])
        # out[2] = aw * bz + ax * by - ay * bx + az * bw
        add(mul(aw, bz, out=t1), mul(ax, by, out=t2), out=t1)
        sub(t1, mul(ay, bx, out=t2), out=t1)
        add(t1, mul(az, bw, out=t2), out=out[2])
        # out[3] = aw * bw - ax * bx - ay * by - az * bz
        sub(mul(aw, bw, out=t1), mul(ax, bx, out=t2), out=t1)
        sub(t1, mul(ay, by, out=t2), out=t1)
        sub(t1, mul(az, bz, out=t2), out=out[3])
        # rotate(parent, offset) = v + w t + u x t with t = 2 (u x v), u = parent's vector part:
        # tx, ty, tz = 2 (ay vz - az vy), 2 (az vx - ax vz), 2 (ax vy - ay vx).
        vx, vy, vz = pos_in[:, low:high]
        tx, ty, tz = work.t[:, :n]
        mul(2.0, sub(mul(ay, vz, out=t1), mul(az, vy, out=t2), out=t1), out=tx)
        mul(2.0, sub(mul(az, vx, out=t1), mul(ax, vz, out=t2), out=t1), out=ty)
        mul(2.0, sub(mul(ax, vy, out=t1), mul(ay, vx, out=t2), out=t1), out=tz)
        moved = pos[:, low:high]
        # moved[0] = base[0] + (vx + aw * tx + (ay * tz - az * ty)), and the same turned.
        for k, v, t, (u1, w1), (u2, w2) in (
            (0, vx, tx, (ay, tz), (az, ty)),
            (1, vy, ty, (az, tx), (ax, tz)),
            (2, vz, tz, (ax, ty), (ay, tx)),
        ):
            add(v, mul(aw, t, out=t1), out=t1)
            sub(mul(u1, w1, out=t2), mul(u2, w2, out=t3), out=t2)
            add(base[k], add(t1, t2, out=t1), out=moved[k])
    # Back to (F, J, ...) in the skeleton's joint order (one pass each).
    world_rot = np.empty_like(local_rot)
    world_rot[:, plan.order] = rot.transpose(2, 1, 0)
    world_pos = np.empty_like(local_pos)
    world_pos[:, plan.order] = pos.transpose(2, 1, 0)
    return world_rot, world_pos


@dataclass(frozen=True)
class _Plan:
    """Joints in depth order: ``order[i]`` is the skeleton joint at row i of the work arrays;
    the first ``roots`` rows are the roots; each level is rows ``low:high`` with its parents'
    rows (``parents``, an index array); ``widest`` is the most joints at one depth."""

    order: NDArray[np.intp]
    roots: int
    levels: tuple[tuple[int, int, NDArray[np.intp]], ...]
    widest: int


@lru_cache(maxsize=256)
def _parents_array(parents: tuple[int, ...]) -> NDArray[np.int64]:
    return np.array(parents, dtype=np.int64)


@lru_cache(maxsize=256)
def _plan(parents: tuple[int, ...]) -> _Plan:
    """The depth order of a hierarchy. Parents come before their children (`Skeleton` checks
    it), so one pass finds every depth."""
    depth: list[int] = []
    for parent in parents:
        depth.append(0 if parent < 0 else depth[parent] + 1)
    order = sorted(range(len(parents)), key=lambda joint: (depth[joint], joint))
    row = {joint: index for index, joint in enumerate(order)}
    levels = []
    low = sum(1 for d in depth if d == 0)
    roots, widest = low, 1
    for level in range(1, max(depth, default=0) + 1):
        joints = [joint for joint in order if depth[joint] == level]
        rows = np.array([row[parents[joint]] for joint in joints], dtype=np.intp)
        levels.append((low, low + len(joints), rows))
        low += len(joints)
        widest = max(widest, len(joints))
    return _Plan(np.array(order, dtype=np.intp), roots, tuple(levels), widest)


@dataclass
class _Work:
    """`forward_kinematics`' working arrays: local and world transforms (component-major, depth
    order), the gathered parent transforms and scratch rows for the terms."""

    rot_in: FloatArray
    pos_in: FloatArray
    rot: FloatArray
    pos: FloatArray
    rot_parent: FloatArray
    pos_parent: FloatArray
    t: FloatArray
    t1: FloatArray
    t2: FloatArray
    t3: FloatArray


# The working arrays are kept per thread for the next clip of the same size: fresh ones every
# call are about 2 MB of new pages for a 7 s take, and glibc hands blocks that large back to the
# kernel when freed, so every page would fault again. Above this size (a long take) the work
# dwarfs the faults and nothing is kept.
_KEEP_WORK_BYTES = 8 * 1024 * 1024
_WORK = threading.local()


def _work(count: int, frames: int, widest: int) -> _Work:
    """Working arrays for ``count`` joints, ``frames`` frames, at most ``widest`` joints a depth;
    uninitialised: every value is written before it is read."""
    key = (count, frames, widest)
    held = getattr(_WORK, "held", None)
    if held is not None and held[0] == key:
        work: _Work = held[1]
        return work
    work = _Work(
        rot_in=np.empty((4, count, frames)),
        pos_in=np.empty((3, count, frames)),
        rot=np.empty((4, count, frames)),
        pos=np.empty((3, count, frames)),
        rot_parent=np.empty((4, widest, frames)),
        pos_parent=np.empty((3, widest, frames)),
        t=np.empty((3, widest, frames)),
        t1=np.empty((widest, frames)),
        t2=np.empty((widest, frames)),
        t3=np.empty((widest, frames)),
    )
    if (14 * count + 13 * widest) * frames * 8 <= _KEEP_WORK_BYTES:
        _WORK.held = (key, work)
    return work


def rest_positions(skeleton: Skeleton) -> FloatArray:
    """World joint positions of ``skeleton``'s rest pose (J, 3)."""
    rest = Clip(
        "rest",
        Path(),
        skeleton,
        skeleton.rest_rotations[None].copy(),
        skeleton.rest_translations[None].copy(),
        30.0,
    )
    positions: FloatArray = forward_kinematics(rest)[1][0]
    return positions


def forward_kinematics_by_joint(clip: Clip) -> tuple[FloatArray, FloatArray]:
    """`forward_kinematics` joint by joint, parents first, on the (F, J, ...) arrays as they are:
    the reference it is tested against, and the path for tracks without a hierarchy or arrays
    that are not float64 (kept in their dtype, as before)."""
    skeleton = clip.skeleton
    world_rot = np.empty_like(clip.rotations)
    world_pos = np.empty_like(clip.translations)
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0 or not skeleton.has_hierarchy:
            world_rot[:, joint] = clip.rotations[:, joint]
            world_pos[:, joint] = clip.translations[:, joint]
            continue
        ax, ay, az, aw = (world_rot[:, parent, k] for k in range(4))
        bx, by, bz, bw = (clip.rotations[:, joint, k] for k in range(4))
        rot = world_rot[:, joint]
        rot[:, 0] = aw * bx + ax * bw + ay * bz - az * by
        rot[:, 1] = aw * by - ax * bz + ay * bw + az * bx
        rot[:, 2] = aw * bz + ax * by - ay * bx + az * bw
        rot[:, 3] = aw * bw - ax * bx - ay * by - az * bz
        # rotate(parent, offset) = v + w t + u x t with t = 2 (u x v), u = parent's vector part.
        vx, vy, vz = (clip.translations[:, joint, k] for k in range(3))
        tx, ty, tz = 2.0 * (ay * vz - az * vy), 2.0 * (az * vx - ax * vz), 2.0 * (ax * vy - ay * vx)
        pos, base = world_pos[:, joint], world_pos[:, parent]
        pos[:, 0] = base[:, 0] + (vx + aw * tx + (ay * tz - az * ty))
        pos[:, 1] = base[:, 1] + (vy + aw * ty + (az * tx - ax * tz))
        pos[:, 2] = base[:, 2] + (vz + aw * tz + (ax * ty - ay * tx))
    return world_rot, world_pos


def topological_order(parents: list[int]) -> list[int]:
    """An order of joint indices in which every parent precedes its children."""
    order: list[int] = []
    placed: set[int] = set()
    children: dict[int, list[int]] = {}
    for joint, parent in enumerate(parents):
        children.setdefault(parent, []).append(joint)
    stack = list(reversed(children.get(-1, [])))
    while stack:
        joint = stack.pop()
        if joint in placed:
            continue
        placed.add(joint)
        order.append(joint)
        stack.extend(reversed(children.get(joint, [])))
    if len(order) != len(parents):
        raise ValueError("joint hierarchy has a cycle")
    return order
