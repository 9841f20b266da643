"""Root-motion measurement: from a clip to the features of spec.md.

The character's root is the ground projection of the hip midpoint (or a configured joint), its
facing comes from the hip line (forward = (left hip - right hip) x up), and every velocity is
taken in the character's own facing frame, frame by frame. That makes the measurement
independent of where the clip starts and which way it faces, exact on arcs (a constant local
velocity integrates to the same speed whatever the turn), and zero for spins and closed loops
in place. Units and the up axis come from the file, the manifest, or detection (see `detect`).
"""

from __future__ import annotations

import hashlib
import math
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import stats
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts
from blendspace_pipeline.motion.clip_ops.phase import FootSignal, GaitCycle, detect_cycle, foot_signal
from blendspace_pipeline.motion.clip_ops.sway import stride_starts, sway_free
from blendspace_pipeline.motion.contacts import plant_phases
from blendspace_pipeline.motion.detect import (
    DetectionGuess,
    RigSettings,
    held_ends,
    motion_part,
    resolve_facing,
    resolve_root,
    resolve_units_guess,
    resolve_up_guess,
    root_speed_doubt,
    stated_unit_note,
    up_vector,
)
from blendspace_pipeline.motion.quaternions import FloatArray

# Below these a clip has no root motion worth placing (a warning, not a silent origin sample).
IN_PLACE_SPEED = 0.05  # m/s
NO_TRAVEL_SPEED = 0.001  # m/s: below it a clip's `direction` is 0 (1 mm/s: a slow creep still counts)
IN_PLACE_TURN_RATE = 3.0  # deg/s
# `speed` is negative only when travel points this far from the facing (spec.md).
BACKWARD_DIRECTION = 100.0  # deg


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
    # Each joint's parent index in `joint_names` (-1: a root): blending needs one hierarchy too.
    joint_parents: list[int] = field(default_factory=list)
    # Decisions the data did not settle (`detection-guess` findings name them and their override).
    guesses: list[DetectionGuess] = field(default_factory=list)
    # Seconds of the clip measured, first and last frame (None: the whole clip).
    range_used: tuple[float, float] | None = None
    # `skeleton_key`: clips of one rig must agree on the up axis and unit they were read with.
    skeleton_key: str = ""
    # Stepping with no whole stride measured: the pelvis sway stays in turn and direction.
    partial_stride: bool = False
    # Who says the up axis: "manifest", "file" (USD `upAxis`, glTF, FBX axis settings) or
    # "detected" (the body). A stated axis is never pooled with other clips' readings.
    up_source: str = "detected"
    # The other files the clip was read with (`readers.dependencies`: USD layers, glTF buffers).
    dependencies: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        # The cache stores measurements as JSON (`pipeline.cache`): rebuild the nested values.
        self.guesses = [DetectionGuess(**g) if isinstance(g, dict) else g for g in self.guesses]
        if self.range_used is not None:
            self.range_used = (float(self.range_used[0]), float(self.range_used[1]))


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


TimeRange = tuple[float, float] | Literal["auto"] | None


def _stated_holds(whole_pos: FloatArray, first: int, stop: int, fps: float) -> list[str]:
    """A note when a stated `range:` (frames ``first`` to ``stop``) keeps held keys at its ends,
    measured as stated: a range written against the DCC's timeline, off by the export's shift,
    read a hold as part of the walk (0.6 m/s for 1.4) or as the whole of it, without a word."""
    ends = held_ends(whole_pos[first:stop])
    # Decimals enough to name a frame at this rate (a quarter frame): at 120 fps two decimals
    # named a held frame again.
    places = max(2, math.ceil(math.log10(2.0 * fps)))
    span = f"{first / fps:.2f}-{(stop - 1) / fps:.2f} s"
    if ends is None:
        return [f"the stated range ({span}) holds one pose throughout: measured as stated, a still pose"]
    lead, tail = ends
    if not lead and not tail:
        return []
    held = [
        f"{count} frame{'s' if count > 1 else ''} at its {end}"
        for count, end in ((lead, "start"), (tail, "end"))
        if count
    ]
    kept = f"[{(first + lead) / fps:.{places}f}, {(stop - 1 - tail) / fps:.{places}f}]"
    return [
        f"the stated range ({span}) keeps keys held ({' and '.join(held)}): measured as stated; "
        f"`range: {kept}` would leave them out"
    ]


