"""Writers and report pieces that must stay linear at 10,000 samples, each checked against a
slow, obvious computation: the JSON's line layout against pydantic's indented dump, the PNG's
span rasteriser against per-pixel tests, and its marker z-buffer against drawing one by one."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_report import sample_document

from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.writers.blendspace_json import dumps_document, write_blendspace_json


def test_json_holds_exactly_what_the_indented_dump_holds_one_line_per_item(tmp_path: Path) -> None:
    doc = sample_document()
    doc.samples[0].contacts = {"left": [[0.0, 0.4]], "right": []}
    path = tmp_path / "locomotion.blendspace.json"
    write_blendspace_json(doc, path)
    text = path.read_text(encoding="utf-8")
    assert json.loads(text) == json.loads(doc.model_dump_json(indent=2))
    assert BlendSpaceDocument.model_validate_json(text) == doc
    # One line per sample (a changed clip is one changed line), in the document's order.
    lines = [json.loads(line.rstrip(",")) for line in text.splitlines() if '"source":' in line]
    assert [line["name"] for line in lines] == [s.name for s in doc.samples]
    assert len(text) < 0.7 * len(doc.model_dump_json(indent=2))


def test_json_of_an_empty_document_still_parses() -> None:
    doc = sample_document()
    doc.samples, doc.triangles, doc.diagnostics, doc.placeholders = [], [], [], []
    assert BlendSpaceDocument.model_validate_json(dumps_document(doc)) == doc


def _inside_convex(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Per-pixel oracle: the pixel centre is on the inner side of (or on) every edge."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    cross = (b[None, :, 0] - a[None, :, 0]) * (points[:, None, 1] - a[None, :, 1]) - (
        b[None, :, 1] - a[None, :, 1]
    ) * (points[:, None, 0] - a[None, :, 0])
    inside: np.ndarray = (cross >= -1e-9).all(axis=1) | (cross <= 1e-9).all(axis=1)  # either winding
    return inside


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_polygon_and_disc_spans_cover_the_pixels_a_per_pixel_test_finds(seed: int) -> None:
    from blendspace_pipeline.report.png import _coverage, _disc_spans, _polygon_spans

    rng = np.random.default_rng(seed)
    height, width = 90, 120
    triangles = [rng.uniform(-20, 130, size=(3, 2)) for _ in range(40)]
    centres = rng.uniform(-10, 130, size=(25, 2))
    radii = rng.uniform(0.5, 30, size=25)
    yy, xx = np.mgrid[0:height, 0:width]
    pixels = np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], axis=1)
    want = np.zeros(height * width, dtype=np.int64)
    for tri in triangles:
        want += _inside_convex(pixels, tri)
    count, top, left = _coverage(_polygon_spans(triangles, height, width))
    got = np.zeros((height, width), dtype=np.int64)
    got[top : top + count.shape[0], left : left + count.shape[1]] = count
    # Only a pixel centre within rounding of an edge may fall either way.
    assert (got.ravel() != want).sum() <= 2
    discs = np.zeros(height * width, dtype=np.int64)
    for centre, radius in zip(centres, radii, strict=True):
        discs += np.hypot(pixels[:, 0] - centre[0], pixels[:, 1] - centre[1]) <= radius
    count, top, left = _coverage(_disc_spans(centres, radii, height, width))
    got = np.zeros((height, width), dtype=np.int64)
    got[top : top + count.shape[0], left : left + count.shape[1]] = count
    assert (got.ravel() == discs).all()


def test_markers_drawn_at_once_equal_markers_drawn_one_by_one() -> None:
    """The z-buffer keeps the last marker on top, as drawing them in order would."""
    from blendspace_pipeline.report.png import _Pen

    rng = np.random.default_rng(5)
    centres = rng.uniform(-5, 85, size=(300, 2))
    centres[10] = centres[3]  # two markers on one pixel: the later wins
    kinds = rng.integers(0, 2, size=300)
    layers = [
        [("disc", 5.0, (1.0, 1.0, 1.0)), ("disc", 3.0, (0.0, 0.0, 1.0))],
        [("square", 4.0, (1.0, 1.0, 0.0)), ("diamond", 3.0, (1.0, 0.0, 0.0))],
    ]
    together = _Pen(np.zeros((80, 80, 3), dtype=np.float32))
    together.markers(centres, kinds, layers)
    one_by_one = _Pen(np.zeros((80, 80, 3), dtype=np.float32))
    for centre, kind in zip(centres, kinds, strict=True):
        for layer in layers[kind]:
            one_by_one.markers(np.array([centre]), np.zeros(1, dtype=np.int64), [[layer]])
    assert np.array_equal(together.canvas, one_by_one.canvas)
