"""Facing averaged over a gait cycle: the heading a swaying pelvis hides.

The hip line turns with the pelvis, +-4 deg on a calm walk and up to +-25 deg on a swaggering
one, once a stride. Single-frame facings at the ends of a take then misread its turn by up to the
sway, and velocities taken in a swaying frame read low. `measure` and the clip operations that
undo a turn use the same averaged facing, so what one removes the other no longer measures.
"""

from __future__ import annotations

import numpy as np

from blendspace_pipeline.motion.quaternions import FloatArray


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
