"""`N.png`: the blend-space diagram for CI pages, chat and thumbnails, drawn with OpenImageIO.

The only module of the package that imports OpenImageIO. It draws the same `diagram.Scene` as
the HTML report: translucent areas (uncovered hatch, acute triangles, too-close clusters) are
painted with numpy first, then grid, edges, outlines and markers are rasterised in numpy too
(`_Pen`: thousands of segments and markers at once, so 10,000 samples cost about as much as a
few hundred), and OIIO draws the text and the legend. Everything is drawn at twice the size and
reduced with a box filter, which anti-aliases the one-pixel lines and text without changing the
colour at a marker's centre.
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
    pen = _Pen(canvas)
    _draw_frame(pen, scene)
    _draw_problems(pen, scene)
    buf = oiio.ImageBuf(oiio.ImageSpec(big.width, big.height, 3, "float"))
    roi = oiio.ROI(0, big.width, 0, big.height, 0, 1, 0, 3)
    if len(scene.samples) <= LABEL_LIMIT:
        # Names go under the markers (a neighbour's label must not cover a marker's centre): OIIO
        # draws them on the canvas so far, the markers follow on its result.
        buf.set_pixels(roi, canvas.astype(np.float32))
        _draw_labels(buf, scene)
        pen = _Pen(np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64).reshape(canvas.shape))
    _draw_markers(pen, scene)
    buf.set_pixels(roi, pen.canvas.astype(np.float32))
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


class _Pen:
    """Lines and filled markers rasterised straight into the numpy canvas, many at a time.

    A line ``width`` pixels wide is parallel one-pixel lines half a pixel apart along its normal
    (whole-pixel offsets along a diagonal normal round onto the same rows and leave gaps), each
    from its rounded end point to the other, one pixel per step along its longer extent. Filled
    markers (disc, square, diamond) are one span per scanline, like OIIO's boxes were. Colours
    are opaque: a later shape covers an earlier one.
    """

    def __init__(self, canvas: FloatArray):
        self.canvas = canvas
        self.height, self.width = canvas.shape[:2]

    def lines(self, starts: FloatArray, ends: FloatArray, colour: Colour, width: float = 1.0) -> None:
        """Segments ``starts[i]`` -> ``ends[i]`` (pixels, (S, 2)), all in one colour."""
        starts = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
        ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
        if not len(starts):
            return
        delta = ends - starts
        length = np.hypot(delta[:, 0], delta[:, 1])
        length[length == 0.0] = 1.0
        normal = np.stack([-delta[:, 1] / length, delta[:, 0] / length], axis=1)
        offsets = np.arange(-(width - 1) / 2.0, (width - 1) / 2.0 + 0.01, 0.5)
        shifted = normal[None, :, :] * offsets[:, None, None]  # (O, S, 2)
        a = np.round(starts[None] + shifted).reshape(-1, 2).astype(np.int64)
        b = np.round(ends[None] + shifted).reshape(-1, 2).astype(np.int64)
        steps = np.abs(b - a).max(axis=1) + 1  # pixels per one-pixel line
        line = np.repeat(np.arange(len(a)), steps)
        first = np.cumsum(steps) - steps
        along = (np.arange(int(steps.sum())) - first[line]) / np.maximum(steps[line] - 1, 1)
        xs = np.round(a[line, 0] + along * (b[line, 0] - a[line, 0])).astype(np.int64)
        ys = np.round(a[line, 1] + along * (b[line, 1] - a[line, 1])).astype(np.int64)
        self._paint(xs, ys, colour)

    def line(self, a: Point, b: Point, colour: Colour, width: float = 1.0) -> None:
        self.lines(np.array([a]), np.array([b]), colour, width)

    def circle(self, centre: Point, radius: float, colour: Colour, width: float) -> None:
        segments = max(24, int(radius))
        angle = 2.0 * np.pi * np.arange(segments + 1) / segments
        points = np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)], axis=1)
        self.lines(points[:-1], points[1:], colour, width)

    def markers(
        self,
        centres: FloatArray,
        kinds: np.ndarray,
        layers_for: Sequence[Sequence[tuple[str, float, Colour]]],
    ) -> None:
        """Marker i at ``centres[i]`` drawn with the (shape, radius, colour) layers of kind
        ``kinds[i]``, in order: every marker's layers before the next marker's, so a later
        marker's outline covers an earlier marker as drawing them one by one would."""
        centres = np.round(np.asarray(centres, dtype=np.float64).reshape(-1, 2)).astype(np.int64)
        if not len(centres):
            return
        # Each kind's layers flattened into one template of pixel offsets and colour indices; a
        # pixel a later layer of the same marker paints again is left out of the earlier one.
        dxs, dys, colour_ids, sizes = [], [], [], []
        palette: list[Colour] = []
        for layers in layers_for:
            covered: dict[tuple[int, int], int] = {}
            for shape, radius, colour in layers:
                for offset in zip(*(a.tolist() for a in _shape_offsets(shape, radius)), strict=True):
                    covered.pop(offset, None)
                    covered[offset] = len(palette)
                palette.append(colour)
            dxs.append(np.array([x for x, _ in covered], dtype=np.int64))
            dys.append(np.array([y for _, y in covered], dtype=np.int64))
            colour_ids.append(np.array(list(covered.values()), dtype=np.int64))
            sizes.append(len(covered))
        template_start = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        template_dx, template_dy = np.concatenate(dxs), np.concatenate(dys)
        template_colour = np.concatenate(colour_ids)
        counts = np.asarray(sizes, dtype=np.int64)[kinds]
        marker = np.repeat(np.arange(len(centres)), counts)
        first = np.cumsum(counts) - counts
        slot = template_start[kinds][marker] + np.arange(int(counts.sum())) - first[marker]
        xs = centres[marker, 0] + template_dx[slot]
        ys = centres[marker, 1] + template_dy[slot]
        keep = (xs >= 0) & (xs < self.width) & (ys >= 0) & (ys < self.height)
        flat = (ys * self.width + xs)[keep]
        # The last write to each pixel wins: the highest write index that reaches it.
        last = np.full(self.width * self.height, -1, dtype=np.int64)
        np.maximum.at(last, flat, np.arange(len(flat)))
        pixels = np.flatnonzero(last >= 0)
        colours = np.array(palette, dtype=np.float64)[template_colour[slot[keep]][last[pixels]]]
        self.canvas.reshape(-1, 3)[pixels] = colours

    def _paint(self, xs: np.ndarray, ys: np.ndarray, colour: Colour) -> None:
        keep = (xs >= 0) & (xs < self.width) & (ys >= 0) & (ys < self.height)
        self.canvas[ys[keep], xs[keep]] = colour


