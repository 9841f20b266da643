"""The PNG's compiled rasteriser (`_kernels.c`: draw_lines, stamp_markers, blend_spans, box_mean,
box_mean_bytes) against the numpy code it replaces (`report/png.py`), to the bit: each primitive
on random and hostile shapes (off the canvas, zero length, hundreds stacked on one pixel), whole
diagrams, and what the kernels decline."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_report import sample_document

from blendspace_pipeline import native
from blendspace_pipeline.report import png
from blendspace_pipeline.space.document import BlendSpaceDocument

kernels = native.kernels
pytestmark = pytest.mark.skipif(kernels is None, reason="the compiled kernels were not built")

HEIGHT, WIDTH = 90, 120


def _both_ways(
    monkeypatch: pytest.MonkeyPatch, draw: Callable[[], np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """What ``draw`` returns with the kernels, then with numpy alone."""
    with_kernels = draw()
    monkeypatch.setattr(native, "kernels", None)
    with_numpy = draw()
    monkeypatch.setattr(native, "kernels", kernels)
    return with_kernels, with_numpy


def _canvas(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, 1.0, size=(HEIGHT, WIDTH, 3)).astype(np.float32)


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes(), f"{int((a != b).any(axis=-1).sum())} pixels differ"


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("width", [1.0, 3.0, 4.5])
def test_lines_are_numpys(monkeypatch: pytest.MonkeyPatch, seed: int, width: float) -> None:
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-60, 180, size=(200, 2))
    ends = rng.uniform(-60, 180, size=(200, 2))
    ends[:10] = starts[:10]  # zero length: one pixel
    ends[10:20, 0] = starts[10:20, 0]  # vertical
    ends[20:30] = starts[20:30] + 0.5  # on the rounding boundary

    def draw() -> np.ndarray:
        pen = png._Pen(_canvas(seed))
        pen.lines(starts, ends, (0.2, 0.4, 0.6), width)
        pen.circles(starts[:5], np.array([3.0, 30.0, 0.0, 55.5, 12.25]), (1.0, 0.0, 0.5), width)
        return pen.canvas

    _same(*_both_ways(monkeypatch, draw))


@pytest.mark.parametrize("seed", range(4))
def test_markers_are_numpys(monkeypatch: pytest.MonkeyPatch, seed: int) -> None:
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-15, 135, size=(400, 2))
    centres[50:60] = centres[3]  # stacked: the last one shows
    kinds = rng.integers(0, 3, size=400)
    layers = [
        [("disc", 5.5, (1.0, 1.0, 1.0)), ("disc", 3.0, (0.0, 0.0, 1.0))],
        [("square", 4.0, (1.0, 1.0, 0.0)), ("diamond", 3.0, (1.0, 0.0, 0.0))],
        [("diamond", 7.5, (0.1, 0.2, 0.3))],
    ]

    def draw() -> np.ndarray:
        pen = png._Pen(_canvas(seed))
        pen.markers(centres, kinds, layers)
        return pen.canvas

    _same(*_both_ways(monkeypatch, draw))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("stripes", [None, (16, 6), (7, 3)])
def test_translucent_spans_are_numpys(
    monkeypatch: pytest.MonkeyPatch, seed: int, stripes: tuple[int, int] | None
) -> None:
    rng = np.random.default_rng(seed)
    polygons = [rng.uniform(-30, 150, size=(3, 2)) for _ in range(60)]
    # 300 discs on one spot: more layers than the level table holds (it saturates at 1).
    centres = np.concatenate([rng.uniform(-10, 130, size=(40, 2)), np.full((300, 2), 50.0)])
    radii = np.concatenate([rng.uniform(0.5, 25, size=40), np.full(300, 6.0)])
    small = (np.array([5, 5, 6]), np.array([3, 4, 100]), np.array([3, 9, 100]))  # sparse: few pixels

    def draw() -> np.ndarray:
        canvas = _canvas(seed)
        png._blend_spans(canvas, png._polygon_spans(polygons, HEIGHT, WIDTH), (0.9, 0.1, 0.1), 0.35, stripes)
        png._blend_spans(
            canvas, png._disc_spans(centres, radii, HEIGHT, WIDTH), (0.1, 0.1, 0.9), 0.15, stripes
        )
        png._blend_spans(canvas, small, (0.0, 1.0, 0.0), 0.45, stripes)
        return canvas

    with_kernels, with_numpy = _both_ways(monkeypatch, draw)
    _same(with_kernels, with_numpy)
    assert not np.array_equal(with_kernels, _canvas(seed))


def test_the_level_table_ends_where_float32_reaches_one() -> None:
    for alpha in (0.15, 0.35, 0.45, 1.0):
        levels = png._levels(alpha)
        assert levels[0] == 0.0 and levels[-1] == 1.0 and (levels[:-1] < 1.0).all()
        assert np.all(np.diff(levels) >= 0)


def test_the_box_filter_is_numpys(monkeypatch: pytest.MonkeyPatch) -> None:
    canvas = np.random.default_rng(9).uniform(0.0, 1.0, size=(2 * HEIGHT, 2 * WIDTH, 3)).astype(np.float32)
    _same(*_both_ways(monkeypatch, lambda: png._box_mean(canvas.copy())))
    # The kernel writes over the canvas's first quarter: the same values as into a new array,
    # and no new image-sized array.
    inside = canvas.copy()
    into = np.empty((HEIGHT, WIDTH, 3), np.float32)
    assert kernels.box_mean(canvas, 2 * HEIGHT, 2 * WIDTH, into, 2)
    mean = png._box_mean(inside)
    _same(mean, into)
    assert np.shares_memory(mean, inside)
    # A canvas it may not write (read-only, or not contiguous) is filtered into a new array.
    frozen = canvas.copy()
    frozen.flags.writeable = False
    _same(png._box_mean(frozen), into)
    assert not np.shares_memory(png._box_mean(frozen), frozen)
    strided = np.asfortranarray(canvas)
    _same(png._box_mean(strided), into)
    assert strided.tobytes(order="A") == np.asfortranarray(canvas).tobytes(order="A")


def _numpy_bytes(canvas: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> np.ndarray:
    monkeypatch.setattr(native, "kernels", None)
    try:
        return png._pixel_bytes(canvas.copy())
    finally:
        monkeypatch.setattr(native, "kernels", kernels)


@pytest.mark.parametrize("scale", [2, 3])
def test_the_png_bytes_are_numpys(monkeypatch: pytest.MonkeyPatch, scale: int) -> None:
    """The 8-bit samples the kernel makes in the box filter's pass are numpy's mean * 255, rint,
    clip and cast: on random colours, on means whose * 255 lands exactly on a half (both ways of
    rounding it), below 0, above 1 and on the edges of float32's precision."""
    monkeypatch.setattr(png, "SCALE", scale)
    rng = np.random.default_rng(scale)
    ties = np.array([(k + 0.5) / 255.0 for k in range(255)], dtype=np.float32)
    hostile = np.concatenate(
        [ties, np.nextafter(ties, np.float32(0)), np.nextafter(ties, np.float32(2)),
         np.array([0, -0.0, 1, -1, 2, 1e-30, 1 - 2**-24, 255.5 / 255, 1e30, -1e30], np.float32)]
    )  # fmt: skip
    values = rng.uniform(-0.1, 1.1, size=HEIGHT * WIDTH * 3).astype(np.float32)
    values[: hostile.size] = hostile
    # Every block uniform: at scale 2 its mean is exactly its value (four equal floats / 4).
    blocks = np.broadcast_to(values.reshape(HEIGHT, 1, WIDTH, 1, 3), (HEIGHT, scale, WIDTH, scale, 3))
    canvas = np.ascontiguousarray(blocks).reshape(scale * HEIGHT, scale * WIDTH, 3)
    if scale == 2:
        assert np.array_equal(png._box_mean(canvas.copy()).reshape(-1)[: hostile.size], hostile)
    expected = _numpy_bytes(canvas, monkeypatch)
    made = canvas.copy()
    got = png._pixel_bytes(made)
    _same(got, expected)
    assert np.shares_memory(got, made)  # over the canvas, no new image-sized array
    # Random, not uniform, blocks too (the sum's order).
    canvas = rng.uniform(-0.1, 1.1, size=(scale * HEIGHT, scale * WIDTH, 3)).astype(np.float32)
    _same(png._pixel_bytes(canvas.copy()), _numpy_bytes(canvas, monkeypatch))
    # A canvas the kernel may not write is converted by numpy, and left as it was.
    frozen = canvas.copy()
    frozen.flags.writeable = False
    _same(png._pixel_bytes(frozen), _numpy_bytes(canvas, monkeypatch))