def part_options(time_range: object) -> dict[str, bool]:
    """What `detect.motion_part` leaves out of a clip cut to ``time_range`` (a manifest entry's
    `range:`), as `measure` decides it: without a range, a leading rest frame and held keys; with
    `range: auto`, nothing more (measure cut them before choosing the range); with a stated range,
    a rest frame only where the range starts at the take's start (the range is measured as stated,
    held keys and all)."""
    if time_range is None:
        return {"rest": True, "held": True}
    if time_range == "auto":
        return {"rest": False, "held": False}
    start = float(time_range[0])  # type: ignore[index]
    return {"rest": start == 0.0, "held": False}


def measure(clip: Clip, settings: RigSettings, time_range: TimeRange = None) -> Measurement:
    """Every feature of spec.md for ``clip`` (trimmed to ``time_range`` first; ``"auto"`` picks
    the steady locomotion part, see `steady_span`)."""
    notes: list[str] = []
    guesses: list[DetectionGuess] = []
    auto = time_range == "auto"
    explicit = None if auto or time_range is None else (float(time_range[0]), float(time_range[1]))
    first, stop = frame_span(clip, explicit)
    # Forward kinematics of the whole clip: the unit estimate needs every frame (below).
    with np.errstate(over="ignore", invalid="ignore"):  # absurd values are reported just below
        whole_rot, whole_pos = forward_kinematics(clip)
    # One pass: the largest magnitude is NaN or infinite when any value is.
    if not np.abs(whole_pos).max(initial=0.0) < _ABSURD_LENGTH:
        raise ClipReadError(
            f"clip {clip.name!r}: joint positions reach {np.nanmax(np.abs(whole_pos)):.3g} units, "
            "beyond any unit of length",
            path=clip.source,
            hint="a channel holds a corrupt value (e.g. 1e308); re-export the clip",
        )
    # The up axis, like the unit, belongs to the file: read from the body over every frame.
    up_axis, up_note, up_guess = resolve_up_guess(clip, whole_pos, settings)
    root = resolve_root(clip, settings, whole_pos)
    up_doubted = up_guess is not None and up_guess.stated
    facing = resolve_facing(clip, settings, up_axis, (whole_rot, whole_pos), check_legs=not up_doubted)
    # The unit belongs to the file, not to a range of it: estimated on the untrimmed clip, every
    # `range:` entry of one take gets the same unit (and so comparable speeds).
    meters_per_unit, units_source, units_guess = resolve_units_guess(clip, whole_pos, settings, up_axis, root)
    # With `range: auto` the whole take is cut first, then the steady strides are chosen in it.
    options = part_options(None if auto else explicit)
    part = motion_part(clip.trimmed(first, stop), whole_pos[first:stop], settings, **options)
    notes += part.notes(clip.fps)
    first, stop = first + part.first, first + part.stop
    if explicit is not None:
        notes += _stated_holds(whole_pos, first, stop, clip.fps)
    ground = _ground_basis(up_axis)
    if auto:
        part_posed = (whole_rot[first:stop], whole_pos[first:stop])
        facing_ground = facing.vectors(*part_posed) @ ground.T
        span = steady_span(
            clip.trimmed(first, stop),
            settings,
            part_posed,
            root.positions(whole_pos[first:stop]) @ ground.T,
            np.unwrap(np.arctan2(facing_ground[:, 1], facing_ground[:, 0])),
        )
        if span is None:
            notes.append("range: auto found no steady gait cycles; the whole clip is measured")
        else:
            first, stop = first + span[0], first + span[1]
    if stop - first < 2:
        raise ClipReadError(
            f"clip {clip.name!r} has {stop - first} frame(s) in the measured range; at least 2 are needed",
            path=clip.source,
            hint="give the clip more frames or widen its `range:`",
        )
    used = clip.trimmed(first, stop) if (first, stop) != (0, clip.frame_count) else clip
    if used.frame_count < 4:  # a pose's two frames read a 25 deg/s turn from one step's noise
        notes.append(
            f"only {used.frame_count} frames measured: speed and turn come from {used.frame_count - 1} "
            "frame step(s), not from a stride"
        )
    world_rot, world_pos = whole_rot[first:stop], whole_pos[first:stop]
    range_used = (first / clip.fps, (stop - 1) / clip.fps)
    if auto:
        notes.append(f"range: auto chose [{range_used[0]:.3f}, {range_used[1]:.3f}] s")
    notes += [n for n in (up_note,) if n]
    notes += root.notes + facing.notes
    repeated = _repeated_names(clip.skeleton.names)
    if repeated:
        notes.append(
            f"joint name(s) used twice or more: {', '.join(repeated)}; a `skeleton:` setting "
            "naming one means the first in the file"
        )
    guesses += [g for g in (up_guess, units_guess, root.guess, facing.guess) if g is not None]
    if units_guess is not None and units_guess.stated:
        settle = "check `skeleton.units`" if units_source == "manifest" else "set `skeleton.units` to be sure"
        notes.append(
            f"{units_guess.evidence}: the {units_source}'s {meters_per_unit:.4g} m per unit doubted; {settle}"
        )
    elif units_source == "manifest" and (odd := stated_unit_note(clip, whole_pos, settings, meters_per_unit)):
        notes.append(odd)
    elif units_guess is not None:
        notes.append(
            f"length unit guessed: {meters_per_unit:.4g} m per unit; set `skeleton.units` to be sure"
        )
    positions = root.positions(world_pos) @ ground.T * meters_per_unit  # (F, 2) metres
    jump = _root_jump(positions, first)
    if jump is not None:
        guesses.append(jump)
    facing_vectors = facing.vectors(world_rot, world_pos)
    forward = facing_vectors @ ground.T  # (F, 2)
    heading = np.unwrap(np.arctan2(forward[:, 1], forward[:, 0]))
    posed = (world_rot, world_pos)  # this FK is reused below, not computed again
    # The foot signal the gait cycle and the sway removal both read, computed once. On the whole
    # clip its up axis and facing are the ones found above; a range reads its own up axis (as
    # `foot_signal` would), and so its own facing.
    whole = used is clip
    found = foot_signal(
        used, settings, posed, up_axis=up_axis if whole else None, facing=facing_vectors if whole else None
    )
    cycle = detect_cycle(used, settings, posed, found=found)
    # The hip line sways with the pelvis once a stride (up to +-25 deg on swaggering gaits).
    steady = sway_free(heading, used, settings, posed, cycle, positions, found=found)
    features = _features(positions, steady, used.fps)
    too_fast = root_speed_doubt(clip, whole_pos, settings, meters_per_unit, features["speed"])
    if too_fast is not None:
        guesses.append(too_fast)
    in_place = abs(features["speed"]) < IN_PLACE_SPEED and abs(features["turn_rate"]) < IN_PLACE_TURN_RATE
    # Stepping, but no whole stride to average the sway over (a short clip or `range:`): the
    # turn and direction keep the pelvis yaw, several deg/s on a fraction of a stride.
    partial_stride = (
        steady is heading and _steps(found) and not _whole_stride(used, settings, posed, found, cycle)
    )
    if partial_stride:
        notes.append(
            f"no whole stride in the {features['duration']:.2f} s measured: the turn and direction "
            "keep the pelvis sway"
        )
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
        units_guessed=units_guess is not None,
        joint_names=list(used.skeleton.names),
        # A track set without hierarchy (Godot) has no parents to compare, not all-roots.
        joint_parents=[int(p) for p in used.skeleton.parents] if used.skeleton.has_hierarchy else [],
        guesses=guesses,
        range_used=range_used
        if (explicit is not None or auto or first > 0 or stop < clip.frame_count)
        else None,
        skeleton_key=skeleton_key(clip),
        partial_stride=partial_stride,
        up_source="manifest" if settings.up != "auto" else "file" if clip.up_axis is not None else "detected",
    )


