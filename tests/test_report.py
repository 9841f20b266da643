"""The HTML report and the PNG: structure, escaping, self-containment and marker positions."""

from __future__ import annotations

import json
import os
import struct
import zlib
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import Delaunay

from blendspace_pipeline.report import write_html_report, write_png
from blendspace_pipeline.report.diagram import COLOURS, build_scene, coverage_percent
from blendspace_pipeline.report.html import render_html
from blendspace_pipeline.space.document import (
    AxisDoc,
    BlendSpaceDocument,
    BuildInfoDoc,
    ClipInfoDoc,
    DiagnosticDoc,
    PlaceholderDoc,
    SampleDoc,
)
from blendspace_pipeline.space.geometry import AxisRange, normalise

TRICKY = 'run <fast> & "hard"'
X_AXIS = AxisDoc(name="x", feature="turn_rate", min=-180, max=180, divisions=72, unit="deg/s")
Y_AXIS = AxisDoc(name="y", feature="speed", min=-3, max=6, divisions=90, unit="m/s")


def make_document(
    points: list[tuple[str, float, float]],
    *,
    generated: frozenset[str] = frozenset(),
    manual: dict[str, list[float]] | None = None,
    diagnostics: list[DiagnosticDoc] | None = None,
    placeholders: list[PlaceholderDoc] | None = None,
) -> BlendSpaceDocument:
    """A document placing each (name, turn_rate, speed) exactly, with Delaunay triangles of the
    normalised positions (as the build makes them)."""
    axes = (AxisRange(X_AXIS.min, X_AXIS.max), AxisRange(Y_AXIS.min, Y_AXIS.max))
    positions = np.array([(x, y) for _, x, y in points], dtype=np.float64)
    triangles = [sorted(map(int, t)) for t in Delaunay(normalise(positions, axes)).simplices]
    samples = [
        SampleDoc(
            name=name,
            source=f"clips/{name}.bvh",
            features={"turn_rate": x, "speed": y, "duration": 1.0},
            position=[x, y],
            generated=name in generated,
            fix="axis-clip" if name in generated else None,
            manual_position=(manual or {}).get(name),
            clip=ClipInfoDoc(
                duration=1.0,
                fps=30,
                frames=31,
                meters_per_unit=0.01,
                units_source="file",
                up_axis="y",
                root="hip midpoint",
                facing="hip line",
                notes=["T-pose in frame 0"],
            ),
        )
        for name, x, y in points
    ]
    return BlendSpaceDocument(
        schema_version=1,
        name="locomotion",
        axes=[X_AXIS, Y_AXIS],
        samples=samples,
        triangles=triangles,
        diagnostics=diagnostics or [],
        placeholders=placeholders or [],
        build=BuildInfoDoc(tool_version="0.1.0", manifest="../manifest.yaml", thresholds={"too_close": 8.0}),
    )


LOCOMOTION = [
    ("idle", 0.0, 0.0),
    ("walk", 0.0, 1.4),
    (TRICKY, 0.0, 6.0),
    ("back", 0.0, -3.0),
    ("turn_l", 90.0, 0.0),
    ("turn_r", -90.0, 0.0),
    ("arc_l", 120.0, 3.0),
    ("arc_r", -130.0, 3.5),
    ("walk_b", 5.0, 1.5),
]


