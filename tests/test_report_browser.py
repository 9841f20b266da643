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


# ---- big sets: paging, filtering, level of detail ------------------------------------------------


def _big_document(count: int, seed: int = 7) -> Any:
    """``count`` clips spread over the space, a finding for every 10th clip (rings), an acute
    triangle finding for every 20th triangle (areas), a placeholder for every 8th clip, and foot
    contacts, range and guesses on some clips so every kind of table cell appears."""
    import numpy as np
    from test_report import make_document

    from blendspace_pipeline.space.document import DiagnosticDoc, PlaceholderDoc

    rng = np.random.default_rng(seed)
    points = [
        (f"take_{i:05d}", float(rng.uniform(-175, 175)), float(rng.uniform(-2.8, 5.8))) for i in range(count)
    ]
    names = [name for name, _, _ in points]
    doc = make_document(points, generated=frozenset(names[::37]))
    findings = [
        DiagnosticDoc(
            rule="misalignment",
            code="BS003",
            severity="warning",
            message=f"{n} is off its axis",
            clips=[n],
            position=[x, y],
        )
        for n, x, y in points[::10]
    ]
    findings += [
        DiagnosticDoc(
            rule="acute-triangle",
            code="BS002",
            severity="warning",
            message=f"sliver {k}",
            clips=[names[i] for i in tri],
            hint="add a clip",
        )
        for k, tri in enumerate(doc.triangles[::20])
    ]
    findings.append(DiagnosticDoc(rule="uncovered-area", code="BS005", severity="info", message="covers 97%"))
    doc.diagnostics = findings
    doc.placeholders = [
        PlaceholderDoc(
            position=[x, y],
            priority="necessary" if k % 3 else "suggested",
            rule="acute-triangle",
            reason=f"fills sliver {k}",
            features={"turn_rate": x, "speed": y},
        )
        for k, (_, x, y) in enumerate(points[::8])
    ]
    for k, sample in enumerate(doc.samples[::5]):
        sample.contacts = {"left": [[0.0, 0.35], [0.6, 0.95]], "right": [[0.3, 0.65]]}
        assert sample.clip is not None
        sample.clip.plant_phases = {"left": 0.0, "right": 0.5}
        if k % 3 == 0:
            sample.clip.range, sample.clip.range_auto = [0.25, 1.25], True
            sample.clip.guesses = ["skeleton: {units: 0.01}"]
    return doc


def _open(browser: Any, doc: Any, path: Path) -> tuple[Any, list[str]]:
    write_html_report(doc, path)
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(path.as_uri())
    return page, errors


def _row_ids(page: Any, table: str, attribute: str) -> list[int]:
    return [
        int(v)
        for v in page.eval_on_selector_all(
            f"#{table} tbody tr", f"rs => rs.map(r => r.getAttribute('{attribute}'))"
        )
    ]


def test_next_page_shows_the_following_rows(browser: Any, tmp_path: Path) -> None:
    from blendspace_pipeline.report.tables import PAGE_SIZE

    doc = _big_document(400)
    page, errors = _open(browser, doc, tmp_path / "paged.report.html")
    try:
        assert _row_ids(page, "clips-table", "data-clip-row") == list(range(PAGE_SIZE))
        page.click('.pager[data-for="clips-table"] button[data-step="1"]')
        assert _row_ids(page, "clips-table", "data-clip-row") == list(range(PAGE_SIZE, 2 * PAGE_SIZE))
        assert f"{PAGE_SIZE + 1}–{2 * PAGE_SIZE} of {len(doc.samples)}" in page.inner_text(
            '.pager[data-for="clips-table"] .page-info'
        )
        page.click('.pager[data-for="clips-table"] button[data-step="-1"]')
        assert _row_ids(page, "clips-table", "data-clip-row") == list(range(PAGE_SIZE))
        # The other long tables page the same way.
        page.click('.pager[data-for="diagnostics-table"] button[data-step="1"]')
        second = list(range(PAGE_SIZE, min(2 * PAGE_SIZE, len(doc.diagnostics))))
        assert len(second) > 10 and _row_ids(page, "diagnostics-table", "data-diagnostic") == second
        assert page.locator("#clips-table tbody tr").count() == PAGE_SIZE  # one page in the DOM
    finally:
        page.close()
    assert not errors, errors


