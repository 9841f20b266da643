"""`N.png`: the blend-space diagram for CI pages, chat and thumbnails, drawn with OpenImageIO.

The only module of the package that imports OpenImageIO. It draws the same `diagram.Scene` as
the HTML report: translucent areas (uncovered hatch, acute triangles, too-close clusters) are
painted with numpy first, then OIIO draws grid, edges, outlines, markers and text. Everything is
drawn at twice the size and reduced with a box filter, which anti-aliases OIIO's one-pixel lines
and text without changing the colour at a marker's centre.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from OpenImageIO import ImageBufAlgo as algo

from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.report.atomic import atomic_path
from blendspace_pipeline.report.diagram import (
    COLOURS,
    PLACEHOLDER_RADIUS,
    SAMPLE_RADIUS,
    Layout,
    Point,
    Problem,
    Scene,
    build_scene,
    problem_colour,
)
from blendspace_pipeline.space.document import BlendSpaceDocument

PNG_LAYOUT = Layout(width=1280, height=960, left=84, right=270, top=78, bottom=70)
SCALE = 2  # supersampling factor
LABEL_LIMIT = 60  # more samples than this: names would hide the diagram
Colour = tuple[float, float, float]


def write_png(doc: BlendSpaceDocument, path: Path) -> None:
    """Render the diagram and write it atomically (temporary file in the same folder, then rename)."""
    image = render(doc)
    with atomic_path(Path(path), suffix=".tmp.png") as temporary:  # OIIO picks the format by extension
        if not image.write(str(temporary), oiio.UINT8):
            raise OSError(f"{path}: could not write the PNG: {image.geterror()}")


def render(doc: BlendSpaceDocument) -> oiio.ImageBuf:
    """The diagram as an RGB float image of `PNG_LAYOUT`'s size."""
    big = _scaled(PNG_LAYOUT)
    scene = build_scene(doc, big)
    canvas = _paint_areas(scene)
    buf = oiio.ImageBuf(oiio.ImageSpec(big.width, big.height, 3, "float"))
    buf.set_pixels(oiio.ROI(0, big.width, 0, big.height, 0, 1, 0, 3), canvas.astype(np.float32))
    _draw_frame(buf, scene)
    _draw_problems(buf, scene)
    _draw_markers(buf, scene)
    _draw_titles(buf, scene, doc)
    _draw_legend(buf, scene)
    small = oiio.ImageBuf(oiio.ImageSpec(PNG_LAYOUT.width, PNG_LAYOUT.height, 3, "float"))
    algo.resize(small, buf, filtername="box")
    return small


def _scaled(layout: Layout) -> Layout:
    return Layout(
        *(
            SCALE * v
            for v in (layout.width, layout.height, layout.left, layout.right, layout.top, layout.bottom)
        )
    )


def _rgb(name: str) -> Colour:
    r, g, b = COLOURS[name]
    return r / 255.0, g / 255.0, b / 255.0


def _c(rgb: tuple[int, int, int]) -> Colour:
    return rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0


# ---- translucent areas, painted in numpy --------------------------------------------------------


def _paint_areas(scene: Scene) -> FloatArray:
    lay = scene.layout
    canvas = np.empty((lay.height, lay.width, 3), dtype=np.float64)
    canvas[:] = _rgb("background")
    left, top = lay.left, lay.top
    right, bottom = int(lay.left + lay.plot_width), int(lay.top + lay.plot_height)
    canvas[top:bottom, left:right] = _rgb("plot")
    for problem in scene.problems:
        if problem.kind == "region":
            _hatch_outside(canvas, problem.points, (left, top, right, bottom))
        elif problem.kind == "polygon":
            _fill(canvas, _polygon_mask(canvas, problem.points), _c(problem_colour(problem.rule)), 0.35)
        elif problem.kind == "circle":
            _fill(
                canvas,
                _disc_mask(canvas, problem.points[0], problem.radius),
                _c(problem_colour(problem.rule)),
                0.15,
            )
    return canvas