def test_the_png_bytes_kernel_declines_a_wrong_size() -> None:
    assert kernels is not None
    canvas = _canvas(1)
    before = canvas.copy()
    assert not kernels.box_mean_bytes(canvas, HEIGHT, WIDTH, np.empty(HEIGHT * WIDTH, np.uint8), 2)
    assert not kernels.box_mean_bytes(canvas, HEIGHT, WIDTH, np.empty(12 * 17 * 3, np.uint8), 7)
    assert np.array_equal(canvas, before)
    assert kernels.box_mean_bytes(canvas, HEIGHT, WIDTH, np.empty(45 * 60 * 3, np.uint8), 2)


def _crowded_document() -> BlendSpaceDocument:
    """The sample document with every finding repeated 150 times (stacked translucent areas)."""
    doc = sample_document()
    doc.diagnostics = [d.model_copy() for d in doc.diagnostics for _ in range(150)]
    return doc


def _empty_document() -> BlendSpaceDocument:
    doc = sample_document()
    doc.samples, doc.triangles, doc.diagnostics, doc.placeholders = [], [], [], []
    return doc


@pytest.mark.parametrize("make", [sample_document, _crowded_document, _empty_document])
def test_whole_diagrams_are_numpys(
    monkeypatch: pytest.MonkeyPatch, make: Callable[[], BlendSpaceDocument]
) -> None:
    doc = make()
    _same(*_both_ways(monkeypatch, lambda: png._pixels(doc)))


