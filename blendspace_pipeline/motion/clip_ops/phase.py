"""Gait-cycle detection and phase: where in its stride a clip is on every frame.

Blending a walk that takes one stride per second with a run that takes one per 0.7 s frame by
frame in normalised time puts their legs out of step (the left foot of one swings forward while
the other's swings back) and the mix shuffles. Engines sync clips by gait phase instead; this
module finds it. The signal is how far the left foot is ahead of the right one along the
character's own facing (the hip-line facing `measure` uses): it swings once per stride and, for a
symmetric gait, flips sign every half stride, so its fundamental frequency *is* the stride rate.
The stride period comes from the signal's zero crossings (or, for an exported loop, from the
clip's length: a loop holds a whole number of strides), a best-fitting sinusoid telling a gait
from noise; the phase runs through the actual crossings, the left foot passing the right one
going forward at phase 0, 1, 2 ... and the right passing the left in between, so clips whose
cadence drifts stay in step.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from blendspace_pipeline.motion import stats
from blendspace_pipeline.motion.clip import Clip, forward_kinematics, rest_positions
from blendspace_pipeline.motion.detect import (
    RigSettings,
    body_joints,
    hip_pair,
    resolve_facing,
    resolve_up,
    rig_memo,
    shape_hips,
    up_vector,
)
from blendspace_pipeline.motion.joint_names import split_side
from blendspace_pipeline.motion.quaternions import FloatArray, vector_norm

# A stride shorter than this is not a gait (a fox trots at about 0.35 s per stride).
MIN_PERIOD_S = 0.25
# The clip must hold almost a whole stride for its period to be measurable.
MIN_CYCLES = 0.95
# The foot-to-foot swing must reach this fraction of the leg length (idle sway stays far below).
MIN_AMPLITUDE = 0.1
# Share of the signal's variance the stride sinusoid must explain: anything less is not periodic
# (a steady mocap walk over several seconds reaches 0.5-0.6 as its cadence wanders).
MIN_FIT = 0.45
# Strides may differ this much (coefficient of variation) before the clip counts as irregular.
MAX_STRIDE_SPREAD = 0.35
_FOOT_BASES = ("foot", "ankle")


@dataclass(frozen=True)
class GaitCycle:
    """A clip's stride: its mean period and the phase (in strides, increasing) of every frame."""

    period: float  # seconds per stride (two steps)
    phase: FloatArray  # (F,) strides since the left foot last passed the right one, unwrapped
    fit: float  # share of the foot signal's variance the stride sinusoid explains
    feet: tuple[str, str]
    # Strides in a clip that loops (0 when it does not): the whole clip, seam included.
    loop_strides: int = 0
    # An open loop's last frame leads into its first (the first is not repeated at the end).
    open_loop: bool = False

    @property
    def cycles(self) -> float:
        """Strides the clip holds (a loop's count includes an open loop's seam)."""
        return float(self.loop_strides) if self.loop_strides else float(self.phase[-1] - self.phase[0])


def foot_joints(clip: Clip, settings: RigSettings) -> tuple[int, int] | None:
    """(left, right) foot joints: below the hips `detect` finds, the first joint named foot or
    ankle, else the joint of the leg farthest from the hip in the rest pose."""
    skeleton = clip.skeleton
    # Remembered per rig; the rest pose is part of the key for rigs without a named foot.
    rest = tuple(
        np.asarray(a, dtype=np.float64).tobytes()
        for a in (skeleton.rest_translations, skeleton.rest_rotations)
    )
    return rig_memo("foot_joints", clip, settings, lambda: _foot_joints(clip, settings), *rest)


def _foot_joints(clip: Clip, settings: RigSettings) -> tuple[int, int] | None:
    hips = hip_pair(clip, settings) if clip.skeleton.has_hierarchy else None
    if hips is None:
        return None
    if shape_hips(clip, settings) is not None:  # legs by the skeleton's shape: its ankles
        body = body_joints(clip, settings)
        return body.feet if body is not None else None
    skeleton = clip.skeleton
    feet = []
    for hip in hips:
        below = skeleton.descendants(hip)
        if not below:
            return None
        named = [j for j in below if any(b in split_side(skeleton.names[j])[1] for b in _FOOT_BASES)]
        if named:
            feet.append(named[0])
            continue
        rest_pos = rest_positions(
            clip.skeleton
        )  # only rigs without a named foot pay for posing the rest pose
        feet.append(max(below, key=lambda j: np.linalg.norm(rest_pos[j] - rest_pos[hip])))
    return feet[0], feet[1]


