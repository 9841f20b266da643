"""SVG of the blend-space diagram and of the trajectory-error map, from a `diagram.Scene`.

Markers carry stable hooks (``data-sample``, ``data-placeholder``, ``data-diagnostic-shape``)
that the report's script and the tests use; colours come from CSS classes so the light and dark
themes and print can restyle them. Everything user-supplied is escaped.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from html import escape

from blendspace_pipeline.report.diagram import PLACEHOLDER_RADIUS, SAMPLE_RADIUS, Point, Problem, Scene

LABEL_LIMIT = 60  # above this many samples, names are hidden until the user asks for them
HEAT_EDGE_LIMIT = 300  # above this many samples the error map leaves out the triangle edges


def _n(value: float) -> str:
    """Pixel coordinate: one decimal is below a screen pixel and keeps 1,000-clip files small."""
    text = f"{value:.1f}"
    return text[:-2] if text.endswith(".0") else text


def _path(points: Iterable[Point], closed: bool = True) -> str:
    parts = [f"{_n(x)} {_n(y)}" for x, y in points]
    if not parts:
        return ""
    return "M" + " L".join(parts) + (" Z" if closed else "")


def _box(scene: Scene) -> tuple[float, float, float, float]:
    lay = scene.layout
    return float(lay.left), float(lay.top), lay.left + lay.plot_width, lay.top + lay.plot_height


def frame(scene: Scene) -> str:
    """Plot background, grid with tick labels, main axes through idle, axis titles."""
    left, top, right, bottom = _box(scene)
    out = [
        f'<rect class="plot-bg" x="{_n(left)}" y="{_n(top)}" width="{_n(right - left)}" '
        f'height="{_n(bottom - top)}"/><g class="grid">'
    ]
    for tick in scene.x_ticks:
        out.append(
            f'<line x1="{_n(tick.pixel)}" y1="{_n(top)}" x2="{_n(tick.pixel)}" y2="{_n(bottom)}"/>'
            f'<text class="tick" x="{_n(tick.pixel)}" y="{_n(bottom + 18)}" text-anchor="middle">'
            f"{escape(tick.label)}</text>"
        )
    for tick in scene.y_ticks:
        out.append(
            f'<line x1="{_n(left)}" y1="{_n(tick.pixel)}" x2="{_n(right)}" y2="{_n(tick.pixel)}"/>'
            f'<text class="tick" x="{_n(left - 8)}" y="{_n(tick.pixel + 4)}" text-anchor="end">'
            f"{escape(tick.label)}</text>"
        )
    out.append("</g>")
    out.append(_main_axes(scene))
    x_axis, y_axis = scene.axes
    out.append(
        f'<text class="axis-title" x="{_n((left + right) / 2)}" y="{_n(scene.layout.height - 14)}" '
        f'text-anchor="middle">{escape(f"{x_axis.feature} ({x_axis.unit})")}</text>'
        f'<text class="axis-title" transform="translate(18 {_n((top + bottom) / 2)}) rotate(-90)" '
        f'text-anchor="middle">{escape(f"{y_axis.feature} ({y_axis.unit})")}</text>'
    )
    return "".join(out)


def _main_axes(scene: Scene) -> str:
    left, top, right, bottom = _box(scene)
    out = ['<g class="main-axes">']
    if scene.zero_x is not None:
        out.append(
            f'<line x1="{_n(scene.zero_x)}" y1="{_n(top)}" x2="{_n(scene.zero_x)}" y2="{_n(bottom)}"/>'
        )
    if scene.zero_y is not None:
        out.append(
            f'<line x1="{_n(left)}" y1="{_n(scene.zero_y)}" x2="{_n(right)}" y2="{_n(scene.zero_y)}"/>'
        )
    out.append("</g>")
    return "".join(out)


def _hooks(problem: Problem) -> str:
    return (
        f'class="problem rule-{escape(problem.rule)} sev-{escape(problem.severity)}" '
        f'data-diagnostic-shape="{problem.diagnostic}"'
    )


def _problem(problem: Problem, box: tuple[float, float, float, float]) -> str:
    hooks = _hooks(problem)
    if problem.kind == "region":  # the plot rectangle with the hull cut out
        left, top, right, bottom = box
        outer = _path([(left, top), (right, top), (right, bottom), (left, bottom)])
        return f'<path {hooks} fill-rule="evenodd" d="{outer} {_path(problem.points)}"/>'
    if problem.kind == "polygon":
        return f'<path {hooks} d="{_path(problem.points)}"/>'
    if problem.kind == "circle":
        (x, y), r = problem.points[0], problem.radius
        return f'<circle {hooks} cx="{_n(x)}" cy="{_n(y)}" r="{_n(r)}"/>'
    if problem.kind == "edge":
        return f'<path {hooks} d="{_path(problem.points, closed=False)}"/>' + _cross(problem)
    radius = problem.radius if problem.kind == "rings" else 7.0
    circles = "".join(f'<circle cx="{_n(x)}" cy="{_n(y)}" r="{_n(radius)}"/>' for x, y in problem.points)
    return f"<g {hooks}>{circles}</g>"


def _cross(problem: Problem) -> str:
    """An × where a crossing edge meets the main axis (where the fix puts the new clip)."""
    if problem.cross is None:
        return ""
    x, y = problem.cross
    d = f"M{_n(x - 5)} {_n(y - 5)} L{_n(x + 5)} {_n(y + 5)} M{_n(x - 5)} {_n(y + 5)} L{_n(x + 5)} {_n(y - 5)}"
    return f'<path class="cross" data-diagnostic-shape="{problem.diagnostic}" d="{d}"/>'


def problem_layers(scene: Scene) -> tuple[str, str]:
    """Areas go under the triangle edges; crossing edges, rings and points over them."""
    box = _box(scene)
    under: list[str] = []
    over: list[str] = []
    for problem in scene.problems:
        (under if problem.kind in ("region", "polygon", "circle") else over).append(_problem(problem, box))
    return f'<g class="problems">{"".join(under)}</g>', f'<g class="problems">{"".join(over)}</g>'


def edges_path(scene: Scene, css_class: str = "edges") -> str:
    """All triangle edges as one path: one element instead of thousands for big sets."""
    markers = scene.samples
    d = "".join(
        f"M{_n(markers[a].x)} {_n(markers[a].y)}L{_n(markers[b].x)} {_n(markers[b].y)}"
        for a, b in scene.edges
    )
    return f'<path class="{css_class}" d="{d}"/>' if d else ""


def placeholders(scene: Scene) -> str:
    """Diamonds: orange for necessary clips, green for suggestions (the paper's colours)."""
    r = PLACEHOLDER_RADIUS
    out = ['<g class="placeholders">']
    for p in scene.placeholders:
        d = _path([(p.x, p.y - r), (p.x + r, p.y), (p.x, p.y + r), (p.x - r, p.y)])
        out.append(f'<path class="placeholder {p.priority}" data-placeholder="{p.index}" d="{d}"/>')
    out.append("</g>")
    return "".join(out)


def samples(scene: Scene) -> str:
    """Circles for measured clips, squares for generated ones; names in a separate layer."""
    r = SAMPLE_RADIUS
    labels, marks = ['<g class="labels">'], ['<g class="samples">']
    for m in scene.samples:
        name = escape(m.name, quote=True)
        labels.append(f'<text x="{_n(m.x + r + 3)}" y="{_n(m.y - r)}">{escape(m.name)}</text>')
        if m.generated:
            marks.append(
                f'<rect class="sample generated" data-sample="{name}" x="{_n(m.x - r)}" y="{_n(m.y - r)}" '
                f'width="{_n(2 * r)}" height="{_n(2 * r)}"/>'
            )
        else:
            marks.append(
                f'<circle class="sample" data-sample="{name}" cx="{_n(m.x)}" cy="{_n(m.y)}" r="{_n(r)}"/>'
            )
    return "".join(labels) + "</g>" + "".join(marks) + "</g>"


def diagram(scene: Scene) -> str:
    lay = scene.layout
    under, over = problem_layers(scene)
    hidden = " hide-labels" if len(scene.samples) > LABEL_LIMIT else ""
    return (
        f'<svg id="space" class="diagram{hidden}" viewBox="0 0 {lay.width} {lay.height}" '
        f'role="img" aria-label="blend-space diagram">'
        f"{PATTERNS}{frame(scene)}{under}{edges_path(scene)}{over}{placeholders(scene)}{samples(scene)}</svg>"
    )


PATTERNS = (
    '<defs><pattern id="hatch" width="8" height="8" patternUnits="userSpaceOnUse" '
    'patternTransform="rotate(45)"><rect width="8" height="8" class="hatch-bg"/>'
    '<line x1="0" y1="0" x2="0" y2="8" class="hatch-line"/></pattern></defs>'
)


@dataclass(frozen=True)
class HeatView:
    """One placement shown on the trajectory-error map: its image and its triangulation."""

    mode: str  # "measured" or "manual"
    image: str  # PNG data URI of the error grid
    points: list[Point]  # placed sample positions, pixels
    edges: list[tuple[int, int]]
    hull: list[Point]  # pixels; the map is drawn inside it, the rest is where engines clamp
    arrows: list[tuple[Point, Point]] = field(default_factory=list)  # hand placement → measured


def heat_map(
    scene: Scene,
    views: list[HeatView],
    grid_shape: tuple[int, int],
    ident: str = "heat",
    label: str = "trajectory-error map",
) -> str:
    """The error image stretched so that grid points sit on their axis values, clipped to the plot."""
    left, top, right, bottom = _box(scene)
    ny, nx = grid_shape
    half_w, half_h = (right - left) / (nx - 1) / 2, (bottom - top) / (ny - 1) / 2
    lay = scene.layout
    # The arrows of hand placement point with this marker (only the trajectory map draws them).
    marker = "arrow-head" if ident == "heat" else f"{ident}-arrow-head"
    out = [
        f'<svg id="{ident}" class="diagram" viewBox="0 0 {lay.width} {lay.height}" role="img" '
        f'aria-label="{label}"><defs><marker id="{marker}" viewBox="0 0 10 10" refX="9" '
        'refY="5" markerWidth="6" markerHeight="6" '
        'orient="auto-start-reverse"><path d="M0 0 L10 5 L0 10 z" class="arrow-head"/></marker></defs>',
        frame(scene),
    ]
    for view in views:
        hidden = "" if view.mode == "measured" else " hidden"
        clip = f"{ident}-hull-{view.mode}"
        outer = _path([(left, top), (right, top), (right, bottom), (left, bottom)])
        out.append(
            f'<g class="heat-view" data-mode="{view.mode}"{hidden}><clipPath id="{clip}">'
            f'<path d="{_path(view.hull)}"/></clipPath><image href="{view.image}" x="{_n(left - half_w)}" '
            f'y="{_n(top - half_h)}" width="{_n(right - left + 2 * half_w)}" '
            f'height="{_n(bottom - top + 2 * half_h)}" preserveAspectRatio="none" clip-path="url(#{clip})"/>'
            f'<path class="heat-outside" fill-rule="evenodd" d="{outer} {_path(view.hull)}"/>'
            f"{_main_axes(scene)}{_view_overlay(view)}</g>"
        )
    out.append("</svg>")
    return "".join(out)


def _view_overlay(view: HeatView) -> str:
    pts = view.points
    # Hundreds of triangles over the map are noise: big sets show only the samples.
    edges = view.edges if len(pts) <= HEAT_EDGE_LIMIT else []
    d = "".join(f"M{_n(pts[a][0])} {_n(pts[a][1])}L{_n(pts[b][0])} {_n(pts[b][1])}" for a, b in edges)
    dots = "".join(f"M{_n(x)} {_n(y)}h0" for x, y in pts)  # round caps of zero-length lines: one path
    arrows = "".join(
        f'<line x1="{_n(a[0])}" y1="{_n(a[1])}" x2="{_n(b[0])}" y2="{_n(b[1])}" '
        'marker-end="url(#arrow-head)"/>'
        for a, b in view.arrows
        if abs(a[0] - b[0]) + abs(a[1] - b[1]) > 1.0
    )
    samples = f'<path class="heat-samples" d="{dots}"/>'
    return f'<path class="heat-edges" d="{d}"/>{samples}<g class="drift">{arrows}</g>'
