"""uncovered-area: the part of the axis rectangle outside the convex hull of the samples."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView, placeholder


def _hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Convex hull, counter-clockwise (monotone chain)."""
    pts = sorted(set(points))
    if len(pts) < 3:
        return pts

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def _area(polygon: list[tuple[float, float]]) -> float:
    return 0.5 * abs(
        sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(polygon, polygon[1:] + polygon[:1], strict=True))
    )


def _inside(point: tuple[float, float], hull: list[tuple[float, float]]) -> bool:
    if len(hull) < 3:
        return False
    for a, b in zip(hull, hull[1:] + hull[:1], strict=True):
        if (b[0] - a[0]) * (point[1] - a[1]) - (b[1] - a[1]) * (point[0] - a[0]) < -1e-9:
            return False
    return True


def covered_fraction(points: list[tuple[float, float]]) -> float:
    """Share of the 0..100 square inside the hull of ``points`` (hull clipped to the square)."""
    clipped = [(min(max(x, 0.0), 100.0), min(max(y, 0.0), 100.0)) for x, y in points]
    hull = _hull(clipped)
    return _area(hull) / 10000.0 if len(hull) >= 3 else 0.0


class UncoveredArea(Rule):
    """The part of the axis rectangle outside the convex hull of the samples is not covered:
    engines clamp queries there to the hull boundary, so the character cannot reach those
    speeds and turn rates. Reports the covered percentage and suggests clips at the uncovered
    corners and edge midpoints of the rectangle.
    """

    slug = "uncovered-area"
    code = "BS005"
    severity = "info"
    summary = "part of the axis rectangle outside the hull; reports covered %"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        points = [s.normalised for s in space.samples]
        covered = covered_fraction(points) * 100.0
        if covered >= 99.999:
            return
        hull = _hull(points)
        marks = []
        for candidate in ((0, 0), (100, 0), (100, 100), (0, 100), (50, 0), (100, 50), (50, 100), (0, 50)):
            point = (float(candidate[0]), float(candidate[1]))
            if not _inside(point, hull):
                position = space.to_axis_units(point)
                marks.append(placeholder(space, position, "suggested", self.slug, "extends coverage"))
        yield self.report(
            f"the samples cover {covered:.1f}% of the axis rectangle",
            hint="queries outside the hull are clamped to its edge; add clips at the suggested positions "
            "or narrow the axis ranges to what the set covers",
            placeholders=marks,
        )