Posed = tuple[FloatArray, FloatArray]  # (world rotations, world positions) of every frame
# `foot_signal`'s answer: (signal, mean leg length, (left foot, right foot)), or None.
FootSignal = tuple[FloatArray, float, tuple[int, int]] | None
# Passed for a `FootSignal` argument when the callee is to compute it itself.
COMPUTE: Literal["compute"] = "compute"


def foot_signal(
    clip: Clip,
    settings: RigSettings,
    posed: Posed | None = None,
    *,
    up_axis: str | None = None,
    facing: FloatArray | None = None,
) -> FootSignal:
    """(left foot minus right foot along the facing on every frame, mean leg length, feet); file units.

    ``posed`` is the clip's forward kinematics when the caller has it already (`measure` does),
    ``up_axis`` what `detect.resolve_up` reads from it and ``facing`` the facing vectors (F, 3)
    of that up axis (`detect.resolve_facing`) when the caller knows them too.
    """
    feet = foot_joints(clip, settings)
    hips = hip_pair(clip, settings) if clip.skeleton.has_hierarchy else None
    if feet is None or hips is None:
        return None
    world_rot, world_pos = posed if posed is not None else forward_kinematics(clip)
    if up_axis is None:
        up_axis, _ = resolve_up(clip, world_pos, settings)
    up = up_vector(up_axis)  # any signed axis: -Y and -Z up too
    forward = (
        resolve_facing(clip, settings, up_axis, (world_rot, world_pos)).vectors(world_rot, world_pos)
        if facing is None
        else facing
    )
    forward = forward - (forward @ up)[:, None] * up
    length = vector_norm(forward)[:, None]
    forward = forward / np.where(length > 0.0, length, 1.0)
    left, right = feet
    signal = np.einsum("fi,fi->f", world_pos[:, left] - world_pos[:, right], forward)
    legs = [
        vector_norm(world_pos[:, foot] - world_pos[:, hip]).mean()
        for foot, hip in zip(feet, hips, strict=True)
    ]
    return signal, float(np.mean(legs)), feet


def _sinusoid_fit(signal: FloatArray, times: FloatArray, frequencies: FloatArray) -> FloatArray:
    """R^2 of the least-squares fit ``c + a cos(2 pi f t) + b sin(2 pi f t)`` for each frequency."""
    centred = signal - signal.mean()
    total = float(centred @ centred)
    angle = 2.0 * np.pi * frequencies[:, None] * times[None, :]
    cos, sin = np.cos(angle), np.sin(angle)
    cos -= cos.mean(axis=1, keepdims=True)  # the constant term, projected out
    sin -= sin.mean(axis=1, keepdims=True)
    cc, ss, cs = (cos * cos).sum(1), (sin * sin).sum(1), (cos * sin).sum(1)
    yc, ys = cos @ centred, sin @ centred
    det = cc * ss - cs * cs
    safe = np.where(det > 1e-12, det, 1.0)
    explained = np.where(det > 1e-12, (ss * yc * yc - 2.0 * cs * yc * ys + cc * ys * ys) / safe, 0.0)
    fit: FloatArray = explained / total if total > 0.0 else np.zeros_like(frequencies)
    return fit


def _chirp_z(signal: FloatArray, start: float, step: float, count: int) -> np.ndarray:
    """``sum_n signal[n] exp(-2 pi i (start + k step) n)`` for k < count (frequencies in cycles per
    sample), by Bluestein's algorithm: three FFTs of about ``len(signal) + count`` points instead of
    the ``len(signal) * count`` products of evaluating each frequency on its own."""
    n = len(signal)
    chirp, kernel, size = _chirp_kernel(n, step, count)
    k = np.arange(n, dtype=np.float64)
    weighted = signal * np.exp(-2j * np.pi * start * k) * chirp[:n]
    spectrum = np.fft.ifft(np.fft.fft(weighted, size) * kernel)[:count]
    result: np.ndarray = spectrum * chirp[:count]
    return result


