"""uncovered-area: the part of the axis rectangle outside the convex hull of the samples."""

from __future__ import annotations

import math
from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import inside_rectangle

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


# What a body can do, for coverage suggestions on (turn rate, speed) axes. Ours, not the paper's:
# turning at speed v on a circle of radius r needs a centripetal acceleration v * omega; people
# sustain about 0.7 g (7 m/s^2) on a bend, so the turn rate a body can hold shrinks as 1 / speed.
LATERAL_ACCELERATION = 7.0  # m/s^2
TURN_FEATURES = ("turn_rate",)
SPEED_FEATURES = ("speed", "forward_speed", "displacement_speed")
# The rectangle is "wider than the set" when it reaches beyond the envelope by more than this
# share of its range on a side (ours: one grid step of the default 4-division Unreal grid is 25%,
# a tenth of the range is well inside that and above snapping noise).
SLACK = 0.10


def envelope(space: SpaceView) -> list[tuple[float, float]]:
    """Positions (axis units) a new clip may be suggested at: corners of what the set can do.

    The set's extents on each axis bound it (a turn rate symmetrically: what a body does to the
    left it does to the right). On (turn rate, speed) axes the turn rate is also capped by what a body holds at that speed
    (`LATERAL_ACCELERATION`): at the fastest speeds the corners come in towards turn 0.
    """
    xs = [s.measured[0] for s in space.samples]
    ys = [s.measured[1] for s in space.samples]
    x_lo, x_hi, y_lo, y_hi = min(xs), max(xs), min(ys), max(ys)
    features = (space.axes[0].feature, space.axes[1].feature)
    turn = 0 if features[0] in TURN_FEATURES else 1 if features[1] in TURN_FEATURES else None
    speed = 1 - turn if turn is not None and features[1 - turn] in SPEED_FEATURES else None
    if turn is not None:  # a body turns both ways as fast: the turn extent is symmetric
        reach = max(abs(v) for v in (xs if turn == 0 else ys))
        if turn == 0:
            x_lo, x_hi = -reach, reach
        else:
            y_lo, y_hi = -reach, reach
    if turn is None or speed is None:
        points = [(x_lo, y_lo), (x_hi, y_lo), (x_hi, y_hi), (x_lo, y_hi)]
        points += [((x_lo + x_hi) / 2, y_lo), (x_hi, (y_lo + y_hi) / 2)]
        points += [((x_lo + x_hi) / 2, y_hi), (x_lo, (y_lo + y_hi) / 2)]
        return points
    lo, hi = (x_lo, x_hi) if turn == 0 else (y_lo, y_hi)
    slow, fast = (y_lo, y_hi) if speed == 1 else (x_lo, x_hi)
    found: list[tuple[float, float]] = []
    for v in (slow, 0.0, fast) if slow < 0.0 < fast else (slow, fast):
        cap = math.degrees(LATERAL_ACCELERATION / abs(v)) if abs(v) > 1e-9 else math.inf
        for w in (max(lo, -cap), min(hi, cap)):
            found.append((w, v) if turn == 0 else (v, w))
    return found


class UncoveredArea(Rule):
    """The part of the axis rectangle outside the convex hull of the samples is not covered:
    engines clamp queries there to the hull boundary, so the character cannot reach those
    speeds and turn rates. Reports the covered percentage and suggests clips that would extend
    the hull, only where a body can move (`envelope`: within the authored extents, and on
    (turn rate, speed) axes with the turn rate shrinking as speed grows). Where the rectangle
    reaches beyond that (by more than `SLACK` of a range), the finding says to narrow the axes
    instead: no clip can fill that part.
    """

    slug = "uncovered-area"
    code = "BS005"
    severity = "info"
    summary = "part of the axis rectangle outside the hull; reports covered %"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        points = [s.normalised for s in space.samples]
        covered = covered_fraction(points) * 100.0
        if covered >= 99.999 or not space.samples:
            return
        hull = _hull(points)
        marks = []
        feasible = envelope(space)
        for position in feasible:
            point = space.to_normalised(position)
            if inside_rectangle(point) and not _inside(point, hull) and _away(point, hull):
                marks.append(placeholder(space, position, "suggested", self.slug, "extends coverage"))
        narrow = self._narrower(space, feasible)
        hint = "queries outside the hull are clamped to its edge; add clips at the suggested positions"
        message = f"the samples cover {covered:.1f}% of the axis rectangle"
        if narrow:
            message += f"; the axes reach beyond what the set can do: narrow {narrow}"
            hint += "; no clip can fill the rest of the rectangle, narrow the axes to what a body can do"
        else:
            hint += " or narrow the axis ranges to what the set covers"
        yield self.report(message, hint=hint, placeholders=marks)

    @staticmethod
    def _narrower(space: SpaceView, feasible: list[tuple[float, float]]) -> str:
        """`x to [a, b], y to [c, d]` for each axis the rectangle overshoots, or ''."""
        parts = []
        for index, axis in enumerate(space.axes):
            values = [p[index] for p in feasible] + [
                0.0 if axis.minimum <= 0.0 <= axis.maximum else axis.minimum
            ]
            lo, hi = max(min(values), axis.minimum), min(max(values), axis.maximum)
            span = axis.maximum - axis.minimum
            if hi <= lo:  # the set does not spread on this axis: nothing to narrow to
                continue
            if (lo - axis.minimum) > SLACK * span or (axis.maximum - hi) > SLACK * span:
                parts.append(f"{axis.feature} to [{lo:.3g}, {hi:.3g}]")
        return ", ".join(parts)


def _away(point: tuple[float, float], hull: list[tuple[float, float]]) -> bool:
    """Whether ``point`` lies more than a hair outside the hull (not on its edge, up to noise)."""
    if len(hull) < 3:
        return True
    cx = sum(p[0] for p in hull) / len(hull)
    cy = sum(p[1] for p in hull) / len(hull)
    shrunk = (cx + (point[0] - cx) * 0.999, cy + (point[1] - cy) * 0.999)
    return not _inside(shrunk, hull)