# A root step this many times the take's typical step, and at least this far (metres), in one
# frame is a jump no body makes: the take starts over (an NLA strip repeated, takes joined) or a
# marker swapped. Speed and turn then average over the jump back.
_JUMP_STEPS = 8.0
_JUMP_METRES = 0.25


def _root_jump(positions: FloatArray, first: int) -> DetectionGuess | None:
    """A doubt when the root's ground track jumps in one frame: an NLA strip with Repeat 2 in
    Blender snaps the root back to the start, and a walk read half its speed without a word."""
    if len(positions) < 3:
        return None
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    limit = max(_JUMP_METRES, _JUMP_STEPS * float(np.median(steps)))
    at = int(np.argmax(steps))
    if steps[at] <= limit:
        return None
    return DetectionGuess(
        "root",
        f"jumps {steps[at]:.2f} m in one frame (the file's)",
        f"between frames {first + at} and {first + at + 1} (the take starts over, or takes were joined): "
        "speed and turn average over the jump",
        "cut the take at the jump with `range:`, or export one cycle",
        stated=True,
    )


def _repeated_names(names: tuple[str, ...] | list[str]) -> list[str]:
    return [name for name, count in Counter(names).items() if count > 1]


# The feet pass each other by this fraction of the leg's length at least: a step, not a shuffle.
_STEP_REACH = 0.3