@lru_cache(maxsize=16)
def _chirp_kernel(n: int, step: float, count: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The chirp, the transformed kernel and the FFT size of `_chirp_z`: they depend on the grid's
    spacing alone, which clips of one length and rate (a library's takes) share."""
    size = 1 << int(np.ceil(np.log2(n + count - 1)))
    k = np.arange(max(n, count), dtype=np.float64)
    # exp(-i pi step k^2): k^2 taken modulo 2/step would lose nothing, but float64 holds k^2
    # exactly far beyond any clip, so the chirp is computed directly.
    chirp = np.exp(-1j * np.pi * step * k * k)
    kernel = np.zeros(size, dtype=np.complex128)
    kernel[:count] = np.conj(chirp[:count])
    kernel[size - n + 1 :] = np.conj(chirp[1:n][::-1])
    transformed = np.fft.fft(kernel)
    chirp.flags.writeable = False  # shared between calls
    transformed.flags.writeable = False
    return chirp, transformed, size


def _sinusoid_fit_grid(signal: FloatArray, start: float, step: float, count: int) -> FloatArray:
    """`_sinusoid_fit` on the evenly spaced frequencies ``start + k step`` (cycles per sample),
    all at once. The fit needs, per frequency, the signal's cosine and sine sums and the sums of
    cos, sin, cos^2, sin^2 and cos sin over the samples: the first two are the signal's Fourier
    transform there, the others the transform of a constant at that frequency and at twice it,
    so a chirp-z transform gives every grid point in n log n instead of n per frequency."""
    return _sinusoid_fit_grid_det(signal, start, step, count)[0]


def _sinusoid_fit_grid_det(
    signal: FloatArray,
    start: float,
    step: float,
    count: int,
    constants: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[FloatArray, np.ndarray]:
    """`_sinusoid_fit_grid`, and where the cos/sin pair was too collinear to fit (fit 0 there).
    ``constants``: the sums of exp(-i x) and exp(-2 i x) over the samples when the caller has
    them (`_geometric_sums`), else their chirp-z transforms."""
    n = len(signal)
    centred = signal - signal.mean()
    total = float(centred @ centred)
    if total <= 0.0:
        return np.zeros(count), np.ones(count, dtype=bool)
    y = _chirp_z(centred, start, step, count)
    s1, s2 = constants if constants is not None else _constant_transforms(n, start, step, count)
    yc, ys = y.real, -y.imag  # the centred signal sums to zero, so its projection needs no mean
    mc, ms = s1.real / n, -s1.imag / n
    cc = 0.5 * (n + s2.real) - n * mc * mc  # cos^2 = (1 + cos 2x) / 2, less the mean's share
    ss = 0.5 * (n - s2.real) - n * ms * ms
    cs = 0.5 * -s2.imag - n * mc * ms  # cos sin = sin(2x) / 2
    det = cc * ss - cs * cs
    # Only a nearly collinear cos/sin pair (a frequency near 0 or Nyquist) has a tiny determinant;
    # it is a difference of sums of order n^2, so the floor scales with n^2 to stay above rounding.
    floor = 1e-12 * float(n) ** 2
    safe = np.where(det > floor, det, 1.0)
    explained = np.where(det > floor, (ss * yc * yc - 2.0 * cs * yc * ys + cc * ys * ys) / safe, 0.0)
    fit: FloatArray = explained / total
    return fit, ~(det > floor)


@lru_cache(maxsize=16)
def _constant_transforms(n: int, start: float, step: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The chirp-z transforms of n ones at the grid's frequencies and at twice them: they depend
    on the grid alone, which clips of one length and rate (a library's takes) share."""
    ones = np.ones(n)
    s1 = _chirp_z(ones, start, step, count)  # sum cos = Re, sum sin = -Im
    s2 = _chirp_z(ones, 2.0 * start, 2.0 * step, count)  # the same at twice the frequency
    s1.flags.writeable = False  # shared between calls
    s2.flags.writeable = False
    return s1, s2


def _geometric_sums(n: int, start: float, step: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """What `_constant_transforms` computes, in closed form: the sum of exp(-i w k) over k < n is
    exp(-i w (n - 1) / 2) sin(w n / 2) / sin(w / 2) (w = 2 pi f, f in cycles per sample); for the
    few frequencies of a refinement grid, cheaper than two more transforms (rounding below 1e-14
    of n, as the transforms')."""
    w = 2.0 * np.pi * (start + step * np.arange(count, dtype=np.float64))

    def sums(w: FloatArray) -> np.ndarray:
        half = np.sin(0.5 * w)
        ratio = np.where(half == 0.0, float(n), np.sin(0.5 * w * n) / np.where(half == 0.0, 1.0, half))
        result: np.ndarray = np.exp(-0.5j * w * (n - 1)) * ratio
        return result

    return sums(w), sums(2.0 * w)


# The refinement evaluates its grid by chirp-z, then fits exactly (`_sinusoid_fit`) only the
# frequencies whose fit comes within this much of the best one (R^2 is at most 1): far more than
# the transform's rounding (below 1e-14 on 3,800 grids of real and generated takes), so the
# exact best of the grid is always among them.
_CANDIDATE_MARGIN = 1e-10


def _best_on_grid(signal: FloatArray, times: FloatArray, grid: FloatArray, fps: float) -> float:
    """The frequency of the evenly spaced ``grid`` (strides per second) whose `_sinusoid_fit` is
    highest (the first of equals), as fitting every one exactly finds it, in n log n."""
    start, step = float(grid[0]) / fps, float(grid[-1] - grid[0]) / (len(grid) - 1) / fps
    constants = _geometric_sums(len(signal), start, step, len(grid))
    approx, collinear = _sinusoid_fit_grid_det(signal, start, step, len(grid), constants)
    top = float(approx.max())
    # Frequencies the transform could not fit are fitted exactly too (`_sinusoid_fit`'s own floor
    # is lower), and so is every frequency of a constant signal.
    candidates = np.nonzero((approx >= top - _CANDIDATE_MARGIN) | collinear)[0]
    if len(candidates) == 1:  # ahead of every other by more than the rounding: the exact best too
        return float(grid[candidates[0]])
    exact = _sinusoid_fit(signal, times, grid[candidates])
    return float(grid[candidates[int(np.argmax(exact))]])


def _stride_frequency(signal: FloatArray, fps: float) -> tuple[float, float]:
    """(strides per second, fit) of the best sinusoid: a coarse grid (a fiftieth of a stride over
    the whole clip) on the signal thinned to about 30 samples a second (strides are slower than
    4 Hz), refined twice on all of it. The grid's size grows with the clip's length, so it is
    evaluated by a chirp-z transform (`_sinusoid_fit_grid`): n log n, where fitting each
    frequency on its own cost n per frequency, quadratic in the clip's length."""
    frames = len(signal)
    duration = (frames - 1) / fps
    low = MIN_CYCLES / duration
    high = min(1.0 / MIN_PERIOD_S, fps / 4.0)
    if high <= low:
        return 0.0, 0.0
    thin = max(1, int(fps // 30))
    times = np.arange(frames) / fps
    step = 0.02 / duration  # a fiftieth of a stride over the whole clip
    count = len(np.arange(low, high + step, step))
    rate = fps / thin  # samples per second of the thinned signal
    fits = _sinusoid_fit_grid(signal[::thin], low / rate, step / rate, count)
    best = low + step * int(np.argmax(fits))
    for _refinement in range(2):
        grid = np.linspace(max(low, best - step), min(high, best + step), 41)
        best = _best_on_grid(signal, times, grid, fps)
        step = float(grid[1] - grid[0])
    fit = float(_sinusoid_fit(signal, times, np.array([best]))[0])
    return best, fit


def _crossings(signal: FloatArray, hysteresis: float) -> tuple[FloatArray, FloatArray]:
    """Fractional frames where ``signal`` crosses zero going up, and going down, ignoring
    wiggles smaller than ``hysteresis``: a crossing counts once the signal has been past -h and
    then past +h (or the reverse), and it is the last zero crossing before that.

    Vectorised (a frame-by-frame loop was a tenth of measuring a clip): frame i (from 1) is clearly
    up (> h) or down (< -h) or neither; an upward crossing is reported where the signal is clearly
    up and was last clearly down, at the last sign change up to there (0 before any).
    """
    count = len(signal)
    if count < 2:
        return np.zeros(0), np.zeros(0)
    a, b = signal[:-1], signal[1:]
    index = np.arange(count - 1)  # step k runs from frame k to frame k + 1
    changes = (a < 0.0) != (b < 0.0)
    zeros = np.zeros(count - 1)
    zeros[changes] = index[changes] + a[changes] / (a[changes] - b[changes])
    last_change = np.maximum.accumulate(np.where(changes, index, -1))
    last_zero = np.where(last_change >= 0, zeros[np.maximum(last_change, 0)], 0.0)
    clear = np.where(b > hysteresis, 1, np.where(b < -hysteresis, -1, 0))
    last_clear = np.maximum.accumulate(np.where(clear != 0, index, -1))
    state = np.where(last_clear >= 0, clear[np.maximum(last_clear, 0)], 0)  # after each step
    before = np.concatenate([[0], state[:-1]])
    ups = last_zero[(clear == 1) & (before == -1)]
    downs = last_zero[(clear == -1) & (before == 1)]
    return ups.astype(np.float64), downs.astype(np.float64)


def _anchors(ups: FloatArray, downs: FloatArray, rate: float, offset: float) -> tuple[FloatArray, FloatArray]:
    """(frames, phases) the phase must pass through.

    Each upward crossing is one stride after the previous one; each downward crossing lies the
    same fraction of a stride after its upward one (1/2 for a symmetric gait, measured on the
    clip's own complete strides). The hysteresis makes the two kinds alternate, so counting
    them numbers the strides even when the cadence drifts a lot; the constant-rate phase
    ``rate * frame + offset`` only decides which whole stride the first crossing belongs to.
    """
    # Each down crossing's place between the up crossings either side of it (``ups`` is sorted:
    # `_crossings` reports them in time order).
    before = np.searchsorted(ups, downs, side="left") - 1
    after = np.searchsorted(ups, downs, side="right")
    inside = (before >= 0) & (after < len(ups))
    previous, following = ups[before[inside]], ups[after[inside]]
    fractions = (downs[inside] - previous) / (following - previous)
    half = stats.median(fractions) if len(fractions) else 0.5
    marks = np.concatenate([ups, downs])
    is_up = np.concatenate([np.ones(len(ups), bool), np.zeros(len(downs), bool)])
    order = np.argsort(marks, kind="stable")
    marks, is_up = marks[order], is_up[order]
    if not len(marks):
        return marks, marks
    # Relative phase: +half from an up to the next down, +(1 - half) from a down to the next up.
    steps = np.where(is_up[1:], 1.0 - half, half)
    relative = np.concatenate([[0.0 if is_up[0] else half], (0.0 if is_up[0] else half) + np.cumsum(steps)])
    whole = float(np.round(stats.median(rate * marks + offset - relative)))
    return marks, relative + whole


def _loop_length(signal: FloatArray, fps: float, amplitude: float) -> tuple[float, bool] | None:
    """(the clip's length as a loop in seconds, whether it is open), or None when it does not loop.

    Exporters write a loop either closed (the last frame repeats the first: length = duration)
    or open (the last frame leads into the first: one frame longer). The seam is judged on the
    foot signal, which is what phase is made of.
    """
    frames = len(signal)
    first, last = float(signal[1] - signal[0]), float(signal[-1] - signal[-2])
    steepest = float(np.abs(np.diff(signal)).max())
    if abs(last - first) > 0.5 * steepest:
        return None  # the motion does not go on the way it started (half a stride ends reversed)
    closed_error = abs(float(signal[-1] - signal[0]))
    open_error = abs(float(signal[0] - signal[-1]) - 0.5 * (last + first))
    if min(closed_error, open_error) >= 0.1 * amplitude:
        return None
    if closed_error <= open_error:
        return (frames - 1) / fps, False
    return frames / fps, True


def detect_cycle(
    clip: Clip,
    settings: RigSettings,
    posed: Posed | None = None,
    *,
    found: FootSignal | Literal["compute"] = COMPUTE,
) -> GaitCycle | None:
    """The clip's stride, or None when it has no clear one (idle, turn on the spot, a shuffle
    shorter than a stride, a rig without recognisable legs). ``posed``: see `foot_signal`;
    ``found``: `foot_signal`'s answer for ``clip`` when the caller has it (`measure` does)."""
    if clip.frame_count < 8:
        return None
    if isinstance(found, str):
        found = foot_signal(clip, settings, posed)
    if found is None:
        return None
    signal, leg, feet = found
    amplitude = 0.5 * float(np.ptp(signal))
    if leg <= 0.0 or amplitude < MIN_AMPLITUDE * leg:
        return None
    frequency, fit = _stride_frequency(signal, clip.fps)
    if frequency <= 0.0 or fit < MIN_FIT:
        return None
    centred = signal - 0.5 * (signal.max() + signal.min())
    hysteresis = 0.25 * amplitude
    loop = _loop_length(signal, clip.fps, amplitude)
    open_loop, strides = False, 0
    if loop is not None:
        # A loop continues past both ends into itself: crossings there anchor its first and last
        # frames too, and the strides it holds are the upward crossings in one turn of it. Its
        # length then gives the period better than a fit to a not-quite sinusoid.
        length, open_loop = loop
        base = centred if open_loop else centred[:-1]
        ups, downs = _crossings(np.concatenate([base, base, base]), hysteresis)
        ups, downs = ups - len(base), downs - len(base)
        strides = int(((ups >= 0) & (ups < len(base))).sum())
        if strides < 1:
            return None
        frequency = strides / length
    else:
        ups, downs = _crossings(centred, hysteresis)
        if len(ups) + len(downs) < 2:
            return None  # not even a stride between crossings: too short to tell (a half stride)
        strides_between = np.concatenate([np.diff(ups), np.diff(downs)])
        if len(strides_between) >= 2 and strides_between.std() > MAX_STRIDE_SPREAD * strides_between.mean():
            return None  # steps at no steady rhythm (dance, start-stop): no single stride to sync to
    frames = np.arange(clip.frame_count, dtype=np.float64)
    angle = 2.0 * np.pi * frequency * frames / clip.fps
    basis = np.stack([np.sin(angle), np.cos(angle), np.ones_like(angle)], axis=1)
    (a, b, _), *_ = np.linalg.lstsq(basis, signal, rcond=None)
    # a sin(x) + b cos(x) = r sin(x + atan2(b, a)): phase 0 where the sinusoid crosses zero upward.
    marks, values = _anchors(ups, downs, frequency / clip.fps, float(np.arctan2(b, a)) / (2.0 * np.pi))
    if loop is None:
        # The crossings' own mean rate: a drifting cadence biases the sinusoid fit, not them.
        frequency = float(values[-1] - values[0]) / float(marks[-1] - marks[0]) * clip.fps
    rate = frequency / clip.fps  # strides per frame
    # Between crossings the phase runs linearly from one to the next, beyond them at the mean
    # stride rate from the nearest one.
    phase = np.interp(frames, marks, values)
    phase = np.where(frames < marks[0], values[0] - (marks[0] - frames) * rate, phase)
    phase = np.where(frames > marks[-1], values[-1] + (frames - marks[-1]) * rate, phase)
    if loop is None and phase[-1] - phase[0] < MIN_CYCLES:
        return None  # crossings half a stride apart in a clip shorter than a stride
    names = clip.skeleton.names
    return GaitCycle(1.0 / frequency, phase, fit, (names[feet[0]], names[feet[1]]), strides, open_loop)


def frames_at_phases(cycle: GaitCycle, phases: FloatArray) -> FloatArray:
    """Fractional frames of the clip at stride ``phases`` (any real numbers).

    Phases before the clip or past its last whole stride wrap by whole strides into it, so a
    looping clip plays on in step (a clip shorter than a stride holds its last frame). For an
    open loop the result may lie between the last frame and ``frame_count``, which stands for
    the first frame again: the caller interpolates across the seam.
    """
    phase = cycle.phase
    frames = np.arange(len(phase), dtype=np.float64)
    if cycle.open_loop:
        phase = np.append(phase, phase[0] + cycle.loop_strides)
        frames = np.append(frames, float(len(frames)))
    start = float(phase[0])
    whole = float(cycle.loop_strides) or max(1.0, float(np.floor(cycle.cycles + 1e-6)))
    wrapped = start + np.mod(phases - start, whole)
    positions: FloatArray = np.interp(wrapped, phase, frames)
    return positions
