"""`N.png`: the blend-space diagram for CI pages, chat and thumbnails, drawn with OpenImageIO.

The only module of the package that imports OpenImageIO. It draws the same `diagram.Scene` as
the HTML report, all in a numpy canvas: translucent areas (uncovered hatch, acute triangles,
too-close clusters) as pixel-row spans of every shape at once, then grid, edges, outlines and
markers (`_Pen`: thousands of segments and markers per vectorised call), so the cost is pixels
plus shapes, not a Python loop per sample. OIIO renders each piece of text on a small patch (its
coverage is blended in); the file is written here (`png_file`). Everything is drawn at twice the size and reduced
with a box filter, which anti-aliases the one-pixel lines and text without changing the colour
at a marker's centre.
"""

from __future__ import annotations

import math
import struct
import warnings
import zlib
from collections.abc import Sequence
from functools import cache, lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio
from OpenImageIO import ImageBufAlgo as algo

from blendspace_pipeline import native
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
Canvas = np.ndarray[Any, np.dtype[np.float32]]  # (height, width, 3) RGB


def write_png(doc: BlendSpaceDocument, path: Path) -> None:
    """Render the diagram and write it atomically (temporary file in the same folder, then rename)."""
    data = png_file(_pixel_bytes(_draw(doc)))
    with atomic_path(Path(path), suffix=".tmp.png") as temporary:
        temporary.write_bytes(data)


# The colour chunks of sRGB pixels: sRGB (perceptual rendering intent, as for any image meant for
# screens), and the gamma and chromaticities older decoders use instead (the PNG specification's
# values that match sRGB).
_SRGB_CHUNKS = (
    (b"sRGB", bytes([0])),
    (b"gAMA", struct.pack(">I", 45455)),
    (b"cHRM", struct.pack(">8I", 31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000)),
)
PNG_COMPRESSION = 3  # zlib level


def png_file(pixels: np.ndarray) -> bytes:
    """The PNG file of 8-bit RGB ``pixels`` (height, width, 3): every row unfiltered (filter type
    0), the rows deflated at zlib level 3.

    A diagram is flat colour: unfiltered rows at level 3 deflate to ~30 % less than libpng's
    adaptive filters at level 6. Written here, with the zlib libpng itself uses, a 1,000-clip
    diagram takes 20 ms against 50 ms through OpenImageIO's PNG writer (same size, 308 kB; its
    extra time went to copying into an image buffer and libpng's per-row calls). OIIO reads the
    file back to the same pixels (tested)."""
    height, width, channels = pixels.shape
    if channels != 3 or pixels.dtype != np.uint8 or not height or not width:
        raise ValueError(
            f"expected 8-bit RGB pixels, got {height}x{width} with {channels} channels of {pixels.dtype}"
        )
    rows = np.empty((height, 1 + 3 * width), dtype=np.uint8)
    rows[:, 0] = 0  # filter type: none
    rows[:, 1:] = pixels.reshape(height, 3 * width)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # 8 bits, RGB, no interlace
    chunks = [
        (b"IHDR", header),
        *_SRGB_CHUNKS,
        (b"IDAT", zlib.compress(rows.data, PNG_COMPRESSION)),
        (b"IEND", b""),
    ]
    return b"\x89PNG\r\n\x1a\n" + b"".join(_chunk(kind, data) for kind, data in chunks)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)))


def render(doc: BlendSpaceDocument) -> oiio.ImageBuf:
    """The diagram as an RGB float image of `PNG_LAYOUT`'s size."""
    small = oiio.ImageBuf(oiio.ImageSpec(PNG_LAYOUT.width, PNG_LAYOUT.height, 3, "float"))
    small.set_pixels(oiio.ROI(0, PNG_LAYOUT.width, 0, PNG_LAYOUT.height, 0, 1, 0, 3), _pixels(doc))
    return small


def _pixels(doc: BlendSpaceDocument) -> Canvas:
    """The diagram's (height, width, 3) float32 pixels at `PNG_LAYOUT`'s size."""
    return _box_mean(_draw(doc))