def sample_document() -> BlendSpaceDocument:
    diagnostics = [
        DiagnosticDoc(
            rule="crossing-axis",
            code="BS001",
            severity="error",
            message="edge crosses speed = 0",
            clips=["arc_r", "back"],
            position=[-60.0, 0.0],
            fix="axis-clip",
            hint="add a clip on the axis",
        ),
        DiagnosticDoc(
            rule="acute-triangle",
            code="BS002",
            severity="warning",
            message="sliver",
            clips=["idle", "walk", "walk_b"],
            hint="add a clip near it",
        ),
        DiagnosticDoc(
            rule="misalignment",
            code="BS003",
            severity="warning",
            message="walk_b turns a little",
            clips=["walk_b"],
            position=[5.0, 1.5],
        ),
        DiagnosticDoc(
            rule="too-close",
            code="BS004",
            severity="warning",
            message="walk and walk_b are close",
            clips=["walk", "walk_b"],
            position=[2.5, 1.45],
        ),
        DiagnosticDoc(
            rule="uncovered-area", code="BS005", severity="info", message="the samples cover 60.0%"
        ),
        DiagnosticDoc(
            rule="in-place-clip",
            code="BS006",
            severity="warning",
            message=f"{TRICKY} <b>is</b> odd",
            clips=[TRICKY],
        ),
    ]
    placeholders = [
        PlaceholderDoc(
            position=[-90.0, 3.0],
            priority="necessary",
            rule="crossing-axis",
            reason="axis key clip",
            features={"turn_rate": -90.0, "speed": 3.0},
        ),
        PlaceholderDoc(position=[180.0, 6.0], priority="suggested", rule="uncovered-area", reason="corner"),
        PlaceholderDoc(position=[-180.0, -3.0], priority="suggested", rule="uncovered-area", reason="corner"),
    ]
    return make_document(
        LOCOMOTION,
        generated=frozenset({"walk_b"}),
        manual={"walk": [0.0, 2.0]},
        diagnostics=diagnostics,
        placeholders=placeholders,
    )


