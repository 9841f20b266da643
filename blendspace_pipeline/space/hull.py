"""The convex hull of the samples in normalised space, and the share of the axis square it covers."""

from __future__ import annotations

from collections.abc import Sequence


def hull_coverage(points: list[tuple[float, float]]) -> float:
    """Share (0..1) of the 0..100 square inside the convex hull of ``points`` (clipped to it)."""
    pts = sorted({(min(max(x, 0.0), 100.0), min(max(y, 0.0), 100.0)) for x, y in points})
    hull = convex_hull(pts)
    if len(hull) < 3:
        return 0.0
    area = 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(hull, hull[1:] + hull[:1], strict=True)))
    return area / 10000.0


def convex_hull(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """Convex hull vertices, counter-clockwise (monotone chain); collinear points are left out."""
    pts = sorted(set(points))
    if len(pts) < 3:
        return pts

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-9:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-9:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]