def _whole_stride(
    clip: Clip,
    settings: RigSettings,
    posed: tuple[FloatArray, FloatArray],
    found: FootSignal,
    cycle: GaitCycle | None,
) -> bool:
    """Whether ``clip`` holds a whole stride: one gait period (a loop of exactly one cycle, over
    which the sway cancels as it is), or two crossings of the feet (a take whose rhythm is too
    uneven for one period)."""
    if cycle is not None and (clip.frame_count - 1) / clip.fps >= cycle.period - 1.5 / clip.fps:
        return True
    starts = stride_starts(clip, settings, posed, found=found)
    return starts is not None and len(starts[0]) >= 2


def _steps(found: FootSignal) -> bool:
    """Whether the feet step (pass each other along the facing by a real step's length)."""
    if found is None:
        return False
    signal, leg, _ = found
    return bool(len(signal) and leg > 0.0 and float(np.ptp(signal)) >= _STEP_REACH * leg)


def skeleton_key(clip: Clip) -> str:
    """Identity of a skeleton: joint names, hierarchy and rest offsets (to 4 significant digits).

    Clips sharing it were exported from one rig, so they must read the same up axis and unit.
    """
    rest = np.asarray(clip.skeleton.rest_translations, dtype=np.float64)
    # Printing the offsets costs more than the rest of a small clip's detection: a library's
    # clips share a few rigs, so the key is remembered per exact rig.
    names, parents = clip.skeleton.names, clip.skeleton.parents
    if isinstance(names, tuple) and isinstance(parents, tuple):
        return _skeleton_key(names, parents, rest.shape, rest.tobytes())
    return _skeleton_key.__wrapped__(names, parents, rest.shape, rest.tobytes())  # lists: not hashable


