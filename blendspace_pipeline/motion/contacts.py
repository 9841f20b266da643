"""Foot contacts: when each foot stands on the ground, where in the stride it plants, sync markers.

A foot is planted while its lowest point (the ankle, or the toe below it when the rig has one)
is near its own floor and barely moves over the ground. Both tests are done in metres, so they
hold for any file unit, and on smoothed signals with hysteresis so mocap jitter does not split a
contact into flickers:

- the floor of a foot is a low percentile of its height over the clip (the ground of the take,
  whatever the rig's origin; a single noisy frame does not move it);
- "near" is a share of how high the foot lifts, bounded to a few centimetres;
- "barely moves" is a horizontal speed below a fixed walking-scale threshold, loosened a little
  for fast gaits whose planted feet roll from heel to toe faster.

A contact then starts when both hold and ends when either is clearly broken; contacts shorter
than a few hundredths of a second are dropped and gaps that short are closed. The phase where a
foot plants is the gait phase (see `clip_ops.phase`) at the start of its contacts, averaged on
the circle; sync markers are those starts, named like Unreal's (``LeftFootDown``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.motion import stats
from blendspace_pipeline.motion.quaternions import FloatArray, vector_norm

FEET = ("left", "right")
BoolArray = NDArray[np.bool_]
MARKER_NAMES = {"left": "LeftFootDown", "right": "RightFootDown"}
# Floor of a foot: this percentile of its height (a take's lowest few frames may be glitches).
_FLOOR_PERCENTILE = 5.0
# Near the floor: this share of the foot's lift, between these bounds in metres.
_HEIGHT_SHARE = 0.3
_HEIGHT_BOUNDS = (0.03, 0.1)
# A planted foot's ground speed stays below this (m/s); swing feet move at about twice the
# character's speed, so the threshold may grow with the speed but never near the swing speed.
_PLANTED_SPEED = 0.35
_PLANTED_SPEED_SHARE = 0.15  # of the character's mean ground speed
# Hysteresis: a contact ends once height or speed exceeds the threshold by this factor.
_RELEASE = 1.4
# Contacts and gaps shorter than this (seconds) are noise.
_MIN_EVENT = 0.05
# Smoothing window of the speed signal, seconds.
_SMOOTH = 0.05
# Uneven ground (a slope, stairs, a hill): where the ground under the feet (the lowest foot joint's
# lowest point in each `_GROUND_WINDOW` of the take) spans more than this many metres, each
# frame's floor is the lowest the foot came over that spot of ground (cells of `_GROUND_CELL`
# metres and their neighbours), not the take's one floor: later plants were all above that floor,
# and lost. Below it the one floor stands. The feet, not the body: a take that sits down, crouches
# or holds a foot up keeps a foot on the one floor (the body's height trend had set a raised foot
# down in the air).
_UNEVEN = 0.06  # twice the narrowest "near the floor" band (3 cm); CMU 131 spans 0.01-0.03
_GROUND_WINDOW = 1.0  # seconds: a stride at a slow walk, so each window holds a plant
_GROUND_CELL = 0.1
# In place (the body ends under this many m/s from where it started): a planted foot slides back
# under the body at the walk's speed (a treadmill, Mixamo's "In Place"); when both feet slide
# alike at `_CONVEYOR` m/s or more, that slide is the ground's, and each foot's speed is taken
# relative to it (the slide near each frame: within `_BELT_WINDOW` seconds either side).
_IN_PLACE_TRAVEL = 0.1
_CONVEYOR = 0.2
_BELT_WINDOW = 0.25  # seconds either side
_BELT_RATE = 60.0  # belt samples per second at most


@dataclass(frozen=True)
class FootContacts:
    """Contact intervals per foot, in seconds from the clip's first (measured) frame."""

    left: list[tuple[float, float]]
    right: list[tuple[float, float]]
    duration: float

    def of(self, foot: str) -> list[tuple[float, float]]:
        return self.left if foot == "left" else self.right

    def to_json(self) -> dict[str, list[list[float]]]:
        return {foot: [[round(a, 4), round(b, 4)] for a, b in self.of(foot)] for foot in FEET}

    @classmethod
    def from_json(cls, data: dict[str, list[list[float]]], duration: float) -> FootContacts:
        return cls(
            [(float(a), float(b)) for a, b in data.get("left", [])],
            [(float(a), float(b)) for a, b in data.get("right", [])],
            duration,
        )

    def mask(self, foot: str, times: FloatArray) -> BoolArray:
        """True where ``foot`` is planted at ``times`` (seconds)."""
        inside = np.zeros(len(times), dtype=bool)
        for start, end in self.of(foot):
            inside |= (times >= start - 1e-9) & (times <= end + 1e-9)
        return inside

    def duty(self, foot: str) -> float:
        """Share of the clip the foot spends planted."""
        if self.duration <= 0.0:
            return 0.0
        return float(sum(b - a for a, b in self.of(foot))) / self.duration