class _Collector(HTMLParser):
    """Elements with their attributes, the text of script blocks, and every attribute value."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.elements: list[tuple[str, dict[str, str | None]]] = []
        self.scripts: list[tuple[dict[str, str | None], str]] = []
        self.text: list[str] = []
        self._script: dict[str, str | None] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.elements.append((tag, dict(attrs)))
        if tag == "script":
            self._script = dict(attrs)

    def handle_startendtag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.elements.append((tag, dict(attrs)))

    def handle_data(self, data: str) -> None:
        if self._script is not None:
            self.scripts.append((self._script, data))
        else:
            self.text.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag == "script":
            self._script = None

    def with_attribute(self, name: str) -> list[dict[str, str | None]]:
        return [attrs for _, attrs in self.elements if name in attrs]


def _parse(text: str) -> _Collector:
    parser = _Collector()
    parser.feed(text)
    parser.close()
    return parser


def test_report_has_one_marker_per_sample_and_placeholder(tmp_path: Path) -> None:
    doc = sample_document()
    path = tmp_path / "locomotion.report.html"
    write_html_report(doc, path)
    page = _parse(path.read_text(encoding="utf-8"))
    markers = [str(a["data-sample"]) for a in page.with_attribute("data-sample")]
    assert sorted(markers) == sorted(s.name for s in doc.samples)  # names unescaped by the parser: exact
    generated = [
        a["data-sample"] for a in page.with_attribute("data-sample") if "generated" in (a["class"] or "")
    ]
    assert generated == ["walk_b"]
    placeholders = page.with_attribute("data-placeholder")
    assert [(a["data-placeholder"], a["class"]) for a in placeholders] == [
        ("0", "placeholder necessary"),
        ("1", "placeholder suggested"),
        ("2", "placeholder suggested"),
    ]
    rows = [a["data-diagnostic"] for a in page.with_attribute("data-diagnostic")]
    assert rows == [str(i) for i in range(len(doc.diagnostics))]
    shapes = {a["data-diagnostic-shape"] for a in page.with_attribute("data-diagnostic-shape")}
    assert shapes == {str(i) for i in range(len(doc.diagnostics))}  # every diagnostic has its area
    assert not list(tmp_path.glob("*.tmp"))  # the atomic write left no temporary file


def test_report_escapes_user_strings_and_is_self_contained() -> None:
    text = render_html(sample_document())
    assert "<fast>" not in text and "<b>is</b>" not in text  # a name or message never becomes markup
    assert "run &lt;fast&gt; &amp; &quot;hard&quot;" in text
    page = _parse(text)
    assert TRICKY in "".join(page.text)  # the same name reads correctly once parsed
    assert "http" not in text  # no URL of any kind: the file opens offline
    for _, attrs in page.elements:
        for key in ("src", "href"):
            value = attrs.get(key)
            assert value is None or value.startswith(("#", "data:")), f"external reference {key}={value}"
    assert not [t for t, _ in page.elements if t == "link"]  # no external stylesheet


def test_embedded_json_parses_and_describes_the_document() -> None:
    doc = sample_document()
    page = _parse(render_html(doc))
    embedded = [body for attrs, body in page.scripts if attrs.get("type") == "application/json"]
    assert len(embedded) == 1
    data = json.loads(embedded[0])
    assert [s["name"] for s in data["samples"]] == [s.name for s in doc.samples]
    tricky = data["samples"][2]
    assert tricky["name"] == TRICKY and tricky["diagnostics"] == [5]
    walk_b = data["samples"][8]
    assert walk_b["diagnostics"] == [1, 2, 3] and walk_b["generated"] is True
    assert data["samples"][1]["manual"] == [0.0, 2.0]
    heat = data["heat"]
    assert len(heat["measured"]["ex"]) == heat["nx"] * heat["ny"]
    assert heat["manual"] is not None  # one clip is placed by hand, so the comparison is there
    inside = [v for v in heat["measured"]["ex"] if v is not None]
    assert inside and max(inside) < 1e-6  # exact placement: no drift inside the hull
    assert max(v for v in heat["manual"]["ey"] if v is not None) > 0.5  # walk placed 0.6 m/s too fast


def test_report_without_manual_positions_has_no_comparison_switch() -> None:
    doc = make_document(LOCOMOTION)
    text = render_html(doc)
    assert 'name="heat-mode"' not in text and 'data-mode="manual"' not in text
    assert "No diagnostics" in text and "No clips to add" in text


def test_coverage_is_the_hull_share_of_the_axis_rectangle() -> None:
    square = [(0.0, 0.0), (50.0, 0.0), (50.0, 50.0), (0.0, 50.0)]
    assert coverage_percent(square) == pytest.approx(25.0)
    overhanging = [(-50.0, -50.0), (150.0, -50.0), (150.0, 150.0), (-50.0, 150.0)]
    assert coverage_percent(overhanging) == pytest.approx(100.0)
    corners = make_document([("a", -180, -3), ("b", 180, -3), ("c", 180, 6), ("d", -180, 6), ("e", 0, 0)])
    assert build_scene(corners).coverage == pytest.approx(100.0)
    half = make_document([("a", -180, -3), ("b", 180, -3), ("c", 180, 6)])
    assert build_scene(half).coverage == pytest.approx(50.0)


def test_png_is_large_enough_and_markers_sit_where_projected(tmp_path: Path) -> None:
    from OpenImageIO import ImageBuf  # the only OIIO use outside png.py: reading the result back

    from blendspace_pipeline.report.png import PNG_LAYOUT

    doc = sample_document()
    path = tmp_path / "locomotion.png"
    write_png(doc, path)
    image = ImageBuf(str(path))
    spec = image.spec()
    assert (spec.width, spec.height) == (PNG_LAYOUT.width, PNG_LAYOUT.height)
    assert spec.width >= 1024 and spec.height >= 768
    pixels = np.asarray(image.get_pixels())
    scene = build_scene(doc, PNG_LAYOUT)
    for marker in scene.samples:
        expected = COLOURS["generated" if marker.generated else "sample"]
        assert _pixel(pixels, marker.x, marker.y) == pytest.approx(expected, abs=3), marker.name
    for placeholder in scene.placeholders:
        expected = COLOURS[placeholder.priority]
        assert _pixel(pixels, placeholder.x, placeholder.y) == pytest.approx(expected, abs=3)
    # The crossing edge is drawn in the rule's colour along its whole length.
    by_name = {m.name: m for m in scene.samples}
    a, b = by_name["arc_r"], by_name["back"]
    for t in (0.3, 0.5, 0.7):
        point = (a.x + t * (b.x - a.x), a.y + t * (b.y - a.y))
        assert _pixel(pixels, *point) == pytest.approx(COLOURS["crossing-axis"], abs=3)
    # The title was rendered: dark text pixels above the plot.
    assert np.asarray(pixels)[5 : PNG_LAYOUT.top - 30, PNG_LAYOUT.left : PNG_LAYOUT.left + 300].min() < 0.3
    assert not list(tmp_path.glob("*.tmp*"))


def test_png_bytes_are_the_rendered_image_as_oiio_converts_it(tmp_path: Path) -> None:
    """`write_png` rounds the float pixels to 8 bits itself: the file holds what OIIO's own
    conversion of `render`'s float image gives, pixel for pixel."""
    from OpenImageIO import UINT8, ImageBuf

    from blendspace_pipeline.report.png import render

    doc = sample_document()
    write_png(doc, tmp_path / "a.png")
    written = ImageBuf(str(tmp_path / "a.png")).get_pixels(UINT8)
    assert np.array_equal(written, render(doc).get_pixels(UINT8))


