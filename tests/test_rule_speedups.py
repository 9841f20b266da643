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


# The engine's own hot paths on a 1,000-clip space (anchoring ~4,500 findings, checking them,
# the placeholder search's nearness test) answer exactly as the code they replace.


def test_evolve_is_dataclasses_replace() -> None:
    import dataclasses

    from blendspace_pipeline.diagnostics import Diagnostic, Placeholder

    mark = Placeholder((1.0, 2.0), "suggested", "too-close", "why", {"speed": 1.0})
    found = Diagnostic("too-close", "BS004", "warning", "m", ("a", "b"), (1.0, 2.0), placeholders=(mark,))
    for changes in ({"path": "m.yaml", "line": 3, "column": 5}, {"hint": "h"}, {"placeholders": ()}, {}):
        evolved = found.evolve(**changes)
        assert evolved == dataclasses.replace(found, **changes)
        assert type(evolved) is Diagnostic and evolved is not found
    assert found.path is None  # the original is untouched
    with pytest.raises(TypeError, match="no field 'lines'"):
        found.evolve(lines=3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        found.evolve(line=3).line = 4  # type: ignore[misc]


def test_evolve_of_a_subclass_runs_its_post_init() -> None:
    import dataclasses

    from blendspace_pipeline.diagnostics import Diagnostic

    seen = []

    @dataclasses.dataclass(frozen=True)
    class StudioFinding(Diagnostic):
        ticket: str = ""

        def __post_init__(self) -> None:
            seen.append(self.line)

    finding = StudioFinding("studio-rule", "ST001", "info", "m", ticket="T-1")
    evolved = finding.evolve(line=7)
    assert type(evolved) is StudioFinding and evolved.ticket == "T-1" and evolved.line == 7
    assert seen == [None, 7]


def test_finite_number_answers_as_the_abc_check() -> None:
    import numbers
    from fractions import Fraction

    from blendspace_pipeline.checks.rule_engine import _finite_number

    values = [0.0, -1.5, math.nan, math.inf, -math.inf, 3, True, np.float64(2.0), np.float32(math.nan)]
    values += [np.int64(4), Fraction(1, 3), "1.0", None, (1.0,), complex(1, 0)]
    for value in values:
        expected = isinstance(value, numbers.Real) and math.isfinite(value)
        assert _finite_number(value) == expected, value


@pytest.mark.parametrize("tau", [0.0, 1e-200, 1e-160, 1e-100, 1e-9, 0.5, 3.0, 12.5, 1e100, 1e160])
def test_placeholder_nearness_answers_as_the_scan(tau: float) -> None:
    from blendspace_pipeline.pipeline.placeholders import _near_samples

    rng = np.random.default_rng(11)
    grid = [(float(x), float(y)) for x in range(0, 101, 3) for y in range(0, 101, 4)]  # exact ties
    staying = np.array(grid + rng.uniform(0, 100, (500, 2)).tolist(), dtype=np.float64)
    if tau == 3.0:  # a sample at a NaN position is never "far enough" for the scan either
        staying = np.vstack([staying, [[math.nan, 50.0]]])
    points = [(float(x) + tau, float(y)) for x, y in grid[::7]]  # exactly tau from a sample
    points += [(float(x), float(y)) for x, y in rng.uniform(-2, 102, (300, 2)).tolist()]
    points += [(p[0] + math.nextafter(tau, 0.0), p[1]) for p in grid[::11]]  # one ulp inside
    points += [(p[0] + tau * (1.0 - 1e-9), p[1]) for p in grid[::13]]
    points += [(p[0] + tau * 0.6, p[1] + tau * 0.8) for p in grid[::17]]  # exactly tau on a diagonal
    points += [(p[0], p[1]) for p in grid[::19]]  # on a sample
    answers = _near_samples(points, staying, tau)
    for point, near in zip(points, answers, strict=True):
        scan = not all(math.hypot(point[0] - q[0], point[1] - q[1]) >= tau for q in staying.tolist())
        assert near == scan, point
    assert _near_samples([], staying, tau) == []
    assert _near_samples(points[:3], staying[:0], tau) == [False] * 3
