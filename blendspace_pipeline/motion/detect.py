"""What a clip file does not say, decided from the data or the manifest's `skeleton:` block.

Up axis, length unit, the root point whose ground projection is the root motion, the facing
direction, and a rest/T-pose first frame. Every decision is returned with a label so the build
can report what was used, and every automatic guess can be overridden in the manifest.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.joint_names import find_hips
from blendspace_pipeline.motion.quaternions import FloatArray

UNIT_METERS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
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


@dataclass
class RootPoint:
    label: str
    positions: Callable[[FloatArray], FloatArray]
    notes: list[str] = field(default_factory=list)


@dataclass
class Facing:
    label: str
    vectors: Callable[[FloatArray, FloatArray], FloatArray]
    notes: list[str] = field(default_factory=list)


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
    if settings.left_hip != "auto" and settings.right_hip != "auto":
        return _joint(clip, settings.left_hip, "left_hip"), _joint(clip, settings.right_hip, "right_hip")
    if not clip.skeleton.has_hierarchy:
        return None
    found = find_hips(clip.skeleton)
    if found is None:
        return None
    left, right = found
    if settings.left_hip != "auto":
        left = _joint(clip, settings.left_hip, "left_hip")
    if settings.right_hip != "auto":
        right = _joint(clip, settings.right_hip, "right_hip")
    return left, right


def resolve_up(clip: Clip, world_pos: FloatArray, settings: RigSettings) -> tuple[str, str | None]:
    if settings.up in ("y", "z"):
        return settings.up, None
    if clip.up_axis is not None:
        return clip.up_axis, None
    # A standing character is taller than it is deep: compare its extent along Y and Z
    # (arms in a T-pose lie along X in both conventions, so X is left out).
    frame = world_pos[min(1, len(world_pos) - 1)]
    extent = frame.max(axis=0) - frame.min(axis=0)
    up = "z" if extent[2] > extent[1] else "y"
    return up, f"up axis detected as {up.upper()} from the skeleton's shape"


def resolve_root(clip: Clip, settings: RigSettings) -> RootPoint:
    if settings.root != "auto":
        joint = _joint(clip, settings.root, "root")
        return RootPoint(label=clip.skeleton.names[joint], positions=lambda p: p[:, joint])
    hips = hip_pair(clip, settings)
    if hips is not None:
        left, right = hips
        names = clip.skeleton.names
        return RootPoint(
            label=f"hip midpoint ({names[left]}, {names[right]})",
            positions=lambda p: 0.5 * (p[:, left] + p[:, right]),
        )
    joint = _fallback_root_joint(clip)
    return RootPoint(
        label=clip.skeleton.names[joint],
        positions=lambda p: p[:, joint],
        notes=[f"no hip joints recognised: root motion measured on joint {clip.skeleton.names[joint]!r}"],
    )


def _fallback_root_joint(clip: Clip) -> int:
    """A joint literally called root if there is one, else the first root of the hierarchy."""
    lowered = [name.lower() for name in clip.skeleton.names]
    for candidate in ("root", "root_jnt", "rootjoint"):
        if candidate in lowered:
            return lowered.index(candidate)
    return 0


def resolve_facing(clip: Clip, settings: RigSettings, up_axis: str) -> Facing:
    up = np.array([0.0, 0.0, 1.0]) if up_axis == "z" else np.array([0.0, 1.0, 0.0])
    hips = hip_pair(clip, settings) if settings.forward == "auto" else None
    if hips is not None:
        left, right = hips

        def from_hip_line(_rot: FloatArray, pos: FloatArray) -> FloatArray:
            return np.cross(pos[:, left] - pos[:, right], up)

        return Facing(label="hip line", vectors=from_hip_line)
    axis_name = settings.forward if settings.forward != "auto" else ("-y" if up_axis == "z" else "+z")
    axis = np.array(_AXIS_VECTORS[axis_name])
    joint = _joint(clip, settings.root, "root") if settings.root != "auto" else _fallback_root_joint(clip)

    def from_joint_axis(rot: FloatArray, _pos: FloatArray) -> FloatArray:
        return quat.rotate(rot[:, joint], np.broadcast_to(axis, (len(rot), 3)))

    notes = []
    if settings.forward == "auto":
        notes.append(
            f"facing taken from joint {clip.skeleton.names[joint]!r} axis {axis_name} (assumed); "
            "set `skeleton.forward` if the character faces another way"
        )
    return Facing(
        label=f"{clip.skeleton.names[joint]} axis {axis_name}", vectors=from_joint_axis, notes=notes
    )


def hip_height(clip: Clip, world_pos: FloatArray, up_axis: str, root: RootPoint) -> float:
    """Upright height of the root point above the lowest joint (the feet), in file units."""
    axis = 2 if up_axis == "z" else 1
    heights = root.positions(world_pos)[:, axis] - world_pos[:, :, axis].min(axis=1)
    return float(np.percentile(heights, _UPRIGHT_PERCENTILE))


def resolve_units(
    clip: Clip, world_pos: FloatArray, settings: RigSettings, up_axis: str, root: RootPoint
) -> tuple[float, str, bool]:
    """(metres per unit, where it came from, whether it is a guess).

    Pass the whole, untrimmed clip: a unit estimated per range would differ between ranges of
    one file.
    """
    if isinstance(settings.units, float | int) and not isinstance(settings.units, bool):
        return float(settings.units), "manifest", False
    if settings.units in UNIT_METERS:
        return UNIT_METERS[str(settings.units)], "manifest", False
    if clip.meters_per_unit is not None:
        return clip.meters_per_unit, "file", False
    if not clip.skeleton.has_hierarchy:
        return 1.0, "assumed metres", True
    height = hip_height(clip, world_pos, up_axis, root)
    if height <= 0:
        return 1.0, "assumed metres", True
    low, high = _PLAUSIBLE_HIP_HEIGHT
    reference = REFERENCE_HIP_HEIGHT - _LOWEST_JOINT_HEIGHT
    plausible = {unit: scale for unit, scale in UNIT_METERS.items() if low <= height * scale <= high}
    if plausible:
        unit = min(plausible, key=lambda u: abs(np.log(height * plausible[u] / reference)))
        return plausible[unit], f"detected ({unit})", False
    return reference / height, "guessed from hip height", True


def detect_tpose_frame(clip: Clip, world_pos: FloatArray, settings: RigSettings) -> bool:
    """True when the first frame should be dropped as a rest/T-pose frame.

    A rest frame stands out as a jump: the pose (joints relative to the root joint) changes
    far more between frames 0 and 1 than between any later consecutive frames.
    """
    if settings.tpose == "keep" or clip.frame_count < 4:
        return False
    if settings.tpose == "drop":
        return True
    if not clip.skeleton.has_hierarchy:
        return False
    local = world_pos - world_pos[:, :1]
    change = np.linalg.norm(np.diff(local, axis=0), axis=2).mean(axis=1)
    typical = float(np.median(change[1:]))
    scale = float(np.linalg.norm(local[1], axis=1).max()) or 1.0
    return bool(change[0] > max(8.0 * typical, 0.05 * scale))
