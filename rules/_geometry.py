"""Small geometric helpers shared by the built-in rules (normalised space, 0..100 per axis)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from blendspace_pipeline.api import SpaceView

Point = tuple[float, float]


def main_axes(space: SpaceView) -> tuple[float | None, float | None]:
    """Normalised coordinates of the lines x = 0 and y = 0 (None when 0 is outside the range)."""
    x_axis, y_axis = space.axes
    x0 = space.to_normalised((0.0, 0.0))[0] if x_axis.minimum <= 0.0 <= x_axis.maximum else None
    y0 = space.to_normalised((0.0, 0.0))[1] if y_axis.minimum <= 0.0 <= y_axis.maximum else None
    return x0, y0


def distance(a: Sequence[float], b: Sequence[float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def angles(a: Point, b: Point, c: Point) -> tuple[float, float, float]:
    """Interior angles in degrees at a, b and c."""

    def at(p: Point, q: Point, r: Point) -> float:
        v1 = (q[0] - p[0], q[1] - p[1])
        v2 = (r[0] - p[0], r[1] - p[1])
        norm = math.hypot(*v1) * math.hypot(*v2)
        if norm == 0.0:
            return 0.0
        cosine = max(-1.0, min(1.0, (v1[0] * v2[0] + v1[1] * v2[1]) / norm))
        return math.degrees(math.acos(cosine))

    return at(a, b, c), at(b, c, a), at(c, a, b)


def circumcenter(a: Point, b: Point, c: Point) -> Point | None:
    d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-12:
        return None
    sa, sb, sc = a[0] ** 2 + a[1] ** 2, b[0] ** 2 + b[1] ** 2, c[0] ** 2 + c[1] ** 2
    return (
        (sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1])) / d,
        (sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])) / d,
    )


def inside_rectangle(point: Point) -> bool:
    return -1e-9 <= point[0] <= 100.0 + 1e-9 and -1e-9 <= point[1] <= 100.0 + 1e-9


def any_closer_each(
    points: Sequence[Sequence[float]], queries: Sequence[Sequence[float]], radius: float
) -> list[bool]:
    """For each query: is any of ``points`` strictly closer than ``radius``, by the very
    `distance` comparison a scan of every point makes (so the same answers), without n
    comparisons per query: a k-d tree proposes the points within a slightly larger radius and
    only those are compared. A distance involving a non-finite coordinate is never below a finite
    radius, so such points and queries need no comparison; an infinite radius is scanned."""
    if not radius > 0.0:
        return [False] * len(queries)  # no distance is below zero (or NaN)
    if not math.isfinite(radius):
        return [any(distance(other, query) < radius for other in points) for query in queries]
    finite = [p for p in points if math.isfinite(p[0]) and math.isfinite(p[1])]
    asked = [i for i, q in enumerate(queries) if math.isfinite(q[0]) and math.isfinite(q[1])]
    answers = [False] * len(queries)
    if not finite or not asked:
        return answers
    from scipy.spatial import cKDTree  # local import: scipy loads only when a rule asks

    tree = cKDTree(np.asarray(finite, dtype=np.float64).reshape(-1, 2))
    where = np.asarray([queries[i] for i in asked], dtype=np.float64).reshape(-1, 2)
    for i, candidates in zip(asked, tree.query_ball_point(where, radius * (1.0 + 1e-6)), strict=True):
        answers[i] = any(distance(finite[j], queries[i]) < radius for j in sorted(candidates))
    return answers


def smallest_angles(corners: Any) -> Any:
    """(T,) the smallest interior angle (degrees) of each triangle of ``corners`` (T, 3, 2), in
    numpy: a filter before `angles` (NaN for a degenerate triangle). Rounding differs from
    `angles` by far less than `ANGLE_MARGIN`, so rules test the exact angle of the few triangles
    within that margin of their limit and report exactly what a per-triangle loop would."""
    a = np.asarray(corners, dtype=np.float64).reshape(-1, 3, 2)
    found = np.full(len(a), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(3):
            p, q, r = a[:, i], a[:, (i + 1) % 3], a[:, (i + 2) % 3]
            v1, v2 = q - p, r - p
            norm = np.hypot(v1[:, 0], v1[:, 1]) * np.hypot(v2[:, 0], v2[:, 1])
            cosine = np.clip((v1[:, 0] * v2[:, 0] + v1[:, 1] * v2[:, 1]) / norm, -1.0, 1.0)
            angle = np.where(norm == 0.0, 0.0, np.degrees(np.arccos(cosine)))
            found = np.fmin(found, angle)
            found[np.isnan(angle)] = np.nan
    return found


# Degrees. numpy's and math's angles differ by under 1e-6 degrees even for near-zero angles (where
# acos is steepest), about 1e-13 near the default limit.
ANGLE_MARGIN = 1e-3
