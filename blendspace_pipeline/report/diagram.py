"""The blend-space diagram as renderer-neutral shapes in pixel coordinates.

The SVG of the HTML report and the OpenImageIO PNG draw the same `Scene`, so both show the same
thing at the same place and the PNG tests can compute where a marker must be. Problem areas
follow the paper's figure 1: crossing edges, acute triangles, misaligned clips, too-close
clusters and the uncovered part of the axis rectangle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.space.document import AxisDoc, BlendSpaceDocument, DiagnosticDoc
from blendspace_pipeline.space.geometry import NORMALISED_EXTENT, AxisRange, normalise
from blendspace_pipeline.space.triangulate import triangle_edges

Point = tuple[float, float]
ProblemKind = Literal["edge", "polygon", "rings", "circle", "region", "point"]

# One palette for both renderers (the SVG's light theme and the PNG), as 0..255 RGB.
COLOURS: dict[str, tuple[int, int, int]] = {
    "background": (255, 255, 255),
    "plot": (248, 249, 251),
    "grid": (222, 226, 232),
    "main-axis": (70, 76, 86),
    "text": (32, 36, 42),
    "muted": (110, 118, 130),
    "edge": (150, 160, 176),
    "sample": (31, 111, 235),
    "generated": (142, 68, 173),
    "necessary": (242, 140, 40),
    "suggested": (44, 160, 44),
    "crossing-axis": (214, 39, 40),
    "acute-triangle": (230, 180, 0),
    "misalignment": (227, 119, 194),
    "too-close": (23, 170, 200),
    "uncovered-area": (150, 150, 150),
    "other": (214, 39, 40),
}
SAMPLE_RADIUS = 6.0
PLACEHOLDER_RADIUS = 8.0


@dataclass(frozen=True)
class Layout:
    """Pixel frame of the diagram: the plot box inside the margins, y growing downwards."""

    width: int = 960
    height: int = 720
    left: int = 70
    right: int = 30
    top: int = 30
    bottom: int = 60
    scale: float = 1.0  # size of markers and rings relative to the SVG's (the PNG draws at 2x)

    @property
    def plot_width(self) -> float:
        return float(self.width - self.left - self.right)

    @property
    def plot_height(self) -> float:
        return float(self.height - self.top - self.bottom)

    def project(self, normalised: FloatArray) -> FloatArray:
        """Normalised 0..100 points (N, 2) → pixel coordinates (N, 2)."""
        points = np.atleast_2d(np.asarray(normalised, dtype=np.float64))
        px = self.left + points[:, 0] / NORMALISED_EXTENT * self.plot_width
        py = self.top + (1.0 - points[:, 1] / NORMALISED_EXTENT) * self.plot_height
        return np.stack([px, py], axis=-1)


@dataclass(frozen=True)
class Tick:
    value: float
    pixel: float
    label: str


@dataclass(frozen=True)
class Marker:
    index: int
    name: str
    x: float
    y: float
    generated: bool = False


@dataclass(frozen=True)
class PlaceholderMarker:
    index: int
    x: float
    y: float
    priority: Literal["necessary", "suggested"]


@dataclass(frozen=True)
class Problem:
    """A problem area of one diagnostic: ``points`` in pixels; ``radius`` for rings and circles."""

    diagnostic: int
    rule: str
    severity: str
    kind: ProblemKind
    points: list[Point]
    radius: float = 0.0
    cross: Point | None = None  # where a crossing edge meets the main axis


@dataclass
class Scene:
    layout: Layout
    axes: tuple[AxisDoc, AxisDoc]
    x_ticks: list[Tick]
    y_ticks: list[Tick]
    zero_x: float | None  # pixel x of the line x = 0 (the main axis through idle), if in range
    zero_y: float | None
    samples: list[Marker]
    edges: list[tuple[int, int]]  # sample indices of each triangle edge, once each
    hull: list[Point]  # counter-clockwise in normalised space; empty when there are no triangles
    placeholders: list[PlaceholderMarker]
    problems: list[Problem] = field(default_factory=list)
    coverage: float = 0.0  # percent of the axis rectangle inside the hull


def axis_ranges(doc: BlendSpaceDocument) -> tuple[AxisRange, AxisRange]:
    x, y = doc.axes
    return AxisRange(x.min, x.max), AxisRange(y.min, y.max)


def nice_step(span: float, target: int = 8) -> float:
    """A 1, 2, 2.5 or 5 × 10^k step giving about ``target`` intervals over ``span``."""
    if span <= 0 or not math.isfinite(span):
        return 1.0
    raw = span / target
    power = 10.0 ** math.floor(math.log10(raw))
    for factor in (1.0, 2.0, 2.5, 5.0, 10.0):
        if raw <= factor * power + 1e-12:
            return factor * power
    return 10.0 * power


def ticks(axis: AxisDoc, to_pixel: tuple[float, float], target: int = 8) -> list[Tick]:
    """Grid values of ``axis`` (multiples of a nice step, so 0 is one when in range) in pixels.

    ``to_pixel`` maps the axis minimum and maximum to their pixel coordinates.
    """
    step = nice_step(axis.max - axis.min, target)
    first = math.ceil(axis.min / step - 1e-9)
    last = math.floor(axis.max / step + 1e-9)
    result = []
    for k in range(first, last + 1):
        value = k * step + 0.0
        fraction = (value - axis.min) / (axis.max - axis.min)
        pixel = to_pixel[0] + fraction * (to_pixel[1] - to_pixel[0])
        result.append(Tick(value, pixel, f"{value:g}"))
    return result


def convex_hull(points: FloatArray) -> list[Point]:
    """Counter-clockwise hull (monotone chain); fewer than 3 points when degenerate."""
    points = _outside_octagon(np.asarray(points, dtype=np.float64).reshape(-1, 2))
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) < 3:
        return pts

    def half(sequence: list[Point]) -> list[Point]:
        chain: list[Point] = []
        for p in sequence:
            while len(chain) >= 2 and _cross(chain[-2], chain[-1], p) <= 1e-12:
                chain.pop()
            chain.append(p)
        return chain[:-1]

    return half(pts) + half(pts[::-1])


def _outside_octagon(points: FloatArray) -> FloatArray:
    """The points not strictly inside the polygon of the eight extreme points (along x, y and
    both diagonals): only those can be on the hull (Akl-Toussaint), a few dozen of thousands."""
    if len(points) < 64:
        return points
    directions = np.array(
        [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)], dtype=np.float64
    )
    extremes = points[np.argmax(points @ directions.T, axis=0)]  # counter-clockwise order
    corners = [tuple(p) for p in extremes]
    corners = [c for i, c in enumerate(corners) if c != corners[i - 1]]
    if len(corners) < 3 or polygon_area(corners) <= 0.0:
        return points
    octagon = np.array(corners)
    a, b = octagon, np.roll(octagon, -1, axis=0)
    # Strictly left of every counter-clockwise edge (with a margin for rounding): inside.
    cross = (b[None, :, 0] - a[None, :, 0]) * (points[:, None, 1] - a[None, :, 1]) - (
        b[None, :, 1] - a[None, :, 1]
    ) * (points[:, None, 0] - a[None, :, 0])
    scale = np.abs(points).max() + 1.0
    inside = (cross > 1e-9 * scale * scale).all(axis=1)
    kept: FloatArray = points[~inside]
    return kept


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def polygon_area(polygon: list[Point]) -> float:
    pairs = zip(polygon, polygon[1:] + polygon[:1], strict=True)
    return 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in pairs))


def clip_to_square(polygon: list[Point]) -> list[Point]:
    """Sutherland–Hodgman clip of a convex polygon to the 0..100 square (samples can lie outside)."""
    edges = [(0, 0.0, 1.0), (0, NORMALISED_EXTENT, -1.0), (1, 0.0, 1.0), (1, NORMALISED_EXTENT, -1.0)]
    result = polygon
    for axis, bound, sign in edges:
        if not result:
            break
        current, result = result, []
        for a, b in zip(current, current[1:] + current[:1], strict=True):
            a_in, b_in = sign * (a[axis] - bound) >= 0, sign * (b[axis] - bound) >= 0
            if a_in:
                result.append(a)
            if a_in != b_in:
                t = (bound - a[axis]) / (b[axis] - a[axis])
                result.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
    return result


def coverage_percent(hull: list[Point]) -> float:
    """Share of the axis rectangle inside the hull (hull clipped to the rectangle), percent."""
    if len(hull) < 3:
        return 0.0
    return polygon_area(clip_to_square(hull)) / NORMALISED_EXTENT**2 * 100.0


def build_scene(doc: BlendSpaceDocument, layout: Layout | None = None) -> Scene:
    layout = layout or Layout()
    axes = axis_ranges(doc)
    normalised = normalise(
        np.asarray([s.position for s in doc.samples], dtype=np.float64).reshape(-1, 2), axes
    )
    pixels = layout.project(normalised) if len(doc.samples) else np.zeros((0, 2))
    used = sorted({i for tri in doc.triangles for i in tri})
    hull = convex_hull(normalised[used]) if used else []
    x_axis, y_axis = doc.axes
    right, bottom = layout.left + layout.plot_width, layout.top + layout.plot_height
    scene = Scene(
        layout=layout,
        axes=(x_axis, y_axis),
        x_ticks=ticks(x_axis, (layout.left, right)),
        y_ticks=ticks(y_axis, (bottom, layout.top), target=7),
        zero_x=_zero_pixel(x_axis, (layout.left, right)),
        zero_y=_zero_pixel(y_axis, (bottom, layout.top)),
        samples=[
            Marker(i, s.name, float(pixels[i, 0]), float(pixels[i, 1]), s.generated)
            for i, s in enumerate(doc.samples)
        ],
        edges=triangle_edges(doc.triangles),
        hull=hull,
        placeholders=_placeholders(doc, layout, axes),
        coverage=coverage_percent(hull),
    )
    by_name = {m.name: m for m in scene.samples}  # once: thousands of findings look clips up
    # Every finding's position projected in one call (NaN rows: no position).
    at = np.full((len(doc.diagnostics), 2), np.nan)
    for i, d in enumerate(doc.diagnostics):
        if d.position is not None and len(d.position) == 2:
            at[i] = d.position
    where = layout.project(normalise(at, axes)) if len(at) else at
    scene.problems = [
        p
        for i, d in enumerate(doc.diagnostics)
        if (p := _problem(i, d, scene, doc, where[i], by_name)) is not None
    ]
    return scene


def _zero_pixel(axis: AxisDoc, to_pixel: tuple[float, float]) -> float | None:
    if not axis.min <= 0.0 <= axis.max or axis.max == axis.min:
        return None
    return to_pixel[0] + (0.0 - axis.min) / (axis.max - axis.min) * (to_pixel[1] - to_pixel[0])


def _placeholders(
    doc: BlendSpaceDocument, layout: Layout, axes: tuple[AxisRange, AxisRange]
) -> list[PlaceholderMarker]:
    if not doc.placeholders:
        return []
    pixels = layout.project(
        normalise(np.asarray([p.position for p in doc.placeholders], dtype=np.float64), axes)
    )
    return [
        PlaceholderMarker(i, float(pixels[i, 0]), float(pixels[i, 1]), p.priority)
        for i, p in enumerate(doc.placeholders)
    ]


def _problem(
    index: int,
    diagnostic: DiagnosticDoc,
    scene: Scene,
    doc: BlendSpaceDocument,
    position: FloatArray,
    by_name: dict[str, Marker],
) -> Problem | None:
    """The area that shows a diagnostic in the diagram, by rule; None when it has no place.
    ``position`` is the finding's position in pixels (NaN without one)."""
    members = [(by_name[c].x, by_name[c].y) for c in diagnostic.clips if c in by_name]
    where = None if np.isnan(position).any() else (float(position[0]), float(position[1]))

    def make(
        kind: ProblemKind, points: list[Point], radius: float = 0.0, cross: Point | None = None
    ) -> Problem:
        return Problem(index, diagnostic.rule, diagnostic.severity, kind, points, radius, cross)

    if diagnostic.rule == "uncovered-area":
        return make("region", [_pixel(p, scene.layout) for p in scene.hull])
    if diagnostic.rule == "crossing-axis" and len(members) == 2:
        return make("edge", members, cross=where)
    if diagnostic.rule == "acute-triangle" and len(members) == 3:
        return make("polygon", members)
    if diagnostic.rule == "too-close" and len(members) >= 2:
        centre = where or (float(np.mean([p[0] for p in members])), float(np.mean([p[1] for p in members])))
        reach = max(math.hypot(p[0] - centre[0], p[1] - centre[1]) for p in members)
        return make("circle", [centre], reach + 2.0 * SAMPLE_RADIUS * scene.layout.scale)
    if members and len(members) < len(doc.samples):  # a rule about every clip would ring them all
        return make("rings", members, 2.2 * SAMPLE_RADIUS * scene.layout.scale)
    if where is not None:
        return make("point", [where])
    return None


def _pixel(normalised: Point, layout: Layout) -> Point:
    projected = layout.project(np.asarray([normalised]))
    return float(projected[0, 0]), float(projected[0, 1])


def problem_colour(rule: str) -> tuple[int, int, int]:
    return COLOURS.get(rule, COLOURS["other"])
