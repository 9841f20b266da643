"""`np.percentile` and `np.median` of 1-D arrays, to the last bit, without their overhead.

Measuring a clip takes a dozen medians and percentiles of a few hundred values; numpy's general
versions (any axis, any method, weights, NaN handling) spend several times the partition itself
on bookkeeping. These take the same order statistics (a partition finds them whatever its
algorithm) and interpolate with numpy's own formulas ("linear" method), so the results are
identical; an array holding NaN goes to numpy, as do empty ones.
"""

from __future__ import annotations

import math

import numpy as np

from blendspace_pipeline.motion.quaternions import FloatArray


def percentiles(values: FloatArray, qs: tuple[float, ...]) -> list[float]:
    """``np.percentile(values, q)`` for each ``q`` of ``qs`` (0-100), ``values`` 1-D."""
    values = np.asarray(values, dtype=np.float64)
    count = len(values)
    if count == 0 or values.ndim != 1 or any(not 0.0 <= q <= 100.0 for q in qs):
        return [float(np.percentile(values, q)) for q in qs]
    spots = []
    for q in qs:
        virtual = (count - 1) * (q / 100.0)  # numpy: (n - 1) * true_divide(q, 100)
        if virtual >= count - 1:  # numpy takes the last value from both sides (index -1)
            spots.append((count - 1, count - 1, virtual + 1.0))
        else:
            below = math.floor(virtual)
            spots.append((below, below + 1, virtual - below))
    order = np.partition(values, sorted({i for spot in spots for i in spot[:2]} | {count - 1}))
    if math.isnan(order[-1]):  # NaN sorts last: numpy's answer is NaN
        return [float(np.percentile(values, q)) for q in qs]
    result = []
    for below, above, gamma in spots:
        a, b = float(order[below]), float(order[above])
        difference = b - a
        # numpy's `_lerp`: from the nearer end, so gamma = 1 gives b exactly.
        result.append(b - difference * (1.0 - gamma) if gamma >= 0.5 else a + difference * gamma)
    return result


def percentile(values: FloatArray, q: float) -> float:
    """``np.percentile(values, q)`` (0-100) of 1-D ``values``."""
    return percentiles(values, (q,))[0]


def median(values: FloatArray) -> float:
    """``np.median(values)`` of 1-D ``values``: the middle value, or the mean of the two."""
    values = np.asarray(values, dtype=np.float64)
    count = len(values)
    if count == 0 or values.ndim != 1:
        return float(np.median(values))
    half = count // 2
    order = np.partition(values, [half - 1, half, count - 1] if count % 2 == 0 else [half, count - 1])
    if math.isnan(order[-1]):
        return float(np.median(values))
    # numpy's mean of the middle value(s): a sum that starts from +0.0 (so -0.0 reads 0.0).
    if count % 2:
        return 0.0 + float(order[half])
    return (0.0 + float(order[half - 1]) + float(order[half])) / 2.0