def test_kernels_decline_what_numpy_would_read_otherwise() -> None:
    assert kernels is not None
    canvas = _canvas(0)
    before = canvas.copy()
    one = np.array([1], dtype=np.int64)
    levels = png._levels(0.35)
    colour = (1.0, 0.0, 0.0)
    # Spans outside the canvas or back to front.
    for rows, first, last in [(HEIGHT, 0, 1), (-1, 0, 1), (1, -1, 3), (1, 5, WIDTH), (1, 5, 4)]:
        spans = [one * rows, one * first, one * last]
        assert not kernels.blend_spans(canvas, HEIGHT, WIDTH, *spans, levels, colour, 0, 0)
    assert not kernels.blend_spans(canvas, HEIGHT, WIDTH, one, one, one, levels[:0], colour, 0, 0)
    assert not kernels.blend_spans(canvas, HEIGHT + 1, WIDTH, one, one, one, levels, colour, 0, 0)
    # A template naming a colour the palette lacks, a kind without a template, an even side.
    template = np.full((1, 3, 3), 1, dtype=np.int64)
    palette = np.zeros((1, 3), dtype=np.float32)
    centre = np.array([[5, 5]], dtype=np.int64)
    assert not kernels.stamp_markers(canvas, HEIGHT, WIDTH, centre, one * 0, template, 3, palette)
    assert not kernels.stamp_markers(canvas, HEIGHT, WIDTH, centre, one, template * 0, 3, palette)
    assert not kernels.stamp_markers(
        canvas, HEIGHT, WIDTH, centre, one * 0, np.zeros((1, 2, 2), np.int64), 2, palette
    )
    # Lines from a NaN cast to int64 (they would never end), odd sizes for the box filter.
    nan_end = np.array([[0, np.iinfo(np.int64).min]], dtype=np.int64)
    assert not kernels.draw_lines(canvas, HEIGHT, WIDTH, centre, nan_end, colour)
    assert not kernels.draw_lines(
        canvas, HEIGHT, WIDTH, centre, np.array([[0, 2**27]], dtype=np.int64), colour
    )
    assert not kernels.stamp_markers(canvas, HEIGHT, WIDTH, nan_end, one * 0, template * 0, 3, palette)
    assert not kernels.box_mean(canvas, HEIGHT, WIDTH, np.empty((HEIGHT // 4, WIDTH // 4, 3), np.float32), 4)
    assert not kernels.box_mean(canvas, HEIGHT, WIDTH, np.empty((12, 17, 3), np.float32), 7)
    assert np.array_equal(canvas, before)
    assert kernels.box_mean(canvas, HEIGHT, WIDTH, np.empty((45, 60, 3), np.float32), 2)