def test_the_filter_finds_a_clip_on_page_7(browser: Any, tmp_path: Path) -> None:
    from blendspace_pipeline.report.tables import PAGE_SIZE

    doc = _big_document(400)
    target = 6 * PAGE_SIZE + 17  # on page 7
    name = doc.samples[target].name
    page, errors = _open(browser, doc, tmp_path / "filter.report.html")
    try:
        assert page.locator(f'#clips-table [data-clip-row="{target}"]').count() == 0
        page.fill('.pager[data-for="clips-table"] input', name.upper())  # case does not matter
        assert _row_ids(page, "clips-table", "data-clip-row") == [target]
        assert name in page.inner_text("#clips-table tbody")
        page.click(f'#clips-table [data-clip-row="{target}"]')
        assert name in page.inner_text("#details")
        # Selecting a clip from elsewhere (its finding, found in the diagnostics table) turns the
        # clips table to that clip's page and marks its row.
        page.fill('.pager[data-for="clips-table"] input', "")
        other = 6 * PAGE_SIZE + 30  # a clip with a misalignment finding (every 10th has one)
        index = next(i for i, d in enumerate(doc.diagnostics) if d.clips == [doc.samples[other].name])
        page.fill('.pager[data-for="diagnostics-table"] input', doc.diagnostics[index].message)
        page.click(f'#diagnostics-table [data-diagnostic="{index}"]')
        page.click(f'#details [data-goto-sample="{other}"]')
        assert page.locator(f'#clips-table [data-clip-row="{other}"].highlight').count() == 1
        assert _row_ids(page, "clips-table", "data-clip-row") == list(range(6 * PAGE_SIZE, 7 * PAGE_SIZE))
        assert page.locator("#clips-table tbody tr").count() == PAGE_SIZE
    finally:
        page.close()
    assert not errors, errors


def test_script_rows_match_the_build_rows(browser: Any, tmp_path: Path) -> None:
    """Pages after the first are rendered by the script: its rows must read exactly like the
    rows the build writes (every kind of cell: contacts, ranges, guesses, generated, units)."""
    from blendspace_pipeline.report import tables

    doc = _big_document(120)
    page, errors = _open(browser, doc, tmp_path / "rows.report.html")
    try:
        for table, rows in (
            ("clips-table", tables.clip_rows(doc)),
            ("diagnostics-table", tables.diagnostic_rows(doc)),
            ("placeholders-table", tables.placeholder_rows(doc)),
        ):
            pages = -(-len(rows) // tables.PAGE_SIZE)
            for number in range(pages):
                start = number * tables.PAGE_SIZE
                expected = "".join(rows[start : start + tables.PAGE_SIZE])
                # Both through the browser's parser, so only the markup can differ, not its spelling.
                same = page.evaluate(
                    """([table, html]) => {
                        const t = document.createElement('tbody'); t.innerHTML = html;
                        return document.querySelector('#' + table + ' tbody').innerHTML === t.innerHTML;
                    }""",
                    [table, expected],
                )
                assert same, (table, number)
                if number + 1 < pages:
                    page.click(f'.pager[data-for="{table}"] button[data-step="1"]')
    finally:
        page.close()
    assert not errors, errors


def test_a_10000_clip_report_has_a_bounded_dom_and_still_selects(browser: Any, tmp_path: Path) -> None:
    """The element count does not grow with the set: 10,000 clips give about as many elements
    as 1,000; selection still marks a finding's clips and clicking a marker still finds it."""
    from blendspace_pipeline.report.diagram import Layout, build_scene

    counts = {}
    for count in (1_000, 10_000):
        doc = _big_document(count)
        page, errors = _open(browser, doc, tmp_path / f"big{count}.report.html")
        try:
            counts[count] = page.evaluate("document.getElementsByTagName('*').length")
            if count == 10_000:
                index = next(i for i, d in enumerate(doc.diagnostics) if d.rule == "acute-triangle")
                page.fill('.pager[data-for="diagnostics-table"] input', doc.diagnostics[index].message + " ")
                page.fill('.pager[data-for="diagnostics-table"] input', doc.diagnostics[index].message)
                page.click(f'#diagnostics-table [data-diagnostic="{index}"]')
                marked = page.eval_on_selector_all(
                    "#space .sample.highlight", "els => els.map(e => e.dataset.sample)"
                )
                assert sorted(marked) == sorted(doc.diagnostics[index].clips)
                assert page.locator(f'#space [data-diagnostic-shape="{index}"].highlight').count() == 1
                # Click where a clip is drawn (from the layout the SVG uses): it is selected.
                target = doc.samples[4321]
                marker = build_scene(doc, Layout()).samples[4321]
                box = page.locator("#space").bounding_box()
                scale = box["width"] / Layout().width
                page.mouse.click(box["x"] + marker.x * scale, box["y"] + marker.y * scale)
                assert target.name in page.inner_text("#details h3")
        finally:
            page.close()
        assert not errors, errors
    assert counts[10_000] < 4_000, counts
    assert counts[10_000] <= counts[1_000] * 1.1, counts
