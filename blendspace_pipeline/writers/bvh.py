"""A clip as BVH text: used for generated clips when the set's sources are BVH.

With a ``template`` (the source BVH) the output copies its hierarchy: joint names, End Sites and
each joint's channel list and order, so the new clip drops into the same pipeline as its source.
When the clip's bone lengths are the template's, the HIERARCHY text is copied verbatim; when they
differ (a mirrored asymmetric rig, a blend of two actors), the OFFSETs are the clip's, because a
joint without position channels is placed by its OFFSET alone and the template's would move it.
Without a template, roots and any other joint whose translation changes get six channels
(position first) and the rest ``Zrotation Xrotation Yrotation``. Numbers use a fixed ``%.6f``
format and ``-0.000000`` never appears, so equal clips give equal bytes.
"""

from __future__ import annotations

import itertools
import os
import uuid
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.readers.bvh import BvhHeader, BvhJoint, bvh_text, read_header
from blendspace_pipeline.readers.provenance import Provenance, bvh_line

_SIX = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
_ROTATION_ONLY = ("Zrotation", "Xrotation", "Yrotation")
_AXIS = {"x": 0, "y": 1, "z": 2}


class LayoutCannotHold(ValueError):
    """The template's channels cannot hold the clip's motion: a joint moves that has no position
    channels there (written in the clip's own layout, it can be)."""


def write_bvh_clip(
    clip: Clip, path: Path, *, template: Path | None = None, provenance: Provenance | None = None
) -> None:
    """Write ``clip`` to ``path`` atomically; ``provenance`` becomes a comment after the frames.

    Raises ValueError when the clip cannot be written faithfully: its joints are not the
    template's, a joint moves but has no position channels in the template, or a value is NaN.
    """
    if clip.skeleton.joint_count == 0:
        raise ValueError(f"clip {clip.name!r} has no joints")
    if not (np.isfinite(clip.rotations).all() and np.isfinite(clip.translations).all()):
        raise ValueError(f"clip {clip.name!r} has NaN or infinite values")
    if template is not None:
        header, verbatim = _template(template, clip)
    else:
        header, verbatim = _default_header(clip), None
    hierarchy = _fit_offsets(clip, header, verbatim)
    text = hierarchy + _motion(clip, header)
    if provenance is not None:
        text += bvh_line(provenance)
    temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        temporary.write_text(text, encoding="utf-8", newline="\n")
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _template(template: Path, clip: Clip) -> tuple[BvhHeader, str]:
    """The template's parsed header and its HIERARCHY text (trailing spaces and CRs dropped)."""
    header = read_header(template)
    names = tuple(j.name for j in header.joints)
    parents = tuple(j.parent for j in header.joints)
    if names != clip.skeleton.names or parents != clip.skeleton.parents:
        raise ValueError(f"clip {clip.name!r} does not have the joints of its BVH template {template}")
    # Decoded as the reader decodes it (a Shift-JIS file's names stay its names), written as UTF-8.
    text = bvh_text(template)
    lines = [line.rstrip() for line in itertools.islice(text.split("\n"), header.motion_line - 1)]
    return header, "\n".join(lines) + "\n"


def _default_header(clip: Clip) -> BvhHeader:
    skeleton = clip.skeleton
    header = BvhHeader()
    for index, (name, parent) in enumerate(zip(skeleton.names, skeleton.parents, strict=True)):
        offset = skeleton.rest_translations[index]
        channels = _SIX if parent < 0 or _moves(clip.translations[:, index]) else _ROTATION_ONLY
        leaf = not skeleton.children(index)
        header.joints.append(
            BvhJoint(name, parent, _triple(offset), channels, 0, (0.0, 0.0, 0.0) if leaf else None)
        )
    return header


def _moves(track: FloatArray) -> bool:
    """Whether a joint's (F, 3) translation track changes more than float noise."""
    tolerance = 1e-5 * (1.0 + float(np.abs(track).max()))
    return bool(np.abs(track - track[0]).max() > tolerance)


def _triple(values: FloatArray) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def _fit_offsets(clip: Clip, header: BvhHeader, verbatim: str | None) -> str:
    """The HIERARCHY text, with each rotation-only joint's OFFSET set to the clip's translation.

    Returns ``verbatim`` (the template's own text) when no OFFSET had to change.
    """
    changed = False
    for index, joint in enumerate(header.joints):
        if any(c.lower().endswith("position") for c in joint.channels):
            continue  # position channels replace the OFFSET: the template's stays
        track = clip.translations[:, index]
        if _moves(track):
            raise LayoutCannotHold(
                f"joint {joint.name!r} of clip {clip.name!r} moves but has no position channels in BVH"
            )
        wanted = track[0]
        if np.abs(wanted - np.array(joint.offset)).max() > 1e-6 * (1.0 + float(np.abs(wanted).max())):
            joint.offset = _triple(wanted)
            changed = True
    return verbatim if verbatim is not None and not changed else _hierarchy(header)