@lru_cache(maxsize=1024)
def _skeleton_key(
    names: tuple[str, ...], parents: tuple[int, ...], shape: tuple[int, ...], rest: bytes
) -> str:
    offsets = np.array2string(
        np.frombuffer(rest, dtype=np.float64).reshape(shape), precision=4, floatmode="maxprec"
    )
    text = repr((names, parents)) + offsets
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# range: auto keeps whole cycles whose speed is within this fraction of the steady speed, whose
# length is within this fraction of the steady cycle's (a start or stop cycle is slower), and
# whose turn differs from the steady turn by at most the larger of these degrees per cycle and
# this fraction of it (a walk that goes straight, then turns, is two parts; a wider band let a
# cycle half way between them, the change of gait, join the two into one).
_STEADY_SPEED_TOLERANCE = 0.08
_STEADY_PERIOD_TOLERANCE = 0.15
_STEADY_TURN_DEGREES = 5.0
_STEADY_TURN_FRACTION = 0.15
_STEADY_TURN_NOISE = 3.0  # times the cycle-to-cycle noise of the take's turns


def steady_span(
    clip: Clip,
    settings: RigSettings,
    posed: tuple[FloatArray, FloatArray],
    ground: FloatArray,
    heading: FloatArray,
) -> tuple[int, int] | None:
    """(first, stop) frames of the steady locomotion part: the longest run of whole gait cycles
    that agree in speed, cycle length and turn (the T-pose, the start from standing and the stop
    left out; of a walk then a turn, or a walk then a run, one part, not an average of both).

    Cycles run from one left-passes-right foot crossing to the next (`phase.foot_signal`); each
    one's speed is its chord over its length in the ground plane (``ground``: the root's (F, 2)
    ground positions, any unit), its turn the change of ``heading`` (radians per frame, unwrapped)
    between its ends, at the same stride phase (so the pelvis sway cancels). Each cycle in turn
    is the reference; the longest run of cycles agreeing with one wins, and the run is taken again
    around its own median cycle, so one odd reference cycle does not cut a steady part short.
    """
    found = stride_starts(clip, settings, posed)
    if found is None or len(found[0]) < 2:
        return None
    ups = found[0]
    frames = np.arange(len(ground), dtype=np.float64)
    at = np.stack([np.interp(ups, frames, ground[:, 0]), np.interp(ups, frames, ground[:, 1])], axis=1)
    lengths = np.diff(ups)
    speeds = np.linalg.norm(np.diff(at, axis=0), axis=1) / lengths
    turns = np.degrees(np.diff(np.interp(ups, frames, heading)))  # degrees per cycle
    # A real walk's heading wanders from cycle to cycle (4-8 deg); a band narrower than that cut
    # a straight walk to its few cycles that curved alike (8 s of 16, turn biased). The band
    # grows with the take's own cycle-to-cycle noise (robust: the median change), so a change of
    # gait still splits where the turns otherwise hold steady.
    noise = 1.4826 * stats.median(np.abs(np.diff(turns))) / math.sqrt(2.0) if len(turns) > 2 else 0.0

    def agreeing(speed: float, length: float, turn: float) -> NDArray[np.bool_]:
        band = max(_STEADY_TURN_DEGREES, _STEADY_TURN_FRACTION * abs(turn), _STEADY_TURN_NOISE * noise)
        turning = np.abs(turns - turn) <= band
        # One cycle that swerves between two that agree is the same walk (an actor looks round);
        # a change of gait keeps differing after it.
        lone = ~turning & np.r_[False, turning[:-1]] & np.r_[turning[1:], False]
        agree: NDArray[np.bool_] = (
            (np.abs(speeds - speed) <= _STEADY_SPEED_TOLERANCE * speed)
            & (np.abs(lengths - length) <= _STEADY_PERIOD_TOLERANCE * length)
            & (turning | lone)
        )
        return agree

    # On a tie, the cycle nearest the median of the faster half of the cycles first (a take with
    # long starts and stops, or no steady part at all, still finds its walk).
    faster = stats.median(np.sort(speeds)[len(speeds) // 2 :])
    best: tuple[int, int] | None = None
    for k in np.argsort(np.abs(speeds - faster), kind="stable"):
        if speeds[k] <= 0.0:
            continue
        run = _longest_run(agreeing(float(speeds[k]), float(lengths[k]), float(turns[k])))
        if run is not None and (best is None or run[1] - run[0] > best[1] - best[0]):
            best = run
    if best is None:
        return None
    middle = slice(best[0], best[1])
    again = _longest_run(
        agreeing(
            float(stats.median(speeds[middle])),
            float(stats.median(lengths[middle])),
            float(stats.median(turns[middle])),
        )
    )
    if again is not None and again[1] - again[0] >= best[1] - best[0]:
        best = again
    first = int(np.floor(ups[best[0]] + 0.5))
    last = int(np.floor(ups[best[1]] + 0.5))
    return first, min(last, len(ground) - 1) + 1


def _longest_run(mask: NDArray[np.bool_]) -> tuple[int, int] | None:
    """(start, stop) of the longest run of True in ``mask`` (the first of equal ones), or None."""
    best: tuple[int, int] | None = None
    start = None
    for index, ok in enumerate([*mask.tolist(), False]):
        if ok and start is None:
            start = index
        elif not ok and start is not None:
            if best is None or index - start > best[1] - best[0]:
                best = (start, index)
            start = None
    return best


@lru_cache(maxsize=16)
def _ground_basis(up_axis: str) -> FloatArray:
    """Rows e1, e2 spanning the ground with e1 x e2 = up, so atan2(e2, e1) grows counter-clockwise
    seen from above: a left turn is positive. Remembered per axis (read-only)."""
    # For Y up: (Z, X); for Z up: (X, Y); the others are these turned to their axis.
    up = up_vector(up_axis)
    axis = int(np.argmax(np.abs(up)))
    first = np.zeros(3)
    first[(axis + 1) % 3] = 1.0
    second = np.cross(up, first)
    basis = np.array([first, second])
    basis.flags.writeable = False
    return basis


DIRECTION_FOLD = 1e-6  # degrees: below the document's last decimal


def _features(positions: FloatArray, heading: FloatArray, fps: float) -> dict[str, float]:
    duration = (len(positions) - 1) / fps
    steps = np.diff(positions, axis=0)
    mid_heading = 0.5 * (heading[1:] + heading[:-1])
    cos, sin = np.cos(mid_heading), np.sin(mid_heading)
    # Each step expressed in the facing frame of its own instant: forward and to the left.
    forward = float(np.sum(steps[:, 0] * cos + steps[:, 1] * sin)) / duration
    lateral = float(np.sum(-steps[:, 0] * sin + steps[:, 1] * cos)) / duration
    ground_speed = float(np.hypot(forward, lateral))
    # A clip that does not travel has no direction of travel: the angle of its drift (an in-place
    # run's 4e-6 m/s read -90, a strafe) would be a number of noise. 0, as straight ahead.
    # (+ 0.0: no -0.0 in the JSON of a mirrored straight walk.)
    direction = (
        float(np.degrees(np.arctan2(lateral, forward))) + 0.0 if ground_speed >= NO_TRAVEL_SPEED else 0.0
    )
    # The range is (-180, 180]: straight back reads 180, also when it is -179.9999999 and would
    # print as -180 (the document keeps 6 decimals; identical takes read -180.0 and 180.0).
    if direction <= -180.0 + DIRECTION_FOLD:
        direction = min(direction + 360.0, 180.0)
    turn = float(np.degrees(heading[-1] - heading[0]))
    return {
        # Strafes (80-100 deg) stay positive: noise in the forward component must not flip the
        # sign of a sideways clip, nor make a mirrored pair read opposite speeds.
        "speed": -ground_speed if abs(direction) > BACKWARD_DIRECTION else ground_speed,
        "displacement_speed": float(np.linalg.norm(positions[-1] - positions[0])) / duration,
        "forward_speed": forward,
        "lateral_speed": lateral,
        "direction": direction,
        "turn_rate": turn / duration,
        "turn": turn,
        "duration": duration,
    }
