"""SVG of the blend-space diagram and of the trajectory-error map, from a `diagram.Scene`.

Markers carry stable hooks (``data-sample``, ``data-placeholder``, ``data-diagnostic-shape``)
that the report's script and the tests use; colours come from CSS classes so the light and dark
themes and print can restyle them. Everything user-supplied is escaped.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from html import escape

from blendspace_pipeline.report.diagram import (
    PLACEHOLDER_RADIUS,
    SAMPLE_RADIUS,
    Marker,
    Point,
    Problem,
    Scene,
)

LABEL_LIMIT = 60  # above this many samples, names are hidden until the user asks for them
HEAT_EDGE_LIMIT = 300  # above this many samples the error map leaves out the triangle edges
# Above this many samples (or placeholders, or findings) the diagram switches to its level of
# detail for big sets: markers and problem areas drawn as a few merged paths instead of one
# element each, names only where they fit, and the script finds what is under the pointer from
# the embedded positions. The page's element count then no longer grows with the set.
DOM_LIMIT = 400
LOD_LABELS = 150  # at most this many names in the big-set diagram (the ones that fit, greedily)


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
    hidden = " hide-labels" if len(scene.samples) > LABEL_LIMIT else ""
    if is_lod(scene):
        under, over = lod_problem_layers(scene)
        marks = lod_placeholders(scene) + lod_samples(scene)
        hidden += " lod"
    else:
        under, over = problem_layers(scene)
        marks = placeholders(scene) + samples(scene)
    return (
        f'<svg id="space" class="diagram{hidden}" viewBox="0 0 {lay.width} {lay.height}" '
        f'role="img" aria-label="blend-space diagram">'
        f'{PATTERNS}{frame(scene)}{under}{edges_path(scene)}{over}{marks}<g id="selection-layer"></g></svg>'
    )


# ---- level of detail for big sets ---------------------------------------------------------------


def is_lod(scene: Scene) -> bool:
    """Whether the diagram draws merged paths (see `DOM_LIMIT`)."""
    return max(len(scene.samples), len(scene.placeholders), len(scene.problems)) > DOM_LIMIT


def _dots(points: Iterable[Point]) -> str:
    """Zero-length segments: with round (or square) caps each is a dot, all in one path."""
    return "".join(f"M{_n(x)} {_n(y)}h0" for x, y in points)


def _circle_path(x: float, y: float, r: float) -> str:
    return f"M{_n(x - r)} {_n(y)}a{_n(r)} {_n(r)} 0 1 0 {_n(2 * r)} 0a{_n(r)} {_n(r)} 0 1 0 {_n(-2 * r)} 0Z"


def lod_samples(scene: Scene) -> str:
    """Measured clips as round dots, generated ones as square dots: two paths; the names that
    fit without overlapping (at most `LOD_LABELS`)."""
    measured = _dots((m.x, m.y) for m in scene.samples if not m.generated)
    generated = _dots((m.x, m.y) for m in scene.samples if m.generated)
    labels = "".join(
        f'<text x="{_n(m.x + SAMPLE_RADIUS + 3)}" y="{_n(m.y - SAMPLE_RADIUS)}">{escape(m.name)}</text>'
        for m in _fitting_labels(scene)
    )
    # Dots shrink with density (about 0.8 of the spacing of evenly spread samples, 3 to 12 px),
    # so 10,000 clips still show the space between them.
    lay = scene.layout
    spacing = (lay.plot_width * lay.plot_height / max(len(scene.samples), 1)) ** 0.5
    size = f' style="stroke-width:{_n(min(max(0.8 * spacing, 3.0), 2 * SAMPLE_RADIUS))}"'
    return (
        f'<g class="labels">{labels}</g><g class="samples lod-samples">'
        f'<path class="sample-dots"{size} d="{measured}"/>'
        f'<path class="sample-dots generated"{size} d="{generated}"/></g>'
    )


def _fitting_labels(scene: Scene) -> list[Marker]:
    """Names placed greedily (in sample order) where their box overlaps no placed name's box,
    checked on a coarse grid of occupied cells; at most `LOD_LABELS`."""
    cell = 12.0
    taken: set[tuple[int, int]] = set()
    placed: list[Marker] = []
    for m in scene.samples:
        x0, y0 = m.x + SAMPLE_RADIUS + 3, m.y - SAMPLE_RADIUS - 11
        width = 6.2 * len(m.name)
        cells = {
            (cx, cy)
            for cx in range(int(x0 // cell), int((x0 + width) // cell) + 1)
            for cy in range(int(y0 // cell), int((y0 + 13) // cell) + 1)
        }
        if cells & taken:
            continue
        taken |= cells
        # The marker's own cells too: a later name must not cover this clip.
        taken.add((int(m.x // cell), int(m.y // cell)))
        placed.append(m)
        if len(placed) >= LOD_LABELS:
            break
    return placed


def lod_placeholders(scene: Scene) -> str:
    r = PLACEHOLDER_RADIUS
    out = ['<g class="placeholders">']
    for priority in ("necessary", "suggested"):
        d = "".join(
            _path([(p.x, p.y - r), (p.x + r, p.y), (p.x, p.y + r), (p.x - r, p.y)])
            for p in scene.placeholders
            if p.priority == priority
        )
        out.append(f'<path class="placeholder {priority}" d="{d}"/>')
    out.append("</g>")
    return "".join(out)


def _problem_d(problem: Problem, box: tuple[float, float, float, float]) -> str:
    if problem.kind == "region":
        left, top, right, bottom = box
        return (
            f"{_path([(left, top), (right, top), (right, bottom), (left, bottom)])} {_path(problem.points)}"
        )
    if problem.kind == "polygon":
        return _path(problem.points)
    if problem.kind == "circle":
        return _circle_path(*problem.points[0], problem.radius)
    if problem.kind == "edge":
        d = _path(problem.points, closed=False)
        if problem.cross is not None:
            x, y = problem.cross
            d += f"M{_n(x - 5)} {_n(y - 5)}L{_n(x + 5)} {_n(y + 5)}M{_n(x - 5)} {_n(y + 5)}L{_n(x + 5)} {_n(y - 5)}"
        return d
    radius = problem.radius if problem.kind == "rings" else 7.0
    return "".join(_circle_path(x, y, radius) for x, y in problem.points)


def lod_problem_layers(scene: Scene) -> tuple[str, str]:
    """One path per (rule, severity, kind): a few elements for thousands of findings."""
    box = _box(scene)
    groups: dict[tuple[str, str, str], list[str]] = {}
    for problem in scene.problems:
        groups.setdefault((problem.rule, problem.severity, problem.kind), []).append(_problem_d(problem, box))
    under: list[str] = []
    over: list[str] = []
    for (rule, severity, kind), parts in groups.items():
        shape = "rings" if kind in ("rings", "point") else kind
        element = (
            f'<path class="problem rule-{escape(rule)} sev-{escape(severity)} {shape}" '
            f'fill-rule="{"evenodd" if kind == "region" else "nonzero"}" d="{"".join(parts)}"/>'
        )
        (under if kind in ("region", "polygon", "circle") else over).append(element)
    return f'<g class="problems">{"".join(under)}</g>', f'<g class="problems">{"".join(over)}</g>'


def _r1(value: float) -> float:
    return round(value, 1)


def lod_data(scene: Scene) -> dict[str, object]:
    """What the script needs to find and highlight things in the merged drawing: pixel
    positions of samples and placeholders, and each finding's shape (kind, points, radius)."""
    shapes: list[object] = [None] * (max((p.diagnostic for p in scene.problems), default=-1) + 1)
    for p in scene.problems:
        shapes[p.diagnostic] = [p.kind, [[_r1(x), _r1(y)] for x, y in p.points], _r1(p.radius)]
    return {
        "samples": [[_r1(m.x), _r1(m.y)] for m in scene.samples],
        "placeholders": [[_r1(p.x), _r1(p.y)] for p in scene.placeholders],
        "shapes": shapes,
    }


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
    moved = [(a, b) for a, b in view.arrows if abs(a[0] - b[0]) + abs(a[1] - b[1]) > 1.0]
    if len(moved) > DOM_LIMIT:  # one path of shafts and drawn heads instead of an element each
        arrows = f'<path class="drift-path" d="{"".join(_arrow_d(a, b) for a, b in moved)}"/>'
    else:
        arrows = "".join(
            f'<line x1="{_n(a[0])}" y1="{_n(a[1])}" x2="{_n(b[0])}" y2="{_n(b[1])}" '
            'marker-end="url(#arrow-head)"/>'
            for a, b in moved
        )
    samples = f'<path class="heat-samples" d="{dots}"/>'
    return f'<path class="heat-edges" d="{d}"/>{samples}<g class="drift">{arrows}</g>'


def _arrow_d(a: Point, b: Point) -> str:
    """A shaft from ``a`` to ``b`` and a closed head at ``b`` (6 px long), as path data."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length = max((dx * dx + dy * dy) ** 0.5, 1e-9)
    ux, uy = dx / length, dy / length
    bx, by = b[0] - 6 * ux, b[1] - 6 * uy
    return (
        f"M{_n(a[0])} {_n(a[1])}L{_n(b[0])} {_n(b[1])}"
        f"M{_n(b[0])} {_n(b[1])}L{_n(bx - 3 * uy)} {_n(by + 3 * ux)}L{_n(bx + 3 * uy)} {_n(by - 3 * ux)}Z"
    )
