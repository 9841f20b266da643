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


class NearPoints:
    """Points bucketed in square cells of side ``radius``: "is any point strictly closer than
    ``radius``?" looks at the cells around the query only, with the very `distance` comparison a
    scan of every point makes (so the same answer), instead of n comparisons per query.

    Cells two away are looked at too: a division rounded the wrong way never hides a neighbour.
    Points that are not finite, and every query when ``radius`` is not a positive finite number,
    fall back to the scan.
    """

    def __init__(self, points: Sequence[Sequence[float]], radius: float):
        self.radius = radius
        self.points = list(points)
        self.bucketed = radius > 0.0 and math.isfinite(radius)
        self.cells: dict[tuple[int, int], list[Sequence[float]]] = {}
        self.loose: list[Sequence[float]] = []
        if self.bucketed:
            for point in self.points:
                if math.isfinite(point[0]) and math.isfinite(point[1]):
                    cell = (math.floor(point[0] / radius), math.floor(point[1] / radius))
                    self.cells.setdefault(cell, []).append(point)
                else:
                    self.loose.append(point)

    def any_closer(self, point: Sequence[float]) -> bool:
        radius = self.radius
        if not (self.bucketed and math.isfinite(point[0]) and math.isfinite(point[1])):
            return any(distance(other, point) < radius for other in self.points)
        cx, cy = math.floor(point[0] / radius), math.floor(point[1] / radius)
        for dx in range(-2, 3):
            for dy in range(-2, 3):
                for other in self.cells.get((cx + dx, cy + dy), ()):
                    if distance(other, point) < radius:
                        return True
        return any(distance(other, point) < radius for other in self.loose)


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
