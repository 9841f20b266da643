"""A clip as BVH text: used for generated clips when the set's sources are BVH.

With a ``template`` (the source BVH) the output copies its hierarchy exactly: joint names,
OFFSETs, End Sites and each joint's channel list and order, so the new clip drops into the same
pipeline as its source. Without one, roots get six channels and other joints
``Zrotation Xrotation Yrotation``. Numbers use a fixed format, so the text is deterministic.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import numpy as np

from blendspace_pipeline import quaternions as quat
from blendspace_pipeline.clip import Clip
from blendspace_pipeline.readers.bvh import BvhHeader, BvhJoint, parse_header

_DEFAULT_ROOT = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
_DEFAULT_JOINT = ("Zrotation", "Xrotation", "Yrotation")
_AXIS = {"x": 0, "y": 1, "z": 2}


def write_bvh_clip(clip: Clip, path: Path, *, template: Path | None = None) -> None:
    """Write ``clip`` to ``path`` atomically; raises ValueError if it does not fit ``template``."""
    if template is not None:
        header, hierarchy = _template(template, clip)
    else:
        header = _default_header(clip)
        hierarchy = _hierarchy(header)
    text = hierarchy + _motion(clip, header)
    temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        temporary.write_text(text, encoding="utf-8", newline="\n")
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _template(template: Path, clip: Clip) -> tuple[BvhHeader, str]:
    """The template's parsed header and its HIERARCHY text, copied verbatim (LF line ends)."""
    lines = template.read_text(encoding="utf-8", errors="replace").splitlines()
    header = parse_header(lines, template)
    names = tuple(j.name for j in header.joints)
    parents = tuple(j.parent for j in header.joints)
    if names != clip.skeleton.names or parents != clip.skeleton.parents:
        raise ValueError(f"clip {clip.name!r} does not have the joints of its BVH template {template}")
    motion = next(i for i, line in enumerate(lines) if line.strip().upper() == "MOTION")
    return header, "\n".join(line.rstrip() for line in lines[:motion]) + "\n"


def _default_header(clip: Clip) -> BvhHeader:
    skeleton = clip.skeleton
    header = BvhHeader()
    for index, (name, parent) in enumerate(zip(skeleton.names, skeleton.parents, strict=True)):
        offset = tuple(float(v) for v in skeleton.rest_translations[index])
        channels = _DEFAULT_ROOT if parent < 0 else _DEFAULT_JOINT
        leaf = not skeleton.children(index)
        header.joints.append(
            BvhJoint(name, parent, offset, channels, 0, (0.0, 0.0, 0.0) if leaf else None)  # type: ignore[arg-type]
        )
    return header


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


def _motion(clip: Clip, header: BvhHeader) -> str:
    columns = []
    for index, joint in enumerate(header.joints):
        order = "".join(c[0].upper() for c in joint.channels if c.lower().endswith("rotation"))
        angles = quat.to_euler(clip.rotations[:, index], order) if order else None
        rotation_column = 0
        for channel in joint.channels:
            if channel.lower().endswith("position"):
                columns.append(clip.translations[:, index, _AXIS[channel[0].lower()]])
            else:
                assert angles is not None
                columns.append(angles[:, rotation_column])
                rotation_column += 1
        if not any(c.lower().endswith("position") for c in joint.channels):
            rest = clip.skeleton.rest_translations[index]
            if not np.allclose(clip.translations[:, index], rest, atol=1e-5 * (1 + np.abs(rest).max())):
                raise ValueError(
                    f"joint {joint.name!r} of clip {clip.name!r} moves but has no position channels in BVH"
                )
    values = np.stack(columns, axis=1) if columns else np.zeros((clip.frame_count, 0))
    values = np.where(np.abs(values) < 5e-7, 0.0, values)
    body = "\n".join(" ".join(f"{v:.6f}" for v in row) for row in values)
    return f"MOTION\nFrames: {clip.frame_count}\nFrame Time: {1.0 / clip.fps:.8f}\n{body}\n"
