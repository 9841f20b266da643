"""The faster built-in rule internals answer exactly as the scans they replace: `any_closer_each`
(missing-opposite's "any sample near the mirrored position") and `smallest_angles`
(acute-triangle's filter before the exact per-triangle angles)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from blendspace_pipeline.rules._geometry import (
    ANGLE_MARGIN,
    angles,
    any_closer_each,
    distance,
    smallest_angles,
)


@pytest.mark.parametrize("radius", [0.0, -1.0, 1e-9, 0.7, 5.0, 30.0, math.inf, math.nan])
def test_near_points_answers_as_the_scan(radius: float) -> None:
    rng = np.random.default_rng(3)
    grid = [(float(x), float(y)) for x in range(0, 101, 5) for y in range(0, 101, 5)]  # exact ties
    points = grid + [tuple(p) for p in rng.uniform(-5, 105, (300, 2)).tolist()]
    points.append((math.nan, 3.0))
    queries = grid + [tuple(q) for q in rng.uniform(-10, 110, (400, 2)).tolist()]
    queries += [
        (math.nan, 1.0),
        (math.inf, 2.0),
        (5.0 + radius, 5.0) if math.isfinite(radius) else (1.0, 1.0),
    ]
    answers = any_closer_each(points, queries, radius)
    for query, answer in zip(queries, answers, strict=True):
        assert answer == any(distance(p, query) < radius for p in points), query


def test_near_points_at_exactly_the_radius_is_not_closer() -> None:
    assert any_closer_each([(10.0, 10.0)], [(13.0, 10.0), (12.999999, 10.0)], 3.0) == [False, True]


def test_smallest_angles_never_drops_a_triangle_the_exact_angle_keeps() -> None:
    rng = np.random.default_rng(11)
    corners = rng.uniform(0, 100, (5000, 3, 2))
    corners[:50, 2] = corners[:50, 0] + 1e-9 * (corners[:50, 1] - corners[:50, 0])  # slivers
    corners[50:60, 1] = corners[50:60, 0]  # degenerate: two corners at one point
    rough = smallest_angles(corners)
    for limit in (0.0, 1e-4, 1.0, 15.0, 30.0, 59.9):
        kept = set(np.flatnonzero(~(rough >= limit + ANGLE_MARGIN)).tolist())
        exact = {i for i, c in enumerate(corners.tolist()) if min(angles(*map(tuple, c))) < limit}
        assert exact <= kept
        assert len(kept - exact) <= 60 + len(corners) // 100  # a filter: few extra exact checks
    exact_min = np.array([min(angles(*map(tuple, c))) for c in corners.tolist()])
    finite = ~np.isnan(rough)
    assert np.max(np.abs(rough[finite] - exact_min[finite])) < ANGLE_MARGIN / 100
