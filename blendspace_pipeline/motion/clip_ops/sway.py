"""Facing averaged over a gait cycle: the heading a swaying pelvis hides.

The hip line turns with the pelvis, +-4 deg on a calm walk and up to +-25 deg on a swaggering
one, once a stride. Single-frame facings at the ends of a take then misread its turn by up to the
sway, and velocities taken in a swaying frame read low. `measure` and the clip operations that
undo a turn use the same averaged facing, so what one removes the other no longer measures.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from blendspace_pipeline.motion import stats
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops.phase import (
    COMPUTE,
    FootSignal,
    GaitCycle,
    detect_cycle,
    foot_signal,
)
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.quaternions import FloatArray, vector_norm


def sway_free(
    heading: FloatArray,
    clip: Clip,
    settings: RigSettings,
    posed: tuple[FloatArray, FloatArray],
    cycle: GaitCycle | Literal["detect"] | None = "detect",
    positions: FloatArray | None = None,
    *,
    found: FootSignal | Literal["compute"] = COMPUTE,
) -> FloatArray:
    """The hip-line ``heading`` (radians, per frame) of ``clip`` without the pelvis sway.

    ``posed`` is the clip's forward kinematics, ``cycle`` its `detect_cycle` when the caller has
    it ("detect": find it here when the strides alone do not tell the period), ``positions`` the root's ground path (any unit) for the fallback's standing ends. With a
    stride to go by, the sway is taken out by `remove_stride_sway`; without one the heading is
    returned as it is (no gait, no stride-tied sway). ``found``: `phase.foot_signal`'s answer for
    ``clip`` when the caller has it.
    """
    strides = stride_starts(clip, settings, posed, found=found)
    if cycle == "detect":
        few = strides is None or len(strides[0]) < 3
        cycle = detect_cycle(clip, settings, posed, found=found) if few else None
    period = _sway_period(strides[0] if strides is not None else None, cycle, clip.fps)
    if period is None:
        return heading
    if strides is not None:
        return remove_stride_sway(heading, strides[1], clip.fps, period, strides[0])
    still = _still_ends(positions, clip.fps, period) if positions is not None else (False, False)
    return smooth_over_cycle(heading, clip.fps, period, still_ends=still)


def smooth_over_cycle(
    heading: FloatArray, fps: float, period: float, *, still_ends: tuple[bool, bool] = (False, False)
) -> FloatArray:
    """``heading`` averaged over a window of one gait cycle centred on each frame.

    Pelvis yaw repeats once a stride, so its mean over any whole stride is the same and the
    average is the sway-free facing (exact for a constant turn rate, which stays linear). The
    first and last half cycle, where no whole window fits, continue the averaged facing at its
    own rate there: a walk-turn-walk take keeps its flat ends, a constant turn its slope.
    An end where the character stands (``still_ends``: start, end) keeps its own facing: a
    standing pelvis does not sway, and continuing a rate from the start-up or slow-down
    strides there would only add their uneven sway. Clips shorter than a stride and a bit are
    returned as they are.
    """
    frames = len(heading)
    window = period * fps  # frames, fractional
    half = 0.5 * window
    centres = np.arange(frames, dtype=np.float64)
    valid = np.nonzero((centres - half >= 0.0) & (centres + half <= frames - 1))[0]
    if window < 2.0 or len(valid) < 2:
        return heading
    # Exact integral of the piecewise-linear heading up to a fractional frame x.
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (heading[1:] + heading[:-1]))])

    def integral(x: FloatArray) -> FloatArray:
        index = np.clip(np.floor(x).astype(int), 0, frames - 2)
        d = x - index
        slope = heading[index + 1] - heading[index]
        result: FloatArray = cumulative[index] + heading[index] * d + 0.5 * slope * d * d
        return result

    c = valid.astype(np.float64)
    averaged = (integral(c + half) - integral(c - half)) / window
    smoothed = heading.copy()
    smoothed[valid] = averaged
    # The averaged facing's own rate at its first and last frame: d/dc of the window mean is
    # (heading(c + half) - heading(c - half)) / window, two facings one stride apart, so at the
    # same point of the sway: sway-free, and the local rate (0 on a straight lead-in of a
    # walk-turn-walk take, the turn rate on an arc).
    index = np.arange(frames, dtype=np.float64)

    def rate_at(c: float) -> float:
        ahead = np.interp(c + half, index, heading)
        behind = np.interp(c - half, index, heading)
        return float(ahead - behind) / window

    rate_start, rate_end = rate_at(float(valid[0])), rate_at(float(valid[-1]))
    before = centres[: valid[0]]
    after = centres[valid[-1] + 1 :]
    if not still_ends[0]:
        smoothed[: valid[0]] = averaged[0] - rate_start * (valid[0] - before)
    if not still_ends[1]:
        smoothed[valid[-1] + 1 :] = averaged[-1] + rate_end * (after - valid[-1])
    return smoothed


def remove_stride_sway(
    heading: FloatArray, feet: FloatArray, fps: float, period: float, starts: FloatArray
) -> FloatArray:
    """``heading`` with the pelvis sway taken out, frame by frame, with the feet as its clock.

    ``feet`` is the left-minus-right foot signal (`measure.stride_starts`), ``starts`` its
    stride starts (fractional frames) and ``period`` the stride in seconds. Pelvis yaw follows
    the legs (the pelvis turns with the swinging leg), so the sway is a function of where the
    feet are, not of the clock: it is fitted (least squares, a cubic in the foot signal and its
    rate) against a sway-free trend where one is known, and subtracted on every frame, the
    partial strides at the ends included. The trend is the facing's mean over each actual stride
    when there are two or more whole strides (uneven strides then cancel exactly), else its mean
    over a window of one period. Starts and stops (the sway grows with the steps), standing ends
    (no steps, no sway) and a turn that ends in the last stride need no special case: no turn
    rate is ever extrapolated.
    """
    frames = len(heading)
    index = np.arange(frames, dtype=np.float64)
    fit = np.zeros(frames, dtype=bool)
    trend = heading.copy()
    starts = np.clip(np.asarray(starts, dtype=np.float64), 0.0, frames - 1.0)
    lengths = np.diff(starts)
    if len(starts) >= 3 and (lengths > 0.0).all():
        cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (heading[1:] + heading[:-1]))])

        def integral(x: FloatArray) -> FloatArray:
            i = np.clip(np.floor(x).astype(int), 0, frames - 2)
            d = x - i
            result: FloatArray = cumulative[i] + heading[i] * d + 0.5 * (heading[i + 1] - heading[i]) * d * d
            return result

        means = (integral(starts[1:]) - integral(starts[:-1])) / lengths
        centres = 0.5 * (starts[1:] + starts[:-1])
        trend = np.interp(index, centres, means)
        # Past the outer centres, on to the outer starts, at the outer segments' rate.
        first_rate = (means[1] - means[0]) / (centres[1] - centres[0])
        last_rate = (means[-1] - means[-2]) / (centres[-1] - centres[-2])
        trend = np.where(index < centres[0], means[0] + first_rate * (index - centres[0]), trend)
        trend = np.where(index > centres[-1], means[-1] + last_rate * (index - centres[-1]), trend)
        fit = (index >= starts[0]) & (index <= starts[-1])
    else:
        half = 0.5 * period * fps
        fit = (index - half >= 0.0) & (index + half <= frames - 1)
        trend = smooth_over_cycle(heading, fps, period)
    if fit.sum() < 8:
        return heading
    scale = float(np.std(feet[fit])) or 1.0
    z = feet / scale
    rate = np.gradient(z) * period * fps / (2.0 * np.pi)
    basis = np.stack(
        [
            z,
            rate,
            z * z,
            z * rate,
            rate * rate,
            z**3,
            z * z * rate,
            z * rate * rate,
            rate**3,
            np.ones(frames),
        ],
        axis=1,
    )
    coefficients, *_ = np.linalg.lstsq(basis[fit], (heading - trend)[fit], rcond=None)
    fitted = basis @ coefficients
    # The sway is the fit less its mean over the strides it was fitted on: that mean belongs to
    # the facing. (Less the constant term alone, the even terms' own mean stayed in: z^2 and
    # rate^2 are never negative, and on a noisy 3-stride run the fit traded 17 deg between them
    # and the constant, so the facing turned 17 deg and a straight run read direction -17.)
    # Outside the strides it was fitted on (a standing start, a partial stride at an end) the
    # cubic meets foot signals it never saw: no more sway than it fitted is taken out there.
    fitted = np.clip(fitted, fitted[fit].min(), fitted[fit].max())
    result: FloatArray = heading - (fitted - float(fitted[fit].mean()))
    return result


def _still_ends(positions: FloatArray, fps: float, period: float) -> tuple[bool, bool]:
    """Whether the character stands over the first and the last half stride: it moves less
    than a quarter of its average speed there (a take that starts or ends standing)."""
    frames = len(positions)
    reach = int(min(frames - 1, max(1, round(0.5 * period * fps))))
    path = float(vector_norm(np.diff(positions, axis=0)).sum())
    if path <= 0.0:
        return True, True
    typical = path / (frames - 1) * reach
    start = float(np.linalg.norm(positions[reach] - positions[0]))
    end = float(np.linalg.norm(positions[-1] - positions[-1 - reach]))
    return start < 0.25 * typical, end < 0.25 * typical


def _sway_period(starts: FloatArray | None, cycle: GaitCycle | None, fps: float) -> float | None:
    """Seconds per stride to average the facing over: timed by the foot crossings themselves
    when there are several at a steady rhythm (exact on the take's own strides, and found in
    whole takes with a start and a stop, where `detect_cycle` sees no single rhythm), else the
    gait cycle's period; None without a gait."""
    if starts is not None and len(starts) >= 3:
        lengths = np.diff(starts)
        if lengths.std() <= _STRIDE_SPREAD * lengths.mean():
            return float(starts[-1] - starts[0]) / (len(starts) - 1) / fps
    if cycle is None:
        return None
    if starts is not None and len(starts) == 2:
        return float(starts[1] - starts[0]) / fps
    return cycle.period


