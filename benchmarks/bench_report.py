"""How big and how fast the HTML report is for a 1,000-clip set, next to a 10-clip one.

    python benchmarks/bench_report.py [--samples 1000] [--runs 3] [--out DIR]

Builds synthetic documents (random snapped positions, the build's Delaunay triangulation, a
mix of diagnostics and placeholders, some hand placements so the error-map comparison is in),
writes each report and its PNG, then opens the report in headless Chromium (Debian's
/usr/bin/chromium through Playwright) and reads the Performance API: time to the `load` event
and to first contentful paint. Target: a 1,000-clip report opens in under 2 s.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.report import write_html_report, write_png
from blendspace_pipeline.space.document import (
    AxisDoc,
    BlendSpaceDocument,
    DiagnosticDoc,
    PlaceholderDoc,
    SampleDoc,
)
from blendspace_pipeline.space.geometry import AxisRange, normalise
from blendspace_pipeline.space.triangulate import triangulate

AXES = [
    AxisDoc(name="x", feature="turn_rate", min=-180, max=180, divisions=100, unit="deg/s"),
    AxisDoc(name="y", feature="speed", min=-3, max=6, divisions=90, unit="m/s"),
]
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
TARGET_SECONDS = 2.0


def synthetic_document(count: int, seed: int = 1) -> BlendSpaceDocument:
    rng = np.random.default_rng(seed)
    ranges = (AxisRange(-180, 180), AxisRange(-3, 6))
    measured = np.column_stack([rng.uniform(-180, 180, count), rng.uniform(-3, 6, count)])
    steps = np.array([3.6, 0.1])
    snapped = np.round(measured / steps) * steps
    triangles = [list(t) for t in triangulate(normalise(snapped, ranges)).triangles]
    samples = [
        SampleDoc(
            name=f"clip_{i:04d}",
            source=f"clips/clip_{i:04d}.bvh",
            features={
                "turn_rate": float(m[0]),
                "speed": float(m[1]),
                "duration": 1.2,
                "turn": float(m[0] * 1.2),
            },
            position=[float(p[0]), float(p[1])],
            snapping_error=[float(p[0] - m[0]), float(p[1] - m[1])],
            manual_position=[float(p[0]), float(p[1] + 0.2)] if i % 10 == 0 else None,
            generated=i % 50 == 0,
            fix="axis-clip" if i % 50 == 0 else None,
        )
        for i, (m, p) in enumerate(zip(measured, snapped, strict=True))
    ]
    return BlendSpaceDocument(
        schema_version=1,
        name=f"bench{count}",
        axes=AXES,
        samples=samples,
        triangles=triangles,
        diagnostics=_diagnostics(samples, triangles, rng),
        placeholders=[
            PlaceholderDoc(
                position=[float(x), float(y)],
                priority="necessary" if k % 3 else "suggested",
                rule="acute-triangle",
                reason="covers a sliver",
            )
            for k, (x, y) in enumerate(zip(rng.uniform(-180, 180, 20), rng.uniform(-3, 6, 20), strict=True))
        ],
    )


def _diagnostics(
    samples: list[SampleDoc], triangles: list[list[int]], rng: np.random.Generator
) -> list[DiagnosticDoc]:
    """About one finding per ten clips, spread over the five rules of the paper."""
    names = [s.name for s in samples]
    found = [
        DiagnosticDoc(
            rule="uncovered-area", code="BS005", severity="info", message="the samples cover 97.0%"
        ),
    ]
    for k, tri in enumerate(triangles[: len(samples) // 20]):
        clips = [names[i] for i in tri]
        found.append(DiagnosticDoc(rule="acute-triangle", code="BS002", severity="warning",
                                   message=f"sliver {k}", clips=clips, hint="add a clip"))  # fmt: skip
        found.append(DiagnosticDoc(rule="crossing-axis", code="BS001", severity="error",
                                   message=f"crossing {k}", clips=clips[:2], fix="axis-clip"))  # fmt: skip
    for i in rng.choice(len(samples), size=min(len(samples), len(samples) // 20 + 1), replace=False):
        found.append(DiagnosticDoc(rule="misalignment", code="BS003", severity="warning",
                                   message="off the axis", clips=[names[int(i)]]))  # fmt: skip
    return found


def measure_load(browser: Any, path: Path, runs: int) -> tuple[float, float]:
    """Median seconds to the load event and to first contentful paint, fresh page each run."""
    loads, paints = [], []
    for _ in range(runs):
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(path.as_uri(), wait_until="load")
        page.wait_for_function("performance.getEntriesByName('first-contentful-paint').length > 0")
        timing = page.evaluate(
            """() => ({load: performance.getEntriesByType('navigation')[0].loadEventEnd,
                     paint: performance.getEntriesByName('first-contentful-paint')[0].startTime})"""
        )
        loads.append(timing["load"] / 1000.0)
        paints.append(timing["paint"] / 1000.0)
        page.close()
    return statistics.median(loads), statistics.median(paints)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None, help="keep the reports here (default: a temp dir)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-report-"))
    out.mkdir(parents=True, exist_ok=True)
    from playwright.sync_api import sync_playwright

    rows = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        for count in (10, args.samples):
            doc = synthetic_document(count)
            html, png = out / f"bench{count}.report.html", out / f"bench{count}.png"
            start = time.perf_counter()
            write_html_report(doc, html)
            html_seconds = time.perf_counter() - start
            start = time.perf_counter()
            write_png(doc, png)
            png_seconds = time.perf_counter() - start
            load, paint = measure_load(browser, html, args.runs)
            rows.append((count, len(doc.triangles), len(doc.diagnostics), html.stat().st_size / 1024,
                         html_seconds, png_seconds, load, paint))  # fmt: skip
        browser.close()
    print(f"reports in {out}")
    print("clips triangles diagnostics   size KB  write html s  write png s  load s  first paint s")
    for row in rows:
        print("{:5d} {:9d} {:11d} {:9.1f} {:13.3f} {:12.3f} {:7.3f} {:14.3f}".format(*row))
    slowest = rows[-1][6]
    verdict = "meets" if slowest < TARGET_SECONDS else "MISSES"
    print(f"{args.samples} clips: loads in {slowest:.3f} s, {verdict} the {TARGET_SECONDS:g} s target")
    return 0 if slowest < TARGET_SECONDS else 1


if __name__ == "__main__":
    raise SystemExit(main())
