"""The report in a real headless Chromium: markers, diagnostic selection, the error-map switch.

Needs Debian's `chromium` (/usr/bin/chromium) and Playwright for Python; `playwright install`
is never run: the system browser is launched directly. Screenshots go to test-artifacts/.
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_report import TRICKY, sample_document

from blendspace_pipeline.report import write_html_report

ARTIFACTS = Path(__file__).resolve().parents[1] / "test-artifacts"
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]

sync_api = pytest.importorskip(
    "playwright.sync_api", reason="Playwright for Python is not installed (pip install playwright)"
)
if not Path(CHROMIUM).exists():
    pytest.skip("Debian's chromium is not installed (apt-get install -y chromium)", allow_module_level=True)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_api.sync_playwright() as playwright:
        instance = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield instance
        instance.close()


@pytest.fixture
def page(browser: Any, tmp_path: Path) -> Iterator[Any]:
    doc = sample_document()
    path = tmp_path / "locomotion.report.html"
    write_html_report(doc, path)
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(path.as_uri())
    yield page
    page.close()
    assert not errors, f"script errors in the report: {errors}"


def test_markers_match_the_document(page: Any) -> None:
    doc = sample_document()
    assert page.locator("#space [data-sample]").count() == len(doc.samples)
    assert page.locator("#space [data-placeholder]").count() == len(doc.placeholders)
    assert page.locator("#space [data-placeholder].necessary").count() == 1
    # The escaped name reached the DOM intact and its marker can be found by it.
    assert page.locator(f"#space [data-sample='{TRICKY.replace(chr(39), '')}']").count() == 1


def test_clicking_a_diagnostic_highlights_its_clips(page: Any) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    doc = sample_document()
    index = next(i for i, d in enumerate(doc.diagnostics) if d.rule == "crossing-axis")
    page.click(f'[data-diagnostic="{index}"]')
    highlighted = page.eval_on_selector_all(
        "#space .sample.highlight", "els => els.map(e => e.dataset.sample)"
    )
    assert sorted(highlighted) == sorted(doc.diagnostics[index].clips)
    assert page.locator(f'#space [data-diagnostic-shape="{index}"].highlight').count() >= 1
    assert "crossing-axis" in page.inner_text("#details")
    page.screenshot(path=str(ARTIFACTS / "report.png"), full_page=True)
    # Another row moves the highlight: only the new diagnostic's clips stay marked.
    acute = next(i for i, d in enumerate(doc.diagnostics) if d.rule == "acute-triangle")
    page.click(f'[data-diagnostic="{acute}"]')
    highlighted = page.eval_on_selector_all(
        "#space .sample.highlight", "els => els.map(e => e.dataset.sample)"
    )
    assert sorted(highlighted) == sorted(doc.diagnostics[acute].clips)


def test_clicking_a_sample_shows_its_measurements(page: Any) -> None:
    page.click('#space [data-sample="walk_b"]', force=True)
    details = page.inner_text("#details")
    assert "walk_b" in details and "clips/walk_b.bvh" in details and "misalignment" in details
    assert page.locator('[data-clip-row="8"].highlight').count() == 1


def test_severity_filter_hides_rows(page: Any) -> None:
    page.uncheck('#diagnostic-filters input[value="warning"]')
    visible = page.eval_on_selector_all(
        "#diagnostics-table tbody tr", "rows => rows.filter(r => !r.hidden).map(r => r.dataset.severity)"
    )
    assert visible == ["error", "info"]


def test_error_map_switches_to_hand_placement(page: Any) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    assert page.locator('#heat .heat-view[data-mode="manual"]').is_hidden()
    page.check('input[name="heat-mode"][value="manual"]')
    assert page.locator('#heat .heat-view[data-mode="manual"]').is_visible()
    assert page.locator('#heat .heat-view[data-mode="measured"]').is_hidden()
    box = page.locator("#heat").bounding_box()
    page.mouse.move(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
    assert "off by" in page.inner_text("#heat-point") or "outside" in page.inner_text("#heat-point")
    page.locator("#trajectory").screenshot(path=str(ARTIFACTS / "report-trajectory.png"))


SAMPLE_PROJECT = Path(__file__).resolve().parents[1] / "sample_project"


def test_sample_project_report_in_the_browser(browser: Any, tmp_path: Path) -> None:
    """The issue's end-to-end check: build the sample project, open its report, count and click."""
    from blendspace_pipeline.pipeline.outputs import build

    # The README's main job: the main manifest (lateral.yaml beside it is its beta layer).
    result = build(SAMPLE_PROJECT / "manifest.yaml", tmp_path / "build")
    doc = result.document
    report = tmp_path / "build" / f"{doc.name}.report.html"
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    try:
        page.goto(report.as_uri())
        assert page.locator("#space [data-sample]").count() == len(doc.samples)
        assert page.locator("#space [data-placeholder]").count() == len(doc.placeholders)
        with_clips = [i for i, d in enumerate(doc.diagnostics) if d.clips]
        assert with_clips, "the sample project is meant to trip rules that name clips"
        index = with_clips[0]
        page.click(f'[data-diagnostic="{index}"]')
        marked = page.eval_on_selector_all(
            "#space .sample.highlight", "els => els.map(e => e.dataset.sample)"
        )
        assert sorted(marked) == sorted(set(doc.diagnostics[index].clips))
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / "sample-project-report.png"), full_page=True)
    finally:
        page.close()