# Strides may differ this much (coefficient of variation) and still time the sway averaging.
_STRIDE_SPREAD = 0.35


def stride_starts(
    clip: Clip,
    settings: RigSettings,
    posed: tuple[FloatArray, FloatArray],
    *,
    found: FootSignal | Literal["compute"] = COMPUTE,
) -> tuple[FloatArray, FloatArray] | None:
    """(fractional frames where the left foot passes the right one going forward along the
    hip-line facing, one per stride; the foot signal centred on its median). None for a rig
    without recognisable legs. ``found``: `phase.foot_signal`'s answer when the caller has it."""
    if isinstance(found, str):
        found = foot_signal(clip, settings, posed)
    if found is None:
        return None
    signal = found[0]
    centred = signal - stats.median(signal)
    amplitude = stats.percentile(np.abs(centred), 95)
    if amplitude <= 0.0:
        return None
    return _upward_crossings(centred, 0.25 * amplitude), centred


def _upward_crossings(signal: FloatArray, hysteresis: float) -> FloatArray:
    """Fractional frames where ``signal`` crosses zero going up after having been below
    ``-hysteresis`` (wiggles smaller than that are not steps).

    Vectorised: a step from a negative frame to a non-negative one is a crossing when the signal
    went below ``-hysteresis`` somewhere since the previous such step (or the start).
    """
    count = len(signal)
    if count < 2:
        return np.zeros(0)
    a, b = signal[:-1], signal[1:]
    steps = np.nonzero((a < 0.0) & (b >= 0.0))[0]  # step k: frame k to frame k + 1
    below = np.concatenate([[0], np.cumsum(signal < -hysteresis)])  # below[k]: frames < k below
    since = np.concatenate([[0], steps[:-1] + 1])  # the frame after the previous step's start
    armed = steps[below[steps + 1] - below[since] > 0]
    a, b = a[armed], b[armed]
    same = a == b
    ups: FloatArray = np.where(same, armed + 1.0, armed + a / np.where(same, -1.0, a - b))
    return ups.astype(np.float64)
