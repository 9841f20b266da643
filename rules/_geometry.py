"""Small geometric helpers shared by the built-in rules (normalised space, 0..100 per axis)."""

from __future__ import annotations

import math
from collections.abc import Sequence

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