def _fill(
    canvas: FloatArray, mask: tuple[slice, slice, np.ndarray] | None, colour: Colour, alpha: float
) -> None:
    if mask is None:
        return
    rows, cols, inside = mask
    region = canvas[rows, cols]
    region[inside] = (1.0 - alpha) * region[inside] + alpha * np.asarray(colour)


def _bounds(canvas: FloatArray, xs: Sequence[float], ys: Sequence[float]) -> tuple[slice, slice] | None:
    height, width = canvas.shape[:2]
    x0, x1 = max(0, int(min(xs))), min(width, math.ceil(max(xs)) + 1)
    y0, y1 = max(0, int(min(ys))), min(height, math.ceil(max(ys)) + 1)
    if x0 >= x1 or y0 >= y1:
        return None
    return slice(y0, y1), slice(x0, x1)


def _polygon_mask(canvas: FloatArray, points: list[Point]) -> tuple[slice, slice, np.ndarray] | None:
    """Pixels inside a convex polygon, within its bounding box.

    Convex, so each pixel row crosses it in one span: intersect the row with every edge and
    keep the extremes. Rows × edges work instead of pixels × edges, which matters for the hull.
    """
    box = _bounds(canvas, [p[0] for p in points], [p[1] for p in points])
    if box is None or len(points) < 3:
        return None
    ys = np.arange(box[0].start, box[0].stop) + 0.5
    xs = np.arange(box[1].start, box[1].stop) + 0.5
    low, high = np.full(ys.shape, np.inf), np.full(ys.shape, -np.inf)
    for (ax, ay), (bx, by) in zip(points, points[1:] + points[:1], strict=True):
        if ay == by:
            continue  # a horizontal edge adds nothing its neighbours' end points do not
        t = (ys - ay) / (by - ay)
        crossing = (t >= 0.0) & (t <= 1.0)
        x = ax + t * (bx - ax)
        low = np.where(crossing, np.minimum(low, x), low)
        high = np.where(crossing, np.maximum(high, x), high)
    inside = (xs[None, :] >= low[:, None]) & (xs[None, :] <= high[:, None])
    return box[0], box[1], inside


def _disc_mask(canvas: FloatArray, centre: Point, radius: float) -> tuple[slice, slice, np.ndarray] | None:
    cx, cy = centre
    box = _bounds(canvas, [cx - radius, cx + radius], [cy - radius, cy + radius])
    if box is None:
        return None
    yy, xx = np.mgrid[box[0], box[1]] + 0.5
    return box[0], box[1], (xx - cx) ** 2 + (yy - cy) ** 2 <= radius**2


def _hatch_outside(canvas: FloatArray, hull: list[Point], box: tuple[int, int, int, int]) -> None:
    """Diagonal hatching over the plot outside the hull: the uncovered area."""
    left, top, right, bottom = box
    yy, xx = np.mgrid[top:bottom, left:right]
    stripes = (xx + yy) % (8 * SCALE) < 3 * SCALE
    inside = np.zeros_like(stripes)
    if len(hull) >= 3:
        mask = _polygon_mask(canvas, hull)
        if mask is not None:
            full = np.zeros(canvas.shape[:2], dtype=bool)
            full[mask[0], mask[1]] = mask[2]
            inside = full[top:bottom, left:right]
    _fill(canvas, (slice(top, bottom), slice(left, right), stripes & ~inside), _rgb("uncovered-area"), 0.45)


# ---- lines and shapes, drawn with OpenImageIO ---------------------------------------------------


