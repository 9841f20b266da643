"""Root-motion measurement: from a clip to the features of spec.md.

The character's root is the ground projection of the hip midpoint (or a configured joint), its
facing comes from the hip line (forward = (left hip - right hip) x up), and every velocity is
taken in the character's own facing frame, frame by frame. That makes the measurement
independent of where the clip starts and which way it faces, exact on arcs (a constant local
velocity integrates to the same speed whatever the turn), and zero for spins and closed loops
in place. Units and the up axis come from the file, the manifest, or detection (see `detect`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts
from blendspace_pipeline.motion.clip_ops.phase import detect_cycle
from blendspace_pipeline.motion.contacts import plant_phases
from blendspace_pipeline.motion.detect import (
    RigSettings,
    detect_tpose_frame,
    resolve_facing,
    resolve_root,
    resolve_units,
    resolve_up,
)
from blendspace_pipeline.motion.quaternions import FloatArray

FEATURE_UNITS = {
    "speed": "m/s",
    "displacement_speed": "m/s",
    "forward_speed": "m/s",
    "lateral_speed": "m/s",
    "direction": "deg",
    "turn_rate": "deg/s",
    "turn": "deg",
    "duration": "s",
}
# Below these a clip has no root motion worth placing (a warning, not a silent origin sample).
IN_PLACE_SPEED = 0.05  # m/s
IN_PLACE_TURN_RATE = 3.0  # deg/s


@dataclass
class Measurement:
    features: dict[str, float]
    meters_per_unit: float
    units_source: str
    up_axis: str
    root: str
    facing: str
    frames: int
    fps: float
    # Seconds per stride (`clip_ops.phase.detect_cycle`), None without a gait: what `eval` syncs
    # playback rates by. No default on purpose: cache entries written before it existed then fail
    # to load (TypeError) and are measured again instead of reading as "no gait".
    gait_period: float | None
    # Foot contacts (`contacts.FootContacts.to_json`: seconds of the measured frames per foot) and
    # the stride phase each foot plants at; None without legs (or without a gait, for phases).
    # No defaults, for the same reason as `gait_period`.
    contacts: dict[str, list[list[float]]] | None
    plant_phases: dict[str, float] | None
    notes: list[str] = field(default_factory=list)
    in_place: bool = False
    units_guessed: bool = False
    joint_names: list[str] = field(default_factory=list)


# No rig spans 1e9 of its units (a million km in metres, 1,000 km in millimetres).
_ABSURD_LENGTH = 1e9


def frame_span(clip: Clip, time_range: tuple[float, float] | None) -> tuple[int, int]:
    """First and stop (exclusive) frame of ``time_range`` (seconds from the clip's start).

    Both ends are included and each snaps to its nearest frame: a BVH ``Frame Time: .0083333``
    is 120.0005 fps, so "frames at or after 1 s" would skip the frame at 0.999996 s and
    ``range: [1, 3]`` would last 1.992 s; the nearest frames keep it at 2.0 s (within half a
    frame at each end whatever the rate's rounding).
    """
    if time_range is None:
        return 0, clip.frame_count
    start, end = time_range
    first = int(np.floor(start * clip.fps + 0.5))
    last = int(np.floor(end * clip.fps + 0.5))
    if first >= clip.frame_count:
        raise ClipReadError(
            f"clip {clip.name!r}: range starts at {start:g} s but the clip lasts {clip.duration:g} s",
            path=clip.source,
            hint="use a range inside the clip",
        )
    if last > clip.frame_count:  # more than a frame past the end: a typo (25 for 2.5), not rounding
        raise ClipReadError(
            f"clip {clip.name!r}: range ends at {end:g} s but the clip lasts {clip.duration:g} s",
            path=clip.source,
            hint=f"use an end of at most {clip.duration:g} s",
        )
    return first, min(last, clip.frame_count - 1) + 1


def trim(clip: Clip, time_range: tuple[float, float] | None) -> Clip:
    """The frames of ``time_range`` (see `frame_span`), as a new clip."""
    if time_range is None:
        return clip
    return clip.trimmed(*frame_span(clip, time_range))


def measure(clip: Clip, settings: RigSettings, time_range: tuple[float, float] | None = None) -> Measurement:
    """Every feature of spec.md for ``clip`` (trimmed to ``time_range`` first)."""
    notes: list[str] = []
    first, stop = frame_span(clip, time_range)
    # Forward kinematics of the whole clip: the unit estimate needs every frame (below).
    with np.errstate(over="ignore", invalid="ignore"):  # absurd values are reported just below
        whole_rot, whole_pos = forward_kinematics(clip)
    if not (np.isfinite(whole_pos).all() and np.abs(whole_pos).max(initial=0.0) < _ABSURD_LENGTH):
        raise ClipReadError(
            f"clip {clip.name!r}: joint positions reach {np.nanmax(np.abs(whole_pos)):.3g} units, "
            "beyond any unit of length",
            path=clip.source,
            hint="a channel holds a corrupt value (e.g. 1e308); re-export the clip",
        )
    used = clip.trimmed(first, stop) if time_range is not None else clip
    world_rot, world_pos = whole_rot[first:stop], whole_pos[first:stop]
    drop = (
        detect_tpose_frame(used, world_pos, settings) if (time_range is None or time_range[0] == 0) else False
    )
    if drop:
        used = used.trimmed(1, used.frame_count)
        world_rot, world_pos = world_rot[1:], world_pos[1:]
        notes.append("first frame is a rest/T-pose and was left out of the measurement")
    if used.frame_count < 2:
        raise ClipReadError(
            f"clip {clip.name!r} has {used.frame_count} frame(s) in the measured range; at least 2 are needed",
            path=clip.source,
            hint="give the clip more frames or widen its `range:`",
        )
    up_axis, up_note = resolve_up(used, world_pos, settings)
    root = resolve_root(used, settings)
    facing = resolve_facing(used, settings, up_axis)
    # The unit belongs to the file, not to a range of it: estimated on the untrimmed clip, every
    # `range:` entry of one take gets the same unit (and so comparable speeds).
    meters_per_unit, units_source, guessed = resolve_units(clip, whole_pos, settings, up_axis, root)
    notes += [n for n in (up_note,) if n]
    notes += root.notes + facing.notes
    if guessed:
        notes.append(
            f"length unit guessed from the hip height: {meters_per_unit:.4g} m per unit; "
            "set `skeleton.units` to be sure"
        )
    ground = _ground_basis(up_axis)
    positions = root.positions(world_pos) @ ground.T * meters_per_unit  # (F, 2) metres
    forward = facing.vectors(world_rot, world_pos) @ ground.T  # (F, 2)
    heading = np.unwrap(np.arctan2(forward[:, 1], forward[:, 0]))
    features = _features(positions, heading, used.fps)
    in_place = abs(features["speed"]) < IN_PLACE_SPEED and abs(features["turn_rate"]) < IN_PLACE_TURN_RATE
    cycle = detect_cycle(used, settings, (world_rot, world_pos))  # reuses this FK, the costly part
    contacts = clip_contacts(used, settings, world_pos, meters_per_unit=meters_per_unit, up_axis=up_axis)
    phases = (
        plant_phases(contacts, cycle.phase, used.fps) if contacts is not None and cycle is not None else None
    )
    return Measurement(
        features=features,
        meters_per_unit=meters_per_unit,
        units_source=units_source,
        up_axis=up_axis,
        root=root.label,
        facing=facing.label,
        frames=used.frame_count,
        fps=used.fps,
        gait_period=cycle.period if cycle is not None else None,
        contacts=contacts.to_json() if contacts is not None else None,
        plant_phases=phases,
        notes=notes,
        in_place=in_place,
        units_guessed=guessed,
        joint_names=list(used.skeleton.names),
    )


def _ground_basis(up_axis: str) -> FloatArray:
    """Rows e1, e2 spanning the ground with e1 x e2 = up, so atan2(e2, e1) grows counter-clockwise
    seen from above: a left turn is positive."""
    if up_axis == "z":
        return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def _features(positions: FloatArray, heading: FloatArray, fps: float) -> dict[str, float]:
    duration = (len(positions) - 1) / fps
    steps = np.diff(positions, axis=0)
    mid_heading = 0.5 * (heading[1:] + heading[:-1])
    cos, sin = np.cos(mid_heading), np.sin(mid_heading)
    # Each step expressed in the facing frame of its own instant: forward and to the left.
    forward = float(np.sum(steps[:, 0] * cos + steps[:, 1] * sin)) / duration
    lateral = float(np.sum(-steps[:, 0] * sin + steps[:, 1] * cos)) / duration
    ground_speed = float(np.hypot(forward, lateral))
    direction = float(np.degrees(np.arctan2(lateral, forward))) if ground_speed > 1e-9 else 0.0
    if direction <= -180.0 + 1e-9:  # the range is (-180, 180]: straight back reads 180
        direction = min(direction + 360.0, 180.0)
    turn = float(np.degrees(heading[-1] - heading[0]))
    return {
        # A pure strafe (90 deg) stays positive despite rounding noise in the forward component.
        "speed": -ground_speed if abs(direction) > 90.0 + 1e-6 else ground_speed,
        "displacement_speed": float(np.linalg.norm(positions[-1] - positions[0])) / duration,
        "forward_speed": forward,
        "lateral_speed": lateral,
        "direction": direction,
        "turn_rate": turn / duration,
        "turn": turn,
        "duration": duration,
    }