def _number(value: float) -> str:
    text = f"{value:.6f}"
    return "0.000000" if text == "-0.000000" else text


def _hierarchy(header: BvhHeader) -> str:
    out = ["HIERARCHY"]
    children: dict[int, list[int]] = {}
    for index, joint in enumerate(header.joints):
        children.setdefault(joint.parent, []).append(index)

    def emit(index: int, depth: int) -> None:
        joint = header.joints[index]
        pad = "\t" * depth
        out.append(f"{pad}{'ROOT' if joint.parent < 0 else 'JOINT'} {joint.name}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {' '.join(_number(v) for v in joint.offset)}")
        if joint.channels:
            out.append(f"{pad}\tCHANNELS {len(joint.channels)} {' '.join(joint.channels)}")
        for child in children.get(index, []):
            emit(child, depth + 1)
        if joint.end_site is not None:
            out.append(f"{pad}\tEnd Site")
            out.append(f"{pad}\t{{")
            out.append(f"{pad}\t\tOFFSET {' '.join(_number(v) for v in joint.end_site)}")
            out.append(f"{pad}\t}}")
        out.append(f"{pad}}}")

    for root in children.get(-1, []):
        emit(root, 0)
    return "\n".join(out) + "\n"


def _file_order(header: BvhHeader) -> list[int]:
    """The joints in the order the HIERARCHY lists them, depth first (`_hierarchy`): the order of
    the MOTION columns too. A clip read from FBX lists its joints breadth first; its columns in
    that order scrambled the motion of every joint after the first branch."""
    children: dict[int, list[int]] = {}
    for index, joint in enumerate(header.joints):
        children.setdefault(joint.parent, []).append(index)
    order: list[int] = []
    stack = list(reversed(children.get(-1, [])))
    while stack:
        index = stack.pop()
        order.append(index)
        stack.extend(reversed(children.get(index, [])))
    return order


def _motion(clip: Clip, header: BvhHeader) -> str:
    columns = []
    for index in _file_order(header):
        joint = header.joints[index]
        order = "".join(c[0].upper() for c in joint.channels if c.lower().endswith("rotation"))
        angles = _angles(clip, index, joint.name, order)
        rotation_column = 0
        for channel in joint.channels:
            if channel.lower().endswith("position"):
                columns.append(clip.translations[:, index, _AXIS[channel[0].lower()]])
            else:
                columns.append(angles[:, rotation_column])
                rotation_column += 1
    if not columns:
        raise ValueError(f"the BVH layout for clip {clip.name!r} has no channels")
    frames = clip.frame_count
    values = np.stack(columns, axis=1)
    # |v| <= 5e-7 would print as "-0.000000" when negative: write an honest zero instead.
    values = np.where(np.abs(values) <= 5e-7, 0.0, values)
    # One %-format over all numbers runs in C; f-strings per value cost seconds on long takes.
    row = " ".join(["%.6f"] * values.shape[1])
    body = "\n".join([row] * frames) % tuple(values.ravel().tolist())
    return f"MOTION\nFrames: {frames}\nFrame Time: {1.0 / clip.fps:.8f}\n{body}\n"


def _angles(clip: Clip, index: int, name: str, order: str) -> FloatArray:
    """(F, len(order)) Euler angles of joint ``index``; ValueError if ``order`` cannot express them.

    A layout with fewer than three rotation channels (``Zrotation Xrotation`` on a hinge, none on
    a fixed joint) is decomposed with the missing axes appended, which must then come out zero.
    """
    rotations = clip.rotations[:, index]
    missing = "".join(axis for axis in "XYZ" if axis not in order)[: max(0, 3 - len(order))]
    if not order:
        residual = np.degrees(2.0 * np.arccos(np.clip(np.abs(rotations[:, 3]), 0.0, 1.0)))
        angles = np.zeros((clip.frame_count, 0))
    else:
        full = quat.to_euler(rotations, order + missing)
        angles, residual = full[:, : len(order)], np.abs(full[:, len(order) :])
    if residual.size and residual.max() > 1e-3:
        raise ValueError(
            f"joint {name!r} of clip {clip.name!r} rotates about an axis its BVH channels "
            f"({order or 'none'}) do not have"
        )
    return angles
