"""The reading most clips agree with, when readings within a relative tolerance are one reading
(a unit written rounded, a frame rate a reader adjusted to fit the clip's length)."""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections import Counter
from collections.abc import Callable, Hashable
from itertools import accumulate
from typing import TypeVar

K = TypeVar("K", bound=Hashable)


def close(a: float, b: float, tolerance: float) -> bool:
    """Whether ``a`` and ``b`` are within ``tolerance`` of the larger one."""
    return abs(a - b) <= tolerance * max(abs(a), abs(b))


def most_agreed(
    counts: Counter[K],
    value: Callable[[K], float],
    tolerance: float,
    group: Callable[[K], Hashable] = lambda _: None,
) -> K:
    """The key of ``counts`` that the most counted items agree with: the same ``group`` and a
    ``value`` within ``tolerance`` (`close`); on a tie, the one counted first. Per group the values
    are sorted and each one's agreeing items counted by bisection (n log n, not n^2: a library is
    thousands of clips). Values must be positive."""
    agreeing: dict[K, int] = {}
    for kind in {group(key) for key in counts}:
        keys = sorted((key for key in counts if group(key) == kind), key=value)
        values = [value(key) for key in keys]
        totals = list(accumulate(counts[key] for key in keys))
        for key, own in zip(keys, values, strict=True):
            low = bisect_left(values, own * (1.0 - tolerance))
            high = bisect_right(values, own / (1.0 - tolerance))
            agreeing[key] = totals[high - 1] - (totals[low - 1] if low else 0)
    return max(counts, key=agreeing.__getitem__)  # the first maximal one, in the order counted