@cache
def _shape_offsets(shape: str, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel offsets of a filled marker, one span per scanline (as `_disc`, `_square`, `_diamond`)."""
    r = round(radius)
    xs: list[int] = []
    ys: list[int] = []
    for dy in range(-r, r + 1):
        if shape == "disc":
            half = math.floor(math.sqrt(max(0.0, radius * radius - dy * dy)))
        elif shape == "diamond":
            half = r - abs(dy)
        else:  # square
            half = r
        xs += range(-half, half + 1)
        ys += [dy] * (2 * half + 1)
    return np.array(xs, dtype=np.int64), np.array(ys, dtype=np.int64)


def _draw_frame(pen: _Pen, scene: Scene) -> None:
    lay = scene.layout
    left, top = float(lay.left), float(lay.top)
    right, bottom = lay.left + lay.plot_width, lay.top + lay.plot_height
    grid = _rgb("grid")
    for tick in scene.x_ticks:
        pen.line((tick.pixel, top), (tick.pixel, bottom), grid, SCALE)
    for tick in scene.y_ticks:
        pen.line((left, tick.pixel), (right, tick.pixel), grid, SCALE)
    axis = _rgb("main-axis")
    if scene.zero_x is not None:
        pen.line((scene.zero_x, top), (scene.zero_x, bottom), axis, 2 * SCALE)
    if scene.zero_y is not None:
        pen.line((left, scene.zero_y), (right, scene.zero_y), axis, 2 * SCALE)
    x0, y0, x1, y1 = int(left), int(top), int(right), int(bottom)
    corners = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], dtype=np.float64)
    pen.lines(corners, np.roll(corners, -1, axis=0), _rgb("muted"))
    if scene.edges:
        points = np.array([(m.x, m.y) for m in scene.samples], dtype=np.float64)
        edges = np.array(scene.edges, dtype=np.int64)
        pen.lines(points[edges[:, 0]], points[edges[:, 1]], _rgb("edge"), 1.5 * SCALE)


def _draw_problems(pen: _Pen, scene: Scene) -> None:
    """Outlines over the edges: crossing edges, acute triangles, clusters, rings."""
    for problem in scene.problems:
        colour = _c(problem_colour(problem.rule))
        if problem.kind == "edge":
            pen.line(problem.points[0], problem.points[1], colour, 4 * SCALE)
            _cross(pen, problem, colour)
        elif problem.kind == "polygon":
            corners = np.array(problem.points, dtype=np.float64)
            pen.lines(corners, np.roll(corners, -1, axis=0), colour, 1.5 * SCALE)
        elif problem.kind == "circle":
            pen.circle(problem.points[0], problem.radius, colour, 1.5 * SCALE)
        elif problem.kind == "rings":
            ring = colour if problem.rule in COLOURS else _severity_colour(problem.severity)
            for centre in problem.points:
                pen.circle(centre, problem.radius, ring, 2 * SCALE)
        elif problem.kind == "point":
            pen.circle(problem.points[0], 7 * SCALE, _severity_colour(problem.severity), 2 * SCALE)


def _severity_colour(severity: str) -> Colour:
    return {"error": _c((214, 39, 40)), "warning": _c((201, 138, 0))}.get(severity, _c((58, 120, 194)))


def _cross(pen: _Pen, problem: Problem, colour: Colour) -> None:
    if problem.cross is None:
        return
    x, y = problem.cross
    d = 6 * SCALE
    pen.line((x - d, y - d), (x + d, y + d), colour, 2 * SCALE)
    pen.line((x - d, y + d), (x + d, y - d), colour, 2 * SCALE)


def _draw_markers(pen: _Pen, scene: Scene) -> None:
    """Placeholders, then samples (each with a white outline), so every marker's centre keeps its colour."""
    white = _rgb("background")
    diamond_outline = ("diamond", (PLACEHOLDER_RADIUS + 1.5) * SCALE, white)
    pen.markers(
        np.array([(p.x, p.y) for p in scene.placeholders]),
        np.array([p.priority == "suggested" for p in scene.placeholders], dtype=np.int64),
        [
            [diamond_outline, ("diamond", PLACEHOLDER_RADIUS * SCALE, _rgb(kind))]
            for kind in ("necessary", "suggested")
        ],
    )
    outline = (SAMPLE_RADIUS + 1.5) * SCALE
    pen.markers(
        np.array([(m.x, m.y) for m in scene.samples]),
        np.array([m.generated for m in scene.samples], dtype=np.int64),
        [
            [("disc", outline, white), ("disc", SAMPLE_RADIUS * SCALE, _rgb("sample"))],
            [("square", outline, white), ("square", SAMPLE_RADIUS * SCALE, _rgb("generated"))],
        ],
    )


def _draw_labels(buf: oiio.ImageBuf, scene: Scene) -> None:
    """Clip names beside their markers (drawn only while there are few enough to read)."""
    for m in scene.samples:
        _text(buf, m.x + (SAMPLE_RADIUS + 4) * SCALE, m.y - SAMPLE_RADIUS * SCALE, m.name, 12, _rgb("text"))


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
    left, bottom = float(lay.left), lay.top + lay.plot_height
    for tick in scene.x_ticks:
        _text(buf, tick.pixel, bottom + 20 * SCALE, tick.label, 13, _rgb("muted"), align="center")
    for tick in scene.y_ticks:
        _text(buf, left - 8 * SCALE, tick.pixel + 5 * SCALE, tick.label, 13, _rgb("muted"), align="right")
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