def test_png_file_is_read_back_by_oiio_pixel_for_pixel_as_srgb(tmp_path: Path) -> None:
    """`png_file` writes the PNG container itself (zlib rows, CRCs, the sRGB chunks): OIIO's
    libpng reader takes any 8-bit RGB image back unchanged, odd sizes and noise included, and
    reads it as sRGB; other pixel types are refused, not written wrong."""
    from OpenImageIO import UINT8, ImageBuf

    from blendspace_pipeline.report.png import png_file

    rng = np.random.default_rng(3)
    for height, width in ((1, 1), (7, 13), (960, 1280)):
        pixels = rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8)
        pixels[: height // 2] = (40, 80, 120)  # flat colour, as a diagram is
        path = tmp_path / f"{height}x{width}.png"
        path.write_bytes(png_file(pixels))
        image = ImageBuf(str(path))
        assert not image.has_error, image.geterror()
        assert (image.spec().width, image.spec().height, image.spec().nchannels) == (width, height, 3)
        assert np.array_equal(image.get_pixels(UINT8), pixels)
        # libpng drops an optional chunk with a bad CRC without a word: the chunks are checked here.
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        chunks, at = [], 8
        while at < len(data):
            (length,) = struct.unpack(">I", data[at : at + 4])
            kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
            (crc,) = struct.unpack(">I", data[at + 8 + length : at + 12 + length])
            assert crc == zlib.crc32(body, zlib.crc32(kind)), kind
            chunks.append((kind, body))
            at += 12 + length
        assert [kind for kind, _ in chunks] == [b"IHDR", b"sRGB", b"gAMA", b"cHRM", b"IDAT", b"IEND"]
        assert chunks[0][1] == struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
        assert chunks[1][1] == b"\x00" and struct.unpack(">I", chunks[2][1]) == (45455,)
        assert struct.unpack(">8I", chunks[3][1]) == (31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000)
        rows = np.frombuffer(zlib.decompress(chunks[4][1]), dtype=np.uint8).reshape(height, 1 + 3 * width)
        assert not rows[:, 0].any() and np.array_equal(rows[:, 1:].reshape(height, width, 3), pixels)
    with pytest.raises(ValueError, match="8-bit RGB"):
        png_file(np.zeros((4, 4, 4), dtype=np.uint8))
    with pytest.raises(ValueError, match="8-bit RGB"):
        png_file(np.zeros((4, 4, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="8-bit RGB"):
        png_file(np.zeros((0, 4, 3), dtype=np.uint8))


def _pixel(pixels: np.ndarray, x: float, y: float) -> tuple[float, float, float]:
    row, column = round(y), round(x)
    return tuple(float(v) * 255.0 for v in pixels[row, column, :3])  # type: ignore[return-value]


def test_png_of_an_empty_space_still_renders(tmp_path: Path) -> None:
    doc = make_document([("a", -90, 0), ("b", 90, 0), ("c", 0, 3)])
    doc.triangles = []
    doc.samples = doc.samples[:1]
    write_png(doc, tmp_path / "one.png")
    assert (tmp_path / "one.png").stat().st_size > 1000


def test_degenerate_spaces_still_render(tmp_path: Path) -> None:
    """No triangles, a lone clip, clips outside the axis range, an axis that misses zero."""
    lone = make_document([("a", -90, 0), ("b", 90, 0), ("c", 0, 3)])
    lone.samples, lone.triangles = lone.samples[:1], []
    line = make_document([("a", -90, 0), ("b", 90, 0), ("c", 0, 3)])
    line.triangles = []
    outside = make_document([("a", -250, -4), ("b", 250, -4), ("c", 0, 9)])
    shifted = make_document([("a", -90, 1), ("b", 90, 1), ("c", 0, 3)])
    shifted.axes[1] = AxisDoc(name="y", feature="speed", min=0.5, max=6, divisions=11, unit="m/s")
    empty = make_document([("a", -90, 0), ("b", 90, 0), ("c", 0, 3)])
    empty.samples, empty.triangles = [], []
    for index, doc in enumerate((lone, line, outside, shifted, empty)):
        page = _parse(render_html(doc))
        assert len(page.with_attribute("data-sample")) == len(doc.samples)
        write_png(doc, tmp_path / f"{index}.png")
    assert build_scene(line).coverage == 0.0
    # Clips beyond the axis range: only the part of the hull inside the rectangle counts. Check
    # against the share of a fine grid of the rectangle that lies inside the triangle.
    corners = normalise(
        np.array([[-250.0, -4.0], [250.0, -4.0], [0.0, 9.0]]), (AxisRange(-180, 180), AxisRange(-3, 6))
    )
    grid = np.stack(np.meshgrid(np.linspace(0, 100, 401), np.linspace(0, 100, 401)), axis=-1).reshape(-1, 2)
    inside = Delaunay(corners).find_simplex(grid) >= 0
    assert build_scene(outside).coverage == pytest.approx(100.0 * inside.mean(), abs=0.5)
    assert build_scene(shifted).zero_y is None  # speed 0 is off this axis: no main axis to draw


def test_the_report_time_is_reproducible(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from blendspace_pipeline.report.html import build_stamp

    old, new = tmp_path / "old.bvh", tmp_path / "new.yaml"
    for path, when in ((old, 1_600_000_000), (new, 1_700_000_000)):
        path.write_text("x")
        os.utime(path, (when, when))
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    assert build_stamp([old, new, tmp_path / "gone.bvh"]) == "2023-11-14 22:13:20 UTC (newest input file)"
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    assert build_stamp([old, new]) == "1970-01-01 00:00:00 UTC (SOURCE_DATE_EPOCH)"
    monkeypatch.delenv("SOURCE_DATE_EPOCH")
    assert build_stamp([]).endswith("UTC (build time)")


def test_a_truncated_json_output_is_refused_and_a_whole_one_passes(tmp_path: Path) -> None:
    from blendspace_pipeline.report.atomic import IncompleteOutput, verify_written

    whole = tmp_path / "n.blendspace.json"
    whole.write_text('{"samples": [1, 2], "name": "n"}\n')
    verify_written(whole)
    cut = tmp_path / "cut.blendspace.json"
    cut.write_text('{"samples": [1, 2], "na')  # what a full disk leaves
    with pytest.raises(IncompleteOutput, match="incomplete"):
        verify_written(cut)