def _line(buf: oiio.ImageBuf, a: Point, b: Point, colour: Colour, width: float = 1.0) -> None:
    """A line ``width`` pixels wide, as parallel one-pixel lines along its normal."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length = math.hypot(dx, dy) or 1.0
    nx, ny = -dy / length, dx / length
    # Half-pixel steps: whole-pixel offsets along a diagonal normal round onto the same rows
    # and leave gaps.
    for offset in np.arange(-(width - 1) / 2.0, (width - 1) / 2.0 + 0.01, 0.5):
        ox, oy = nx * offset, ny * offset
        algo.render_line(
            buf,
            round(a[0] + ox),
            round(a[1] + oy),
            round(b[0] + ox),
            round(b[1] + oy),
            colour,
            skip_first_point=False,
        )


def _circle(buf: oiio.ImageBuf, centre: Point, radius: float, colour: Colour, width: float) -> None:
    segments = max(24, int(radius))
    points = [
        (
            centre[0] + radius * math.cos(2 * math.pi * k / segments),
            centre[1] + radius * math.sin(2 * math.pi * k / segments),
        )
        for k in range(segments + 1)
    ]
    for a, b in itertools.pairwise(points):
        _line(buf, a, b, colour, width)


def _disc(buf: oiio.ImageBuf, centre: Point, radius: float, colour: Colour) -> None:
    """Filled disc as one box per scanline (OIIO has no filled-circle primitive)."""
    cx, cy = round(centre[0]), round(centre[1])
    r = round(radius)
    for dy in range(-r, r + 1):
        half = math.floor(math.sqrt(max(0.0, radius * radius - dy * dy)))
        algo.render_box(buf, cx - half, cy + dy, cx + half, cy + dy, colour, fill=True)


def _diamond(buf: oiio.ImageBuf, centre: Point, radius: float, colour: Colour) -> None:
    cx, cy = round(centre[0]), round(centre[1])
    r = round(radius)
    for dy in range(-r, r + 1):
        half = r - abs(dy)
        algo.render_box(buf, cx - half, cy + dy, cx + half, cy + dy, colour, fill=True)


def _square(buf: oiio.ImageBuf, centre: Point, radius: float, colour: Colour) -> None:
    cx, cy, r = round(centre[0]), round(centre[1]), round(radius)
    algo.render_box(buf, cx - r, cy - r, cx + r, cy + r, colour, fill=True)


def _draw_frame(buf: oiio.ImageBuf, scene: Scene) -> None:
    lay = scene.layout
    left, top = float(lay.left), float(lay.top)
    right, bottom = lay.left + lay.plot_width, lay.top + lay.plot_height
    grid, muted = _rgb("grid"), _rgb("muted")
    for tick in scene.x_ticks:
        _line(buf, (tick.pixel, top), (tick.pixel, bottom), grid, SCALE)
        _text(buf, tick.pixel, bottom + 20 * SCALE, tick.label, 13, muted, align="center")
    for tick in scene.y_ticks:
        _line(buf, (left, tick.pixel), (right, tick.pixel), grid, SCALE)
        _text(buf, left - 8 * SCALE, tick.pixel + 5 * SCALE, tick.label, 13, muted, align="right")
    axis = _rgb("main-axis")
    if scene.zero_x is not None:
        _line(buf, (scene.zero_x, top), (scene.zero_x, bottom), axis, 2 * SCALE)
    if scene.zero_y is not None:
        _line(buf, (left, scene.zero_y), (right, scene.zero_y), axis, 2 * SCALE)
    algo.render_box(buf, int(left), int(top), int(right), int(bottom), _rgb("muted"))
    edge = _rgb("edge")
    for a, b in scene.edges:
        sa, sb = scene.samples[a], scene.samples[b]
        _line(buf, (sa.x, sa.y), (sb.x, sb.y), edge, 1.5 * SCALE)


def _draw_problems(buf: oiio.ImageBuf, scene: Scene) -> None:
    """Outlines over the edges: crossing edges, acute triangles, clusters, rings."""
    for problem in scene.problems:
        colour = _c(problem_colour(problem.rule))
        if problem.kind == "edge":
            _line(buf, problem.points[0], problem.points[1], colour, 4 * SCALE)
            _cross(buf, problem, colour)
        elif problem.kind == "polygon":
            for a, b in zip(problem.points, problem.points[1:] + problem.points[:1], strict=True):
                _line(buf, a, b, colour, 1.5 * SCALE)
        elif problem.kind == "circle":
            _circle(buf, problem.points[0], problem.radius, colour, 1.5 * SCALE)
        elif problem.kind == "rings":
            ring = colour if problem.rule in COLOURS else _severity_colour(problem.severity)
            for centre in problem.points:
                _circle(buf, centre, problem.radius, ring, 2 * SCALE)
        elif problem.kind == "point":
            _circle(buf, problem.points[0], 7 * SCALE, _severity_colour(problem.severity), 2 * SCALE)


def _severity_colour(severity: str) -> Colour:
    return {"error": _c((214, 39, 40)), "warning": _c((201, 138, 0))}.get(severity, _c((58, 120, 194)))


def _cross(buf: oiio.ImageBuf, problem: Problem, colour: Colour) -> None:
    if problem.cross is None:
        return
    x, y = problem.cross
    d = 6 * SCALE
    _line(buf, (x - d, y - d), (x + d, y + d), colour, 2 * SCALE)
    _line(buf, (x - d, y + d), (x + d, y - d), colour, 2 * SCALE)


def _draw_markers(buf: oiio.ImageBuf, scene: Scene) -> None:
    """Labels first, then placeholders, then samples, so every marker's centre keeps its colour."""
    white = _rgb("background")
    if len(scene.samples) <= LABEL_LIMIT:
        for m in scene.samples:
            _text(
                buf, m.x + (SAMPLE_RADIUS + 4) * SCALE, m.y - SAMPLE_RADIUS * SCALE, m.name, 12, _rgb("text")
            )
    for p in scene.placeholders:
        _diamond(buf, (p.x, p.y), (PLACEHOLDER_RADIUS + 1.5) * SCALE, white)
        _diamond(buf, (p.x, p.y), PLACEHOLDER_RADIUS * SCALE, _rgb(p.priority))
    for m in scene.samples:
        if m.generated:
            _square(buf, (m.x, m.y), (SAMPLE_RADIUS + 1.5) * SCALE, white)
            _square(buf, (m.x, m.y), SAMPLE_RADIUS * SCALE, _rgb("generated"))
        else:
            _disc(buf, (m.x, m.y), (SAMPLE_RADIUS + 1.5) * SCALE, white)
            _disc(buf, (m.x, m.y), SAMPLE_RADIUS * SCALE, _rgb("sample"))