def test_engine_maps_in_the_browser(browser: Any, tmp_path: Path) -> None:
    """The trajectory-error and foot-skate maps of the engine-played blend: drawn, coloured, and
    reading the numbers the JSON carries."""
    import json

    from blendspace_pipeline.cli import main
    from blendspace_pipeline.motion.procedural import GaitSpec, generate_planted
    from blendspace_pipeline.writers.usd_clip import write_usd_clip

    specs = [
        GaitSpec("idle", duration=1.0),
        GaitSpec("walk_fwd", speed=1.4, duration=1.0),
        GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
        GaitSpec("run_turn_left", speed=4.0, turn_rate=90.0, duration=1.0, stride_length=2.6),
        GaitSpec("walk_turn_left", speed=1.4, turn_rate=60.0, duration=1.5),
    ]
    for spec in specs:
        clip = generate_planted(spec)
        write_usd_clip(clip, tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: engine\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -10, max: 100, divisions: 22}\n"
        "  y: {feature: speed, min: 0, max: 5, divisions: 50}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    summary = json.loads((out / "engine.blendspace.json").read_text())["blend_quality"]["summary"]
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    try:
        page.goto((out / "engine.report.html").as_uri())
        for ident in ("runtime-heat", "skate-heat"):
            figure = page.locator(f"#{ident}")
            figure.scroll_into_view_if_needed()
            assert figure.is_visible()
            box = page.locator(f"#{ident} image").bounding_box()
            assert box is not None and box["width"] > 100 and box["height"] > 100
            # The map is a real picture: its pixels take several colours of the ramp.
            colours = page.evaluate(
                """async (id) => {
                    const href = document.querySelector('#' + id + ' image').getAttribute('href');
                    const img = new Image(); img.src = href; await img.decode();
                    const c = document.createElement('canvas'); c.width = img.width; c.height = img.height;
                    const g = c.getContext('2d'); g.drawImage(img, 0, 0);
                    const d = g.getImageData(0, 0, c.width, c.height).data; const seen = new Set();
                    for (let i = 0; i < d.length; i += 4) seen.add(d[i] * 65536 + d[i + 1] * 256 + d[i + 2]);
                    return seen.size;
                }""",
                ident,
            )
            assert colours > 3
        maxima = {
            ident: float(page.get_attribute(f"#{ident}-figure", "data-max"))
            for ident in ("runtime-heat", "skate-heat")
        }
        assert maxima["runtime-heat"] == pytest.approx(summary["trajectory_error_max"], rel=1e-4)
        assert maxima["skate-heat"] == pytest.approx(summary["foot_skate_max"], rel=1e-4)
        assert "m/s" in page.inner_text("#engine-stats")
        ARTIFACTS.mkdir(exist_ok=True)
        page.locator("#engine-blend").screenshot(path=str(ARTIFACTS / "report-engine-maps.png"))
    finally:
        page.close()
    assert not errors, f"script errors in the report: {errors}"
