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