# ---- text ---------------------------------------------------------------------------------------


@cache
def _font() -> str | None:
    """A font OIIO can render with: the wheel bundles DroidSans; None (no labels) when none works."""
    probe = oiio.ImageBuf(oiio.ImageSpec(64, 32, 3, "float"))
    for name in ("DroidSans", "DejaVuSans", ""):
        if algo.render_text(probe, 2, 20, "Ag", 12, name, (1.0, 1.0, 1.0)):
            return name
        probe.geterror()  # clear the error so the next attempt reports its own
    warnings.warn(
        "OpenImageIO found no font: the PNG is drawn without text (install fonts-dejavu-core)", stacklevel=2
    )
    return None


def _text(
    buf: oiio.ImageBuf,
    x: float,
    y: float,
    text: str,
    size: int,
    colour: Colour,
    align: str = "left",
    bold: bool = False,
) -> None:
    font = _font()
    if font is None or not text:
        return
    name = f"{font}-Bold" if bold and font == "DroidSans" else font
    algo.render_text(buf, round(x), round(y), text, size * SCALE, name, colour, alignx=align)


def _draw_titles(buf: oiio.ImageBuf, scene: Scene, doc: BlendSpaceDocument) -> None:
    lay = scene.layout
    counts = {s: sum(d.severity == s for d in doc.diagnostics) for s in ("error", "warning", "info")}
    generated = sum(s.generated for s in doc.samples)
    _text(buf, lay.left, 32 * SCALE, f"{doc.name} — blend space", 22, _rgb("text"), bold=True)
    summary = (
        f"{len(doc.samples) - generated} clips, {generated} generated · {counts['error']} errors, "
        f"{counts['warning']} warnings, {counts['info']} info · coverage {scene.coverage:.1f}% · "
        f"{len(doc.placeholders)} clips to add"
    )
    _text(buf, lay.left, 56 * SCALE, summary, 13, _rgb("muted"))
    x_axis, y_axis = scene.axes
    centre_x = lay.left + lay.plot_width / 2
    _text(
        buf,
        centre_x,
        lay.height - 18 * SCALE,
        f"{x_axis.feature} ({x_axis.unit})",
        14,
        _rgb("text"),
        "center",
    )
    _vertical_text(buf, 14 * SCALE, lay.top + lay.plot_height / 2, f"{y_axis.feature} ({y_axis.unit})", 14)