def _pixel_bytes(canvas: Canvas) -> np.ndarray:
    """The PNG's 8-bit samples of the supersampled ``canvas``: its box mean times 255, rounded half
    to even and clipped, as OIIO converts a float image when it writes one (the same bytes;
    tested), without a float image in between.

    In place: the canvas is the only large array a PNG takes (each fresh page faults, and in a
    forked writer on a VM a fresh huge page cost 0.3-7 ms). The compiled kernel makes the bytes in
    the box filter's own pass, over the canvas's first sixteenth; numpy takes four more passes."""
    height, width = canvas.shape[:2]
    kernels = native.kernels
    if kernels is not None and canvas.flags.c_contiguous and canvas.flags.writeable:
        shape = (height // SCALE, width // SCALE, 3)
        out = canvas.reshape(-1).view(np.uint8)[: shape[0] * shape[1] * 3].reshape(shape)
        if kernels.box_mean_bytes(canvas, height, width, out, SCALE):
            return out
    mean = _box_mean(canvas)
    mean *= np.float32(255.0)
    np.rint(mean, out=mean)
    np.clip(mean, 0, 255, out=mean)
    return mean.astype(np.uint8)


def _draw(doc: BlendSpaceDocument) -> Canvas:
    """The diagram drawn at `SCALE` times `PNG_LAYOUT`'s size, before the box filter."""
    big = _scaled(PNG_LAYOUT)
    scene = build_scene(doc, big)
    canvas = _paint_areas(scene)
    pen = _Pen(canvas)
    _draw_frame(pen, scene)
    _draw_problems(pen, scene)
    _draw_swatches(pen, scene)
    if len(scene.samples) <= LABEL_LIMIT:
        # Names go under the markers: a neighbour's label must not cover a marker's centre.
        _draw_labels(canvas, scene)
    _draw_markers(pen, scene)
    _draw_titles(canvas, scene, doc)
    _draw_legend(canvas, _legend_origin(scene))
    return canvas


def _box_mean(canvas: Canvas) -> Canvas:
    """The box filter: the mean of every SCALE x SCALE block (the compiled kernel, or numpy).

    The kernel writes the mean over the canvas's first quarter (a block is read before any write
    reaches it), so it takes no new memory; the canvas is not used after it."""
    height, width = canvas.shape[:2]
    kernels = native.kernels
    if kernels is not None and canvas.flags.c_contiguous and canvas.flags.writeable:
        size = (height // SCALE) * (width // SCALE) * 3
        mean = canvas.reshape(-1)[:size].reshape(height // SCALE, width // SCALE, 3)
        if kernels.box_mean(canvas, height, width, mean, SCALE):
            return mean
    # Summed in place in the order `sum()` adds them (the same float32 result, without a new
    # full-size array per term).
    mean = 0 + canvas[0::SCALE, 0::SCALE]
    for dy, dx in [(dy, dx) for dy in range(SCALE) for dx in range(SCALE)][1:]:
        mean += canvas[dy::SCALE, dx::SCALE]
    mean /= SCALE**2
    return mean


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
#
# Every area is rasterised as pixel-row spans (one span per row for a convex polygon or a disc),
# all shapes of one colour at once: a difference array along each row, summed, counts how many
# shapes cover each pixel, and k translucent layers of one colour blend as one layer of alpha
# 1 - (1 - alpha)^k. The cost is spans + pixels, whatever the number or the size of the shapes.
# The compiled kernel (`native`) does the same per row; numpy is the fallback, the same bits.

AREA_ALPHA = {"polygon": 0.35, "circle": 0.15}
HATCH_ALPHA = 0.45
HATCH_STRIPES = (8 * SCALE, 3 * SCALE)  # (row + column) % 16 < 6: diagonal stripes


@cache
def _levels(alpha: float) -> np.ndarray:
    """float32 1 - (1 - alpha)^k for k = 0, 1, ... up to the first k where it rounds to 1: k
    overlapping layers blend as one of alpha ``_levels(alpha)[min(k, len - 1)]``. Each value is
    computed on its own in Python floats, so it does not depend on the table's length."""
    values = [0.0]
    for k in range(1, 4096):
        values.append(float(np.float32(1.0 - (1.0 - alpha) ** k)))
        if values[-1] == 1.0:
            break
    return np.array(values, dtype=np.float32)


def _paint_areas(scene: Scene) -> Canvas:
    lay = scene.layout
    canvas = np.empty((lay.height, lay.width, 3), dtype=np.float32)
    left, top = lay.left, lay.top
    right, bottom = int(lay.left + lay.plot_width), int(lay.top + lay.plot_height)
    # The background around the plot, then the plot: each pixel is filled once, by whole rows
    # (a colour broadcast over (rows, columns, 3) copies 3 floats at a time, ~5x slower).
    background = np.empty((lay.width, 3), dtype=np.float32)
    background[:] = _rgb("background")
    through_plot = background.copy()
    through_plot[left:right] = _rgb("plot")
    canvas[:top] = background
    canvas[bottom:] = background
    canvas[top:bottom] = through_plot
    # Shapes grouped by (kind, colour) in the order the findings list them.
    groups: dict[tuple[str, Colour], list[Problem]] = {}
    for problem in scene.problems:
        if problem.kind == "region":
            groups.setdefault(("region", _rgb("uncovered-area")), []).append(problem)
        elif problem.kind in AREA_ALPHA:
            groups.setdefault((problem.kind, _c(problem_colour(problem.rule))), []).append(problem)
    height, width = canvas.shape[:2]
    for (kind, colour), problems in groups.items():
        if kind == "region":
            _hatch_outside(canvas, problems[0].points, (left, top, right, bottom))
            continue
        if kind == "polygon":
            spans = _polygon_spans([np.asarray(p.points, dtype=np.float64) for p in problems], height, width)
        else:
            centres = np.array([p.points[0] for p in problems], dtype=np.float64).reshape(-1, 2)
            spans = _disc_spans(centres, np.array([p.radius for p in problems]), height, width)
        _blend_spans(canvas, spans, colour, AREA_ALPHA[kind])
    return canvas


def _span_pixels(spans: Spans, width: int) -> np.ndarray:
    """Flat pixel index of every pixel of every span."""
    rows, c0, c1 = spans
    lengths = c1 - c0 + 1
    pixels: np.ndarray = np.repeat(rows * width + c0, lengths) + _ramp(lengths)
    return pixels


def _blend_spans(
    canvas: Canvas, spans: Spans, colour: Colour, alpha: float, stripes: tuple[int, int] | None = None
) -> None:
    """Blend the spans' shapes over the canvas (k overlapping shapes as one layer of alpha
    1 - (1 - alpha)^k, `_levels`); ``stripes`` (period, on): only the pixels where
    (row + column) % period < on. The compiled kernel; else, in numpy, few pixels (small shapes
    over a big plot): their flat indices, counted by sorting; many: the coverage counts of
    `_coverage` over the spans' bounding box."""
    rows, c0, c1 = spans
    if not len(rows):
        return
    height, width = canvas.shape[:2]
    period, on = stripes or (0, 0)
    kernels = native.kernels
    if kernels is not None and canvas.flags.c_contiguous:
        arrays = [np.ascontiguousarray(a, dtype=np.int64) for a in spans]
        if kernels.blend_spans(canvas, height, width, *arrays, _levels(alpha), colour, period, on):
            return
    area = (int(rows.max()) - int(rows.min()) + 1) * (int(c1.max()) - int(c0.min()) + 1)
    if int((c1 - c0 + 1).sum()) * 4 > area:
        count, top, left = _coverage(spans)
        if period:
            ys, xs = np.ogrid[top : top + count.shape[0], left : left + count.shape[1]]
            count[(ys + xs) % period >= on] = 0
        _blend(canvas, (count, top, left), colour, alpha)
        return
    pixel = _span_pixels(spans, width)
    if period:
        pixel = pixel[(pixel // width + pixel % width) % period < on]
    if len(pixel):
        pixel, count = np.unique(pixel, return_counts=True)
        _mix(canvas, pixel, count, colour, alpha)


def _mix(canvas: Canvas, pixel: np.ndarray, count: np.ndarray, colour: Colour, alpha: float) -> None:
    """``count[i]`` layers of ``colour`` at ``alpha`` over flat pixel ``pixel[i]``."""
    levels = _levels(alpha)
    mix = levels[np.minimum(count, len(levels) - 1)][:, None]
    pixels = canvas.reshape(-1, 3)
    values = pixels[pixel]
    pixels[pixel] = values + mix * (np.asarray(colour, dtype=np.float32) - values)


Spans = tuple[np.ndarray, np.ndarray, np.ndarray]  # row, first column, last column (inclusive)


def _polygon_spans(polygons: Sequence[FloatArray], height: int, width: int) -> Spans:
    """Pixel-row spans of convex polygons (pixels whose centre is inside), all at once.

    Convex, so each row crosses a polygon in one span: intersect the row with every edge of its
    polygon and keep the extremes. Rows x edges work instead of pixels x edges.
    """
    polygons = [p for p in polygons if len(p) >= 3]
    if not polygons:
        return _no_spans()
    counts = np.array([len(p) for p in polygons], dtype=np.int64)
    a = np.concatenate(polygons)
    first = np.cumsum(counts) - counts
    following = np.arange(len(a)) + 1
    following[first + counts - 1] = first  # each polygon's last edge closes it
    b = a[following]
    row0 = np.maximum(np.ceil(np.minimum.reduceat(a[:, 1], first) - 0.5), 0).astype(np.int64)
    row1 = np.minimum(np.floor(np.maximum.reduceat(a[:, 1], first) - 0.5), height - 1).astype(np.int64)
    rows_of = np.maximum(row1 - row0 + 1, 0)
    polygon = np.repeat(np.arange(len(counts)), rows_of)
    if not len(polygon):
        return _no_spans()
    rows = row0[polygon] + _ramp(rows_of)
    # Every (row, edge of its polygon) pair; a row's pairs are contiguous for `reduceat`.
    pair_row = np.repeat(np.arange(len(rows)), counts[polygon])
    edge = first[polygon][pair_row] + _ramp(counts[polygon])
    y = rows[pair_row] + 0.5
    ay, by = a[edge, 1], b[edge, 1]
    flat = ay == by  # a horizontal edge adds nothing its neighbours' end points do not
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(flat, -1.0, (y - ay) / np.where(flat, 1.0, by - ay))
    crossing = (t >= 0.0) & (t <= 1.0)
    x = a[edge, 0] + t * (b[edge, 0] - a[edge, 0])
    starts = np.cumsum(counts[polygon]) - counts[polygon]
    low = np.minimum.reduceat(np.where(crossing, x, np.inf), starts)
    high = np.maximum.reduceat(np.where(crossing, x, -np.inf), starts)
    return _clip_spans(rows, low, high, width)


def _disc_spans(centres: FloatArray, radii: FloatArray, height: int, width: int) -> Spans:
    """Pixel-row spans of discs (pixels whose centre is within the radius), all at once."""
    if not len(centres):
        return _no_spans()
    row0 = np.maximum(np.ceil(centres[:, 1] - radii - 0.5), 0).astype(np.int64)
    row1 = np.minimum(np.floor(centres[:, 1] + radii - 0.5), height - 1).astype(np.int64)
    rows_of = np.maximum(row1 - row0 + 1, 0)
    disc = np.repeat(np.arange(len(centres)), rows_of)
    rows = row0[disc] + _ramp(rows_of)
    dy = rows + 0.5 - centres[disc, 1]
    half = np.sqrt(np.maximum(radii[disc] ** 2 - dy**2, 0.0))
    return _clip_spans(rows, centres[disc, 0] - half, centres[disc, 0] + half, width)


def _ramp(lengths: np.ndarray) -> np.ndarray:
    """0, 1, ..., n-1 for every n in ``lengths``, concatenated."""
    lengths = np.asarray(lengths, dtype=np.int64)
    total = int(lengths.sum())
    ramp: np.ndarray = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return ramp


def _no_spans() -> Spans:
    empty = np.zeros(0, dtype=np.int64)
    return empty, empty, empty


def _clip_spans(rows: np.ndarray, low: FloatArray, high: FloatArray, width: int) -> Spans:
    with np.errstate(invalid="ignore"):
        c0 = np.maximum(np.ceil(low - 0.5), 0)
        c1 = np.minimum(np.floor(high - 0.5), width - 1)
    keep = np.isfinite(c0) & np.isfinite(c1) & (c0 <= c1)
    return rows[keep], c0[keep].astype(np.int64), c1[keep].astype(np.int64)


def _coverage(spans: Spans) -> tuple[np.ndarray, int, int]:
    """How many spans cover each pixel of the spans' bounding box, and the box's top-left pixel
    (row, column): +1 at a span's start, -1 after its end, summed along each row."""
    rows, c0, c1 = spans
    if not len(rows):
        return np.zeros((0, 0), dtype=np.int64), 0, 0
    top, left = int(rows.min()), int(c0.min())
    height, width = int(rows.max()) - top + 1, int(c1.max()) - left + 1
    stride = width + 1
    size = height * stride
    at = (rows - top) * stride - left
    diff = np.bincount(at + c0, minlength=size) - np.bincount(at + c1 + 1, minlength=size)
    return np.cumsum(diff.reshape(height, stride)[:, :width], axis=1), top, left


def _blend(canvas: Canvas, coverage: tuple[np.ndarray, int, int], colour: Colour, alpha: float) -> None:
    """``count`` layers of ``colour`` at ``alpha`` over the canvas (count 0 leaves a pixel as is),
    in place over the coverage's box: shapes this dense are cheapest as whole-array arithmetic."""
    count, top, left = coverage
    if not count.size:
        return
    # Spans are clipped to the canvas, so the box lies inside it.
    region = canvas[top : top + count.shape[0], left : left + count.shape[1]]
    # 1 - (1 - alpha)^k for every count, looked up rather than raised per pixel.
    levels = _levels(alpha)
    change = np.asarray(colour, dtype=np.float32) - region
    change *= levels[np.minimum(count, len(levels) - 1)][..., None]
    region += change


def _hatch_outside(canvas: Canvas, hull: list[Point], box: tuple[int, int, int, int]) -> None:
    """Diagonal hatching over the plot outside the hull: the uncovered area.

    The plot rows minus the hull's span on each row are spans too: only the uncovered pixels
    are visited (a few percent of the plot when the samples cover most of it).
    """
    left, top, right, bottom = box
    height, width = canvas.shape[:2]
    rows = np.arange(top, bottom)
    start, end = np.full(rows.shape, right), np.full(rows.shape, left - 1)  # hull span: empty
    if len(hull) >= 3:
        hull_rows, c0, c1 = _polygon_spans([np.asarray(hull, dtype=np.float64)], height, width)
        on_plot = (hull_rows >= top) & (hull_rows < bottom)
        start[hull_rows[on_plot] - top] = np.maximum(c0[on_plot], left)
        end[hull_rows[on_plot] - top] = np.minimum(c1[on_plot], right - 1)
    crossed = start <= end
    before = (rows, np.full(rows.shape, left), np.where(crossed, start - 1, right - 1))
    after = (rows[crossed], end[crossed] + 1, np.full(int(crossed.sum()), right - 1))
    spans = tuple(np.concatenate([a, b]) for a, b in zip(before, after, strict=True))
    keep = spans[1] <= spans[2]
    outside = (spans[0][keep], spans[1][keep], spans[2][keep])
    _blend_spans(canvas, outside, _rgb("uncovered-area"), HATCH_ALPHA, HATCH_STRIPES)


_PIXEL = np.dtype((np.void, 12))  # one RGB float32 pixel


class _Pen:
    """Lines and filled markers rasterised straight into the numpy canvas, many at a time.

    A line ``width`` pixels wide is parallel one-pixel lines half a pixel apart along its normal
    (whole-pixel offsets along a diagonal normal round onto the same rows and leave gaps), each
    from its rounded end point to the other, one pixel per step along its longer extent. Filled
    markers (disc, square, diamond) are one span per scanline. Colours are opaque: a later shape
    covers an earlier one.
    """

    def __init__(self, canvas: Canvas):
        self.canvas = canvas
        self.height, self.width = canvas.shape[:2]
        # The canvas as one 12-byte item per pixel: writing whole pixels by flat index is one
        # scatter of items instead of three floats each (the same bytes land in the same place).
        self.pixels = canvas.reshape(-1, 3).view(_PIXEL).reshape(-1) if canvas.flags.c_contiguous else None

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
        kernels = native.kernels
        if (
            kernels is not None
            and self.pixels is not None
            and kernels.draw_lines(self.canvas, self.height, self.width, a, b, colour)
        ):
            return
        steps = np.abs(b - a).max(axis=1) + 1  # pixels per one-pixel line
        line = np.repeat(np.arange(len(a)), steps)
        along = _ramp(steps) / np.maximum(steps[line] - 1, 1)
        xs = np.round(a[line, 0] + along * (b[line, 0] - a[line, 0])).astype(np.int64)
        ys = np.round(a[line, 1] + along * (b[line, 1] - a[line, 1])).astype(np.int64)
        self._paint(xs, ys, colour)

    def line(self, a: Point, b: Point, colour: Colour, width: float = 1.0) -> None:
        self.lines(np.array([a]), np.array([b]), colour, width)

    def circles(self, centres: FloatArray, radii: FloatArray, colour: Colour, width: float) -> None:
        """Circle outlines, max(24, radius) segments each, all in one `lines` call."""
        starts, ends = _circle_segments(centres, radii)
        self.lines(starts, ends, colour, width)

    def circle(self, centre: Point, radius: float, colour: Colour, width: float) -> None:
        self.circles(np.array([centre]), np.array([radius]), colour, width)

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
        kinds = np.asarray(kinds, dtype=np.int64)
        # Each kind's layers as one template: the palette index per offset from the centre, a
        # later layer over an earlier one (-1: not covered).
        reach = max(round(radius) for layers in layers_for for _, radius, _ in layers)
        side = 2 * reach + 1
        template = np.full((len(layers_for), side, side), -1, dtype=np.int64)
        palette: list[Colour] = []
        for kind, layers in enumerate(layers_for):
            for shape, radius, colour in layers:
                dx, dy = _shape_offsets(shape, radius)
                template[kind, dy + reach, dx + reach] = len(palette)
                palette.append(colour)
        kernels = native.kernels
        if kernels is not None and self.pixels is not None:
            stamped = kernels.stamp_markers(
                self.canvas,
                self.height,
                self.width,
                np.ascontiguousarray(centres),
                np.ascontiguousarray(kinds),
                template,
                side,
                np.array(palette, dtype=np.float32),
            )
            if stamped:
                return
        # Z-buffer: the highest marker index whose template covers a pixel is the one on top.
        # One vectorised pass per template offset (a few hundred), each over all markers.
        # The buffer spans the markers' bounding box grown by the template's reach (so no offset
        # falls outside it); what lies beyond the canvas is dropped when the colours are written.
        x0, y0 = int(centres[:, 0].min()) - reach, int(centres[:, 1].min()) - reach
        width = int(centres[:, 0].max()) + reach + 1 - x0
        height = int(centres[:, 1].max()) + reach + 1 - y0
        top = np.full(height * width, -1, dtype=np.int64)
        covered_by_kind = template >= 0
        # Per kind: its markers' buffer positions (at offset 0) and indices, gathered once.
        base = (centres[:, 1] - y0) * width + (centres[:, 0] - x0)
        members_of = [np.flatnonzero(kinds == kind) for kind in range(len(layers_for))]
        by_kind = [(kind, base[members], members) for kind, members in enumerate(members_of) if len(members)]
        for oy, ox in zip(*np.nonzero(covered_by_kind.any(axis=0)), strict=True):
            shift = (oy - reach) * width + (ox - reach)
            for kind, at, members in by_kind:
                if covered_by_kind[kind, oy, ox]:
                    np.maximum.at(top, at + shift, members)
        pixels = np.flatnonzero(top >= 0)
        marker = top[pixels]
        py, px = pixels // width + y0, pixels % width + x0
        colours = np.array(palette, dtype=np.float32)[
            template[kinds[marker], py - centres[marker, 1] + reach, px - centres[marker, 0] + reach]
        ]
        inside = (px >= 0) & (px < self.width) & (py >= 0) & (py < self.height)
        py, px, colours = py[inside], px[inside], colours[inside]
        if self.pixels is not None:
            self.pixels[py * self.width + px] = np.ascontiguousarray(colours).view(_PIXEL).reshape(-1)
        else:
            self.canvas[py, px] = colours

    def _paint(self, xs: np.ndarray, ys: np.ndarray, colour: Colour) -> None:
        keep = (xs >= 0) & (xs < self.width) & (ys >= 0) & (ys < self.height)
        if self.pixels is not None:
            self.pixels[ys[keep] * self.width + xs[keep]] = np.asarray(colour, dtype=np.float32).view(_PIXEL)[
                0
            ]
        else:
            self.canvas.reshape(-1, 3)[ys[keep] * self.width + xs[keep]] = colour


def _circle_segments(centres: FloatArray, radii: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Segment start and end points of circle outlines, max(24, int(radius)) segments each."""
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    segments = np.maximum(24, radii.astype(np.int64))
    circle = np.repeat(np.arange(len(centres)), segments)
    step = _ramp(segments)
    angle0 = 2.0 * np.pi * step / segments[circle]
    angle1 = 2.0 * np.pi * (step + 1) / segments[circle]
    r = radii[circle][:, None]
    starts = centres[circle] + r * np.stack([np.cos(angle0), np.sin(angle0)], axis=1)
    ends = centres[circle] + r * np.stack([np.cos(angle1), np.sin(angle1)], axis=1)
    return starts, ends


@cache
def _shape_offsets(shape: str, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel offsets of a filled marker, one span per scanline (disc, square or diamond)."""
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
    """Outlines over the edges: crossing edges, acute triangles, clusters, rings.

    Segments are gathered per (colour, width) in the findings' order and drawn in one call each:
    thousands of rings cost one vectorised pass, not one call per ring.
    """
    segments: dict[tuple[Colour, float], list[tuple[FloatArray, FloatArray]]] = {}
    circles: dict[tuple[Colour, float], list[tuple[Point, float]]] = {}

    def add(colour: Colour, width: float, starts: FloatArray, ends: FloatArray) -> None:
        segments.setdefault((colour, width), []).append((starts, ends))

    for problem in scene.problems:
        colour = _c(problem_colour(problem.rule))
        if problem.kind == "edge":
            add(colour, 4 * SCALE, np.array(problem.points[:1]), np.array(problem.points[1:2]))
            if problem.cross is not None:
                x, y, d = problem.cross[0], problem.cross[1], 6 * SCALE
                add(colour, 2 * SCALE, np.array([(x - d, y - d), (x - d, y + d)]),
                    np.array([(x + d, y + d), (x + d, y - d)]))  # fmt: skip
        elif problem.kind == "polygon":
            corners = np.array(problem.points, dtype=np.float64)
            add(colour, 1.5 * SCALE, corners, np.roll(corners, -1, axis=0))
        elif problem.kind == "circle":
            circles.setdefault((colour, 1.5 * SCALE), []).append((problem.points[0], problem.radius))
        elif problem.kind == "rings":
            ring = colour if problem.rule in COLOURS else _severity_colour(problem.severity)
            circles.setdefault((ring, 2 * SCALE), []).extend((c, problem.radius) for c in problem.points)
        elif problem.kind == "point":
            key = (_severity_colour(problem.severity), 2.0 * SCALE)
            circles.setdefault(key, []).append((problem.points[0], 7.0 * SCALE))
    for key, found in circles.items():
        starts, ends = _circle_segments(np.array([c for c, _ in found]), np.array([r for _, r in found]))
        add(*key, starts, ends)
    for (colour, width), parts in segments.items():
        pen.lines(np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]), colour, width)


def _severity_colour(severity: str) -> Colour:
    return {"error": _c((214, 39, 40)), "warning": _c((201, 138, 0))}.get(severity, _c((58, 120, 194)))


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


def _draw_labels(canvas: Canvas, scene: Scene) -> None:
    """Clip names beside their markers (drawn only while there are few enough to read)."""
    for m in scene.samples:
        _text(
            canvas, m.x + (SAMPLE_RADIUS + 4) * SCALE, m.y - SAMPLE_RADIUS * SCALE, m.name, 12, _rgb("text")
        )


# ---- text ---------------------------------------------------------------------------------------


def _font() -> str | None:
    """A font OIIO can render with: the wheel bundles DroidSans; None (no labels, and a warning
    once per process) when none works."""
    font = _found_font()
    if font is None:
        warnings.warn(
            "OpenImageIO found no font: the PNG is drawn without text (install fonts-dejavu-core)",
            stacklevel=2,
        )
    return font


@cache
def _found_font() -> str | None:
    """The probe behind `_font`, silent: `warm` runs it in the build server, whose commands must
    still warn their own callers (a warning shown once is not shown again in a forked process)."""
    probe = oiio.ImageBuf(oiio.ImageSpec(64, 32, 3, "float"))
    for name in ("DroidSans", "DejaVuSans", ""):
        if algo.render_text(probe, 2, 20, "Ag", 12, name, (1.0, 1.0, 1.0)):
            return name
        probe.geterror()  # clear the error so the next attempt reports its own
    return None


def _text(
    canvas: Canvas,
    x: float,
    y: float,
    text: str,
    size: int,
    colour: Colour,
    align: str = "left",
    bold: bool = False,
) -> None:
    """Text at (x, y) (baseline, OIIO's alignment): OIIO renders its coverage on a patch just
    big enough, which is blended into the canvas, so the full-size canvas never goes through
    OIIO."""
    font = _font()
    if font is None or not text:
        return
    name = f"{font}-Bold" if bold and font == "DroidSans" else font
    alpha, ox, oy = _text_coverage(text, size * SCALE, name, align)
    left, top = round(x) - ox, round(y) - oy
    height, width = canvas.shape[:2]
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + alpha.shape[0], height), min(left + alpha.shape[1], width)
    if y0 >= y1 or x0 >= x1:
        return
    cover = alpha[y0 - top : y1 - top, x0 - left : x1 - left, None]
    region = canvas[y0:y1, x0:x1]
    region += cover * (np.asarray(colour, dtype=np.float32) - region)


def warm() -> None:
    """Render now what every diagram draws the same (the font probe, the legend's text), for a
    process that forks the PNG's writers (the build server): each then starts with them, about
    20 ms of a served build's PNG. The legend is drawn on one pixel: its text is rendered (and
    remembered by `_text_coverage`) before it is placed. Without a font it does nothing (each
    command warns its own caller)."""
    if _found_font() is not None:
        _draw_legend(np.zeros((1, 1, 3), dtype=np.float32), (0.0, 0.0))


@lru_cache(maxsize=64)  # a patch is 30-300 KB; a 1,000-clip diagram draws 26 (2 MB)
def _text_coverage(text: str, size: int, font: str, align: str) -> tuple[np.ndarray, int, int]:
    """The text's coverage (0..1) on a patch, and the patch pixel of the text's origin: the patch
    is twice the text's width around the origin, so any alignment fits. Remembered (read-only):
    see `warm`."""
    extent = algo.text_size(text, size, font)
    width = extent.xend - extent.xbegin + 8
    ox, oy = width + 4, 4 - extent.ybegin
    patch = oiio.ImageBuf(oiio.ImageSpec(2 * width + 8, extent.yend - extent.ybegin + 8, 1, "float"))
    algo.render_text(patch, ox, oy, text, size, font, (1.0,), alignx=align)
    alpha = np.asarray(patch.get_pixels(oiio.FLOAT), dtype=np.float32).reshape(patch.spec().height, -1)
    alpha.flags.writeable = False
    return alpha, ox, oy


def _draw_titles(canvas: Canvas, scene: Scene, doc: BlendSpaceDocument) -> None:
    lay = scene.layout
    left, bottom = float(lay.left), lay.top + lay.plot_height
    for tick in scene.x_ticks:
        _text(canvas, tick.pixel, bottom + 20 * SCALE, tick.label, 13, _rgb("muted"), align="center")
    for tick in scene.y_ticks:
        _text(canvas, left - 8 * SCALE, tick.pixel + 5 * SCALE, tick.label, 13, _rgb("muted"), align="right")
    counts = {s: sum(d.severity == s for d in doc.diagnostics) for s in ("error", "warning", "info")}
    generated = sum(s.generated for s in doc.samples)
    _text(canvas, lay.left, 32 * SCALE, f"{doc.name} — blend space", 22, _rgb("text"), bold=True)
    summary = (
        f"{len(doc.samples) - generated} clips, {generated} generated · {counts['error']} errors, "
        f"{counts['warning']} warnings, {counts['info']} info · coverage {scene.coverage:.1f}% · "
        f"{len(doc.placeholders)} clips to add"
    )
    _text(canvas, lay.left, 56 * SCALE, summary, 13, _rgb("muted"))
    x_axis, y_axis = scene.axes
    centre_x = lay.left + lay.plot_width / 2
    _text(
        canvas,
        centre_x,
        lay.height - 18 * SCALE,
        f"{x_axis.feature} ({x_axis.unit})",
        14,
        _rgb("text"),
        "center",
    )
    _vertical_text(canvas, 14 * SCALE, lay.top + lay.plot_height / 2, f"{y_axis.feature} ({y_axis.unit})", 14)


def _vertical_text(canvas: Canvas, x: float, centre_y: float, text: str, size: int) -> None:
    """Text reading bottom to top, its left edge at ``x``, centred on ``centre_y``."""
    font = _font()
    if font is None:
        return
    alpha = np.rot90(_text_coverage(text, size * SCALE, font, "left")[0])  # counter-clockwise
    rows, cols = np.nonzero(alpha > 0)
    if not len(rows):
        return
    alpha = alpha[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
    top, left = round(centre_y - alpha.shape[0] / 2), round(x)
    region = canvas[top : top + alpha.shape[0], left : left + alpha.shape[1]]
    cover = alpha[: region.shape[0], : region.shape[1], None]
    region += cover * (np.asarray(_rgb("text"), dtype=np.float32) - region)


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


def _legend_origin(scene: Scene) -> tuple[float, float]:
    lay = scene.layout
    return lay.left + lay.plot_width + 28 * SCALE, float(lay.top + 10 * SCALE)


def _draw_legend(canvas: Canvas, origin: tuple[float, float]) -> None:
    """The legend's text from ``origin`` (`_legend_origin`; its swatches are drawn with the pen,
    `_draw_swatches`)."""
    x, y = origin
    _text(canvas, x, y, "Legend", 15, _rgb("text"), bold=True)
    for _, label in LEGEND:
        y += 30 * SCALE
        _text(canvas, x + 28 * SCALE, y, label, 13, _rgb("text"))


def _draw_swatches(pen: _Pen, scene: Scene) -> None:
    x, y = _legend_origin(scene)
    for key, _ in LEGEND:
        y += 30 * SCALE
        _swatch(pen, key, (x + 10 * SCALE, y - 5 * SCALE))


def _swatch(pen: _Pen, key: str, centre: Point) -> None:
    colour = _rgb(key)
    r = 7 * SCALE
    shapes = {"sample": ("disc", SAMPLE_RADIUS), "generated": ("square", SAMPLE_RADIUS)}
    shapes |= {"necessary": ("diamond", PLACEHOLDER_RADIUS), "suggested": ("diamond", PLACEHOLDER_RADIUS)}
    if key in shapes:
        shape, radius = shapes[key]
        pen.markers(np.array([centre]), np.zeros(1, dtype=np.int64), [[(shape, radius * SCALE, colour)]])
    elif key == "crossing-axis":
        pen.line((centre[0] - r, centre[1]), (centre[0] + r, centre[1]), colour, 4 * SCALE)
    elif key in ("misalignment", "too-close"):
        pen.circle(centre, r, colour, 2 * SCALE)
    else:
        x0, y0, x1, y1 = (
            round(centre[0] - r),
            round(centre[1] - r),
            round(centre[0] + r),
            round(centre[1] + r),
        )
        if key == "acute-triangle":
            pen.canvas[y0 : y1 + 1, x0 : x1 + 1] = tuple(0.35 * c + 0.65 for c in colour)
        else:  # the uncovered-area hatching
            for a, b in (((x0, y1), (x1, y0)), ((x0, y0 + r), (x0 + r, y0)), ((x0 + r, y1), (x1, y0 + r))):
                pen.line(a, b, colour, SCALE)
        corners = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], dtype=np.float64)
        pen.lines(corners, np.roll(corners, -1, axis=0), colour)