def sync_markers(contacts: FootContacts) -> list[tuple[float, str]]:
    """(time, name) of every foot-down event, sorted by time: what Unreal's sync markers hold.

    A contact already under way at the clip's first frame is not a foot-down event there.
    """
    markers = [(start, MARKER_NAMES[foot]) for foot in FEET for start, _ in contacts.of(foot) if start > 1e-9]
    return sorted(markers)


def _smooth(values: FloatArray, window: int) -> FloatArray:
    if window <= 1 or len(values) < window:
        return values
    kernel = np.ones(window) / window
    padded = np.concatenate(
        [np.full(window // 2, values[0]), values, np.full(window - 1 - window // 2, values[-1])]
    )
    smoothed: FloatArray = np.convolve(padded, kernel, mode="valid")
    return smoothed


def _ground_speed(track: FloatArray, fps: float, reach: int) -> FloatArray:
    """Speed from the displacement over ``reach`` frames either side: per-frame differences of
    mocap amplify its millimetre jitter into tenths of a metre per second at 120 fps."""
    frames = len(track)
    inner = frames - 2 * reach  # frames whose window lies inside the clip: i - reach >= 0, i + reach < frames
    if inner <= 0:
        index = np.arange(frames)
        ahead, behind = np.minimum(index + reach, frames - 1), np.maximum(index - reach, 0)
        span = np.maximum(ahead - behind, 1) / fps
        return vector_norm(track[ahead] - track[behind]) / span  # type: ignore[no-any-return]
    # The same differences as gathering ``track`` at the clamped indices: slices inside, the
    # clamped ends (``reach`` frames each) gathered.
    moved = np.empty_like(track)
    np.subtract(track[2 * reach :], track[:inner], out=moved[reach : frames - reach])
    edge = np.arange(reach)
    moved[:reach] = track[edge + reach] - track[0]
    tail = np.arange(frames - reach, frames)
    moved[frames - reach :] = track[frames - 1] - track[tail - reach]
    speed: FloatArray = vector_norm(moved) / _spans(frames, reach, fps)
    return speed


@lru_cache(maxsize=64)
def _spans(frames: int, reach: int, fps: float) -> FloatArray:
    """Seconds between the clamped ends of each frame's window (`_ground_speed`), read-only."""
    index = np.arange(frames)
    ahead, behind = np.minimum(index + reach, frames - 1), np.maximum(index - reach, 0)
    span: FloatArray = np.maximum(ahead - behind, 1) / fps
    span.flags.writeable = False
    return span


def _joint_mean(world_pos: FloatArray, scale: float) -> FloatArray:
    """``(world_pos * scale).mean(axis=1)`` of (F, J, 3) positions. numpy's reduction over the
    joints runs an inner loop of 3 per frame and joint; einsum adds the joints one by one as the
    reduction does (the same result to the last bit, checked for 1 to 150 joints) several times
    faster."""
    joints = world_pos.shape[1]
    if joints == 0:
        return (world_pos * scale).mean(axis=1)  # type: ignore[no-any-return]
    # x * 1.0 is x exactly (IEEE), so metres need no scaled copy of every joint (0.4 MB a 7 s take).
    mean: FloatArray = np.einsum("fjc->fc", world_pos if scale == 1.0 else world_pos * scale) / joints
    return mean


def _intervals(mask: BoolArray, fps: float) -> list[tuple[float, float]]:
    """[start, end] seconds of runs of True, short gaps closed and short runs dropped."""
    frames = len(mask)
    # Runs of True from the changes of the padded mask (vectorised: a loop over frames was slow).
    edges = np.diff(np.concatenate([[0], np.asarray(mask, dtype=bool).astype(np.int8), [0]]))
    firsts, lasts = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
    runs = [[first, last] for first, last in zip(firsts.tolist(), lasts.tolist(), strict=True)]
    shortest = _MIN_EVENT * fps
    merged: list[list[int]] = []
    for run in runs:
        if merged and run[0] - merged[-1][1] - 1 < shortest:
            merged[-1][1] = run[1]
        else:
            merged.append(run)
    kept = [r for r in merged if r[1] - r[0] + 1 >= shortest or r[0] == 0 or r[1] == frames - 1]
    return [(r[0] / fps, r[1] / fps) for r in kept if r[1] > r[0]]


def detect_contacts(
    world_pos: FloatArray,
    feet: tuple[list[int], list[int]],
    *,
    fps: float,
    meters_per_unit: float,
    up_axis: str,
) -> FootContacts:
    """Contact intervals of the two feet.

    ``world_pos`` is the clip's forward kinematics (F, J, 3) in file units; ``feet`` lists, per
    foot (left, right), the joints that may touch the ground (ankle, then toe).
    """
    frames = len(world_pos)
    up, up_sign, ground = _vertical(up_axis)
    # The character's ground speed (mean of every joint: the body's centre), to scale thresholds.
    centre = _joint_mean(world_pos, meters_per_unit)[:, ground]
    duration = (frames - 1) / fps
    travel = float(vector_norm(np.diff(centre, axis=0)).sum()) / duration if duration > 0 else 0.0
    speed_limit = _PLANTED_SPEED + _PLANTED_SPEED_SHARE * travel
    # In place: the body ends where it started (its limbs' swing adds path, not displacement).
    still = duration <= 0 or float(vector_norm(centre[-1] - centre[0])) / duration < _IN_PLACE_TRAVEL
    window = max(1, round(_SMOOTH * fps))
    reach = max(1, round(0.5 * _SMOOTH * fps))
    signals = [
        [_FootSignal.of(world_pos[:, j], meters_per_unit, up, up_sign, ground, window) for j in joints]
        for joints in feet
    ]
    belt = still and _feet_share_a_belt([chain[0] for chain in signals], fps)
    uneven = _ground_span([foot.height for chain in signals for foot in chain], fps) > _UNEVEN
    found = []
    for chain in signals:
        planted = np.zeros(frames, dtype=bool)
        for foot in chain:
            speed = _ground_speed(foot.track, fps, reach)
            low, near = foot.height - foot.floor, foot.near
            if belt:
                speed = _on_the_belt(foot.track, fps, reach, low <= near, speed)
            if uneven:  # a slope, stairs: the floor under the foot, and its lift over it
                low = foot.height - _floor_under(foot.height, foot.track)
                lift = stats.percentiles(low, (100.0 - _FLOOR_PERCENTILE,))[0]
                near = float(np.clip(_HEIGHT_SHARE * lift, *_HEIGHT_BOUNDS))
            planted |= _hysteresis(low, near, speed, speed_limit)
        found.append(_intervals(planted, fps))
    return FootContacts(found[0], found[1], duration)


@dataclass(frozen=True)
class _FootSignal:
    """One joint of a foot in metres: its smoothed height over the up axis, its ground track, the
    take's floor under it (a low percentile) and how near that floor counts as down."""

    height: FloatArray
    track: FloatArray
    floor: float
    near: float

    @classmethod
    def of(
        cls,
        position: FloatArray,
        meters_per_unit: float,
        up: int,
        up_sign: float,
        ground: list[int],
        window: int,
    ) -> _FootSignal:
        # Metres; x * 1.0 is x, so a clip in metres (and an up axis pointing up) is read in place.
        metres = position if meters_per_unit == 1.0 else position * meters_per_unit
        height = _smooth(metres[:, up] if up_sign == 1.0 else up_sign * metres[:, up], window)
        floor, high = stats.percentiles(height, (_FLOOR_PERCENTILE, 100.0 - _FLOOR_PERCENTILE))
        near = float(np.clip(_HEIGHT_SHARE * (high - floor), *_HEIGHT_BOUNDS))
        return cls(height, metres[:, ground], floor, near)


def _feet_share_a_belt(ankles: list[_FootSignal], fps: float) -> bool:
    """Whether both feet slide alike while down, at `_CONVEYOR` m/s or more: the ground of an
    in-place walk moving under the body. The feet of a spin on the spot slide too, but in
    opposite directions (each around the body); they keep no belt."""
    belts = []
    for foot in ankles:
        down = foot.height - foot.floor <= foot.near
        if len(foot.track) < 2 or not down.any():
            return False
        belts.append(np.median(np.gradient(foot.track, axis=0)[down] * fps, axis=0))
    sizes = [float(np.hypot(*b)) for b in belts]
    return min(sizes) >= _CONVEYOR and float(np.hypot(*(belts[0] - belts[1]))) <= 0.5 * max(sizes)


def _on_the_belt(track: FloatArray, fps: float, reach: int, down: BoolArray, speed: FloatArray) -> FloatArray:
    """A foot's ground speed relative to the ground under an in-place clip: near each frame, the
    median motion of the foot's frames near the floor (``down``: mostly its plants) within
    `_BELT_WINDOW` seconds is the belt's (it turns with a turning walk); ``speed`` as it is
    without a frame near the floor."""
    frames = len(track)
    if frames < 2 or not down.any():
        return speed
    velocity = np.gradient(track, axis=0) * fps
    # At most `_BELT_RATE` samples a second: the belt changes over a stride, and the windowed
    # median's cost grows with frames x window (a 300 s take at 240 fps took 5 s and 484 MB).
    step = max(1, round(fps / _BELT_RATE))
    every = np.arange(0, frames, step)
    half = max(1, round(_BELT_WINDOW * fps / step))
    # Each sample's window of the low frames' motion (NaN elsewhere); its median per axis.
    low = np.where(down[every, None], velocity[every], np.nan)
    padded = np.concatenate([np.full((half, 2), np.nan), low, np.full((half, 2), np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1, axis=0)  # (S, 2, W)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window without a low frame: NaN
        sampled = np.nan_to_num(np.nanmedian(windows, axis=2))
    index = np.arange(frames, dtype=np.float64)
    belt = np.stack([np.interp(index, every, sampled[:, axis]) for axis in range(2)], axis=1)
    # The track as seen from the belt (its slide integrated and taken out), then the same
    # windowed speed as `_ground_speed`.
    slide = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (belt[1:] + belt[:-1]), axis=0) / fps])
    return _ground_speed(track - slide, fps, reach)


def _ground_span(heights: list[FloatArray], fps: float) -> float:
    """How far (metres) the ground under the feet rises or falls over the take: per `_GROUND_WINDOW`,
    the lowest point of any foot joint (``heights``), then the span of those lows (each the median
    of it and its neighbours). A stride's lift, a raised foot or a sit-down leave one foot on the
    floor."""
    lowest = np.min(np.stack(heights), axis=0)
    size = max(1, round(_GROUND_WINDOW * fps))
    blocks = len(lowest) // size
    if blocks < 2:
        return 0.0
    # The 10th percentile, not the minimum: a glitch frame (smoothed over a few frames) is no
    # ground; a plant holds a third of a stride or more.
    lows = np.percentile(lowest[: blocks * size].reshape(blocks, size), 10.0, axis=1)
    if blocks >= 5:  # one glitch frame moves its window's low only: the median of three drops it
        lows = np.median(np.stack([lows[:-2], lows[1:-1], lows[2:]]), axis=0)
    return float(lows.max() - lows.min())


def _floor_under(height: FloatArray, track: FloatArray) -> FloatArray:
    """Per frame, the lowest the foot came over its spot of ground (``track``: its ground
    positions, metres): its `_GROUND_CELL` cell and the eight around it. A foot lands on each
    step or spot of the slope; between them its swing only passes over, too fast to plant."""
    cells = np.floor(track / _GROUND_CELL).astype(np.int64)
    keys, inverse = np.unique(cells, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    lowest = np.full(len(keys), np.inf)
    np.minimum.at(lowest, inverse, height)
    index = {(x, z): i for i, (x, z) in enumerate(keys.tolist())}
    around = [
        min(
            lowest[j]
            for dx in (-1, 0, 1)
            for dz in (-1, 0, 1)
            if (j := index.get((x + dx, z + dz))) is not None
        )
        for x, z in keys.tolist()
    ]
    floors: FloatArray = np.asarray(around)[inverse]
    return floors


def _hysteresis(low: FloatArray, near: float, speed: FloatArray, limit: float) -> BoolArray:
    """Planted: enters when both height and speed are under their thresholds, leaves once either
    exceeds its threshold times `_RELEASE`."""
    enter = (low <= near) & (speed <= limit)
    stay = (low <= near * _RELEASE) & (speed <= limit * _RELEASE)
    if (enter & ~stay).any():  # only for negative thresholds, which no caller passes
        return _hysteresis_loop(enter, stay)
    # Vectorised (a loop over frames was slow): with every entry inside the stay set, a frame is
    # planted when the last entry up to it comes after the last frame outside the stay set.
    index = np.arange(len(low))
    last_enter = np.maximum.accumulate(np.where(enter, index, -1))
    last_leave = np.maximum.accumulate(np.where(stay, -1, index))
    planted: BoolArray = (last_enter >= 0) & (last_enter > last_leave)
    return planted


def _hysteresis_loop(enter: BoolArray, stay: BoolArray) -> BoolArray:
    inside = np.zeros(len(enter), dtype=bool)
    state = False
    for i in range(len(enter)):
        state = bool(stay[i]) if state else bool(enter[i])
        inside[i] = state
    return inside


def plant_phases(contacts: FootContacts, phase: FloatArray, fps: float) -> dict[str, float] | None:
    """Per foot, the gait phase (0..1, strides since the left foot passed the right going
    forward) at which it plants, averaged on the circle over its foot-down events; None when a
    foot never plants inside the clip."""
    result = {}
    frames = np.arange(len(phase), dtype=np.float64)
    for foot in FEET:
        starts = [start for start, _ in contacts.of(foot) if start > 1e-9]
        if not starts:
            return None
        values = np.interp(np.array(starts) * fps, frames, phase)
        angle = 2.0 * np.pi * values
        mean = float(np.arctan2(np.sin(angle).mean(), np.cos(angle).mean())) / (2.0 * np.pi)
        result[foot] = round(mean % 1.0, 4)
    return result


def phase_distance(a: float, b: float) -> float:
    """Distance of two phases on the unit circle (0..0.5)."""
    d = abs(a - b) % 1.0
    return min(d, 1.0 - d)


def foot_sliding(
    world_pos: FloatArray,
    joints: tuple[list[int], list[int]],
    contacts: FootContacts,
    *,
    fps: float,
    meters_per_unit: float,
    up_axis: str,
) -> float | None:
    """Mean ground speed (m/s) of the feet while planted: per foot, the slower of its joints
    (a rolling foot pivots on the heel, then the toe); None when no foot is ever planted."""
    _, _, ground = _vertical(up_axis)
    times = np.arange(len(world_pos)) / fps
    speeds = []
    for foot, chain in zip(FEET, joints, strict=True):
        down = contacts.mask(foot, times)
        steady = down[1:] & down[:-1]
        if not steady.any():
            continue
        per_joint = [
            np.linalg.norm(np.diff(world_pos[:, j][:, ground], axis=0), axis=1) * fps * meters_per_unit
            for j in chain
        ]
        speeds.append(np.minimum.reduce(per_joint)[steady])
    if not speeds:
        return None
    return float(np.concatenate(speeds).mean())


def _vertical(up_axis: str) -> tuple[int, float, list[int]]:
    """(index of the up axis, +1 or -1 for its direction, the two ground axes) for "y", "-z", ..."""
    up = "xyz".index(up_axis.lstrip("+-"))
    return up, (-1.0 if up_axis.startswith("-") else 1.0), [axis for axis in range(3) if axis != up]