def _vertical_text(buf: oiio.ImageBuf, x: float, centre_y: float, text: str, size: int) -> None:
    """Text reading bottom to top: rendered flat on a patch, rotated, pasted."""
    if _font() is None:
        return
    extent = algo.text_size(text, size * SCALE, _font() or "")
    width, height = extent.xend - extent.xbegin + 4, extent.yend - extent.ybegin + 4
    patch = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, "float"))
    algo.fill(patch, _rgb("background"))
    _text(patch, 2 - extent.xbegin, 2 - extent.ybegin, text, size, _rgb("text"))
    turned = algo.rotate270(patch)
    algo.paste(buf, round(x), round(centre_y - width / 2), 0, 0, turned)


LEGEND = [
    ("sample", "measured clip"),
    ("generated", "generated clip"),
    ("necessary", "necessary clip to add"),
    ("suggested", "suggested clip to add"),
    ("crossing-axis", "edge crossing a main axis"),
    ("acute-triangle", "acute triangle"),
    ("misalignment", "misaligned clip"),
    ("too-close", "clips too close"),
    ("uncovered-area", "uncovered area"),
]


def _draw_legend(buf: oiio.ImageBuf, scene: Scene) -> None:
    lay = scene.layout
    x = lay.left + lay.plot_width + 28 * SCALE
    y = float(lay.top + 10 * SCALE)
    _text(buf, x, y, "Legend", 15, _rgb("text"), bold=True)
    for key, label in LEGEND:
        y += 30 * SCALE
        _swatch(buf, key, (x + 10 * SCALE, y - 5 * SCALE))
        _text(buf, x + 28 * SCALE, y, label, 13, _rgb("text"))


def _swatch(buf: oiio.ImageBuf, key: str, centre: Point) -> None:
    colour = _rgb(key)
    r = 7 * SCALE
    if key == "sample":
        _disc(buf, centre, SAMPLE_RADIUS * SCALE, colour)
    elif key == "generated":
        _square(buf, centre, SAMPLE_RADIUS * SCALE, colour)
    elif key in ("necessary", "suggested"):
        _diamond(buf, centre, PLACEHOLDER_RADIUS * SCALE, colour)
    elif key == "crossing-axis":
        _line(buf, (centre[0] - r, centre[1]), (centre[0] + r, centre[1]), colour, 4 * SCALE)
    elif key in ("misalignment", "too-close"):
        _circle(buf, centre, r, colour, 2 * SCALE)
    else:
        x0, y0, x1, y1 = centre[0] - r, centre[1] - r, centre[0] + r, centre[1] + r
        if key == "acute-triangle":
            light = tuple(0.35 * c + 0.65 for c in colour)
            algo.render_box(buf, round(x0), round(y0), round(x1), round(y1), light, fill=True)
        else:  # the uncovered-area hatching
            for a, b in (((x0, y1), (x1, y0)), ((x0, y0 + r), (x0 + r, y0)), ((x0 + r, y1), (x1, y0 + r))):
                _line(buf, a, b, colour, SCALE)
        algo.render_box(buf, round(x0), round(y0), round(x1), round(y1), colour)
