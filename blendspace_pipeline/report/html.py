"""`N.report.html`: one self-contained, interactive page (inline CSS, JS and SVG; no network).

What a technical animator opens after every build: the blend space with its problem areas and
placeholders, the diagnostics linked to the diagram, coverage, the trajectory-error map (measured
vs hand placement), every clip's measurements and the build's settings. Data for the script is
embedded once as JSON; the script delegates events, so a 1,000-clip report stays light.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from html import escape
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.features import FEATURE_UNITS
from blendspace_pipeline.motion.blend_model import DEFAULT_SYNC
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.report import tables
from blendspace_pipeline.report.atomic import atomic_path
from blendspace_pipeline.report.diagram import (
    Layout,
    Scene,
    axis_ranges,
    build_scene,
    convex_hull,
)
from blendspace_pipeline.report.heatmap import css_gradient, heat_rgba, png_data_uri, scale_maximum
from blendspace_pipeline.report.svg import LABEL_LIMIT, HeatView, diagram, heat_map, is_lod, lod_data
from blendspace_pipeline.report.trajectory_error import (
    TrajectoryErrorGrid,
    document_trajectory_error,
    has_manual_positions,
    manual_positions,
    manual_triangles,
    measured_positions,
)
from blendspace_pipeline.space.document import BlendQualityDoc, BlendSpaceDocument, ClipInfoDoc, DiagnosticDoc
from blendspace_pipeline.space.geometry import normalise
from blendspace_pipeline.space.runtime_blend import DEFAULT_HORIZON, runtime_grid
from blendspace_pipeline.space.triangulate import triangle_edges

# Foot sliding below this (m/s) is scaled as if it were the maximum: a few cm/s is invisible.
SKATE_SCALE = 0.2
SIGNIFICANT = 5  # digits kept in the embedded JSON: far below any measurement's precision


@dataclass(frozen=True)
class Trajectory:
    measured: TrajectoryErrorGrid
    manual: TrajectoryErrorGrid | None

    @property
    def maximum(self) -> float:
        """Colour-scale top, shared by both placements so their maps compare directly."""
        extra = [self.manual.max_distance] if self.manual is not None else []
        return scale_maximum(self.measured.max_distance, *extra)


def write_html_report(
    doc: BlendSpaceDocument,
    path: Path,
    inputs: Sequence[Path] = (),
    *,
    stamp: str | None = None,
    draft: ReportDraft | None = None,
) -> None:
    """Write the report atomically: a temporary file in the same folder, then a rename.
    ``stamp``: the report's time when the caller has it (else `build_stamp` of ``inputs``);
    ``draft``: the part drawn before the blend quality was known (`draft_report`)."""
    text = render_html(doc, stamp=stamp or build_stamp(inputs), draft=draft)
    with atomic_path(Path(path)) as temporary:
        temporary.write_text(text, encoding="utf-8", newline="\n")


def build_stamp(inputs: Sequence[Path] = ()) -> str:
    """The report's one clock, chosen so that building twice gives byte-identical folders.

    ``SOURCE_DATE_EPOCH`` (the reproducible-builds convention) wins; otherwise the newest
    modification time of the build's inputs (manifest and clips: it changes exactly when the
    report's content may); the wall clock only when there are no inputs to date.
    """
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if epoch.isdigit():
        when, what = datetime.fromtimestamp(int(epoch), UTC), "SOURCE_DATE_EPOCH"
    else:
        times = [p.stat().st_mtime for p in inputs if p.is_file()]
        if times:
            when, what = datetime.fromtimestamp(int(max(times)), UTC), "newest input file"
        else:
            when, what = datetime.now(UTC), "build time"
    return f"{when:%Y-%m-%d %H:%M:%S} UTC ({what})"


@dataclass(frozen=True, eq=False)  # one draft per document object: identity, not content
class ReportDraft:
    """Everything of ``doc``'s report that its blend quality does not change (all but the summary
    cards and the engine section), drawn once.

    `build --jobs N` draws it while the blend quality maps are still computed on the other core,
    so the report is finished in a fraction of its time once they arrive (0.2 of 0.25 s on 1,000
    clips). It belongs to the one document object it was drawn from, which the build changes
    afterwards only by setting `blend_quality`; `render_html` draws afresh for any other object."""

    doc: BlendSpaceDocument
    scene: Scene
    trajectory: Trajectory
    sections: str  # from the diagram to the trajectory error map, rendered
    clips: str  # the clips table section, rendered
    script: str  # the embedded data for the script, as JSON


def draft_report(doc: BlendSpaceDocument) -> ReportDraft:
    scene = build_scene(doc, Layout())
    trajectory = Trajectory(
        measured=document_trajectory_error(doc),
        manual=document_trajectory_error(doc, manual=True) if has_manual_positions(doc) else None,
    )
    # The long tables show their first page as HTML rendered here; the script renders the other
    # pages (and filtered ones) from the embedded data with the same markup (`report.js` rows).
    page = tables.PAGE_SIZE
    rows = {
        "diagnostics-table": tables.diagnostic_rows(doc, page),
        "placeholders-table": tables.placeholder_rows(doc, page),
        "clips-table": tables.clip_rows(doc, page),
    }
    sections = "".join(
        [
            _diagram_section(scene),
            _section(
                "diagnostics",
                "Diagnostics",
                tables.diagnostic_filters(doc) + tables.diagnostics_table(doc, rows["diagnostics-table"]),
            ),
            _refused_section(doc),
            _section(
                "placeholders",
                "Clips to add",
                _placeholder_intro() + tables.placeholders_table(doc, rows["placeholders-table"]),
            ),
            _coverage_section(doc, scene),
            _trajectory_section(doc, scene, trajectory),
        ]
    )
    data = _data(doc, scene, trajectory)
    data["page_size"] = page
    data["feature_columns"] = tables.feature_columns(doc)
    data["units"] = dict(FEATURE_UNITS)
    if is_lod(scene):
        data["lod"] = lod_data(scene)
    clips = _section("clips", "Clips", tables.clips_table(doc, rows["clips-table"]))
    return ReportDraft(doc, scene, trajectory, sections, clips, _script_json(data))


def render_html(
    doc: BlendSpaceDocument, *, stamp: str | None = None, draft: ReportDraft | None = None
) -> str:
    if draft is None or draft.doc is not doc:
        draft = draft_report(doc)
    scene, trajectory = draft.scene, draft.trajectory
    stamp = stamp or build_stamp()
    body = "".join(
        [
            _summary(doc, scene, trajectory),
            draft.sections,
            _engine_section(doc, scene),
            draft.clips,
            _section("build", "Build", tables.build_table(doc, stamp)),
        ]
    )
    title = escape(f"{doc.name} — blend-space report")
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">'
        f'<meta name="color-scheme" content="light dark"><title>{title}</title>'
        f"<style>{_asset('report.css')}</style></head><body>"
        f"<header><h1>{escape(doc.name)} <small>blend-space report</small></h1></header><main>{body}</main>"
        f'<div id="tooltip" role="tooltip" hidden></div>'
        f'<script type="application/json" id="report-data">{draft.script}'
        "</script>"
        f"<script>{_asset('report.js')}</script></body></html>\n"
    )


def _asset(name: str) -> str:
    return resources.files("blendspace_pipeline.report").joinpath(name).read_text(encoding="utf-8")


def _section(ident: str, title: str, content: str) -> str:
    return f'<section id="{ident}"><h2>{escape(title)}</h2>{content}</section>'


def _summary(doc: BlendSpaceDocument, scene: Scene, trajectory: Trajectory) -> str:
    counts = {s: sum(d.severity == s for d in doc.diagnostics) for s in tables.SEVERITIES}
    generated = sum(s.generated for s in doc.samples)
    necessary = sum(p.priority == "necessary" for p in doc.placeholders)
    verdict = (
        f'<p class="verdict bad">{_plural(counts["error"], "error")} to fix before this space blends '
        "cleanly.</p>"
        if counts["error"]
        else '<p class="verdict good">No errors: the space is usable'
        + (f", with {_plural(counts['warning'], 'warning')} to review.</p>" if counts["warning"] else ".</p>")
    )
    cards = [
        ("clips", f"{len(doc.samples) - generated}", f"+ {generated} generated" if generated else "measured"),
        ("errors", str(counts["error"]), f"{counts['warning']} warnings, {counts['info']} info"),
        ("clips to add", str(len(doc.placeholders)), f"{necessary} necessary"),
        ("coverage", f"{scene.coverage:.1f}%", "of the axis rectangle"),
        ("max drift", _g(trajectory.measured.max_distance), "% of an axis range, inside the hull"),
    ]
    quality = doc.blend_quality
    if quality is not None and "trajectory_error_max" in quality.summary:
        skate = quality.summary.get("foot_skate_max")
        cards.append(
            (
                "as played",
                _g(quality.summary["trajectory_error_max"]),
                f"% error with {quality.sync} sync"
                + (f"; feet slide up to {_g(skate)} m/s" if skate is not None else ""),
            )
        )
    html = "".join(
        f'<div class="card"><div class="card-value">{escape(v)}</div>'
        f'<div class="card-label">{escape(k)}</div>'
        f'<div class="card-note">{escape(n)}</div></div>'
        for k, v, n in cards
    )
    return f'<section id="summary">{verdict}<div class="cards">{html}</div></section>'


def _plural(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def _diagram_section(scene: Scene) -> str:
    toggles = "".join(
        f'<label><input type="checkbox" data-layer="{layer}"{" checked" if on else ""}> {label}</label>'
        for layer, label, on in (
            ("labels", "names", len(scene.samples) <= LABEL_LIMIT),
            ("edges", "triangles", True),
            ("problems", "problem areas", True),
            ("placeholders", "clips to add", True),
        )
    )
    return (
        '<section id="diagram"><h2>Blend space</h2><div class="diagram-wrap"><figure>'
        f"{diagram(scene)}<figcaption>{_legend()}</figcaption></figure>"
        '<aside id="details" aria-live="polite"><p class="empty">Click a clip, a clip to add or a problem '
        "area, or a row of the diagnostics table, to see its details here.</p></aside></div>"
        f'<div class="toggles" id="layer-toggles">{toggles}</div></section>'
    )


def _legend() -> str:
    items = [
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
    return (
        '<ul class="legend">'
        + "".join(f'<li><i class="key {k}"></i>{escape(t)}</li>' for k, t in items)
        + "</ul>"
    )


def _placeholder_intro() -> str:
    return (
        '<p class="note">Author clips with these measurements (or accept the generated ones) and rebuild. '
        '<span class="prio necessary">necessary</span> clips fix a problem; '
        '<span class="prio suggested">suggested</span> ones extend coverage or quality.</p>'
    )


def _refused_section(doc: BlendSpaceDocument) -> str:
    """The fixes the build tried and did not keep, and why: what it refused to do to the space."""
    refused = [d for d in doc.diagnostics if d.rule in ("fix-rejected", "fix-skipped")]
    if not refused:
        return ""
    rows = "".join(
        f"<tr><td>{escape(d.rule)}</td><td>{escape(', '.join(d.clips))}</td><td>{escape(d.message)}</td></tr>"
        for d in refused
    )
    return _section(
        "refused",
        "Fixes not applied",
        "<p>The build keeps a fix only if the space gets better (fewer errors, then fewer warnings, then "
        "more coverage) and no authored key clip (on a main axis, or a corner of the covered area) is lost. "
        "These fixes were tried and left out:</p>"
        f'<table class="refused"><thead><tr><th>finding</th><th>clips</th><th>why</th></tr></thead>'
        f"<tbody>{rows}</tbody></table>",
    )


def _coverage_section(doc: BlendSpaceDocument, scene: Scene) -> str:
    x, y = doc.axes
    uncovered = [d.message for d in doc.diagnostics if d.rule == "uncovered-area"]
    note = f"<p>{escape(uncovered[0])}</p>" if uncovered else ""
    rectangle = (x.max - x.min) * (y.max - y.min)
    return _section(
        "coverage",
        "Coverage",
        f'<div class="meter" role="meter" aria-valuenow="{scene.coverage:.1f}" aria-valuemin="0" '
        f'aria-valuemax="100"><span style="width:{scene.coverage:.1f}%"></span></div>'
        f"<p>The hull of the samples covers <strong>{scene.coverage:.1f}%</strong> of the axis rectangle "
        f"{escape(x.feature)} {x.min:g}…{x.max:g} {escape(x.unit)} × {escape(y.feature)} {y.min:g}…{y.max:g} "
        f"{escape(y.unit)} ({_g(rectangle * scene.coverage / 100)} of {_g(rectangle)} "
        f"{escape(x.unit)}·{escape(y.unit)}). Outside the hull engines clamp the query to its edge, so the "
        f"character cannot reach those values.</p>{note}",
    )


def _trajectory_section(doc: BlendSpaceDocument, scene: Scene, trajectory: Trajectory) -> str:
    grid = trajectory.measured
    views = [_heat_view(doc, scene, "measured", grid, trajectory.maximum)]
    switch = ""
    if trajectory.manual is not None:
        views.append(_heat_view(doc, scene, "manual", trajectory.manual, trajectory.maximum))
        switch = (
            '<div class="toggles" id="heat-mode"><label>'
            '<input type="radio" name="heat-mode" value="measured" '
            'checked> measured placement</label><label><input type="radio" name="heat-mode" value="manual"> '
            "authors' hand placement (<code>position:</code>)</label></div>"
        )
    bar = (
        f'<div class="colour-bar"><span class="bar" style="background:{css_gradient()}"></span>'
        f'<span class="bar-labels"><span>0</span><span>{trajectory.maximum / 2:.3g}</span>'
        f'<span>≥ {trajectory.maximum:.3g}</span></span><span class="bar-title">error, % of an axis range '
        '(normalised distance); <span class="outside-key"></span> outside the hull (engines clamp)'
        "</span></div>"
    )
    return _section(
        "trajectory",
        "Trajectory error",
        '<p class="note">At each point the engine blends the clips of its triangle with weights from their '
        "placed positions; what the character then does is the same blend of what the clips really measure. "
        "The map shows how far that is from the requested point: placement only, every clip at its own "
        'speed; <a href="#engine-blend">the blend as the engine plays it</a> adds sync and playback rates.</p>'
        f'{switch}<div class="heat-wrap"><figure>{heat_map(scene, views, grid.distance.shape)}{bar}</figure>'
        f'<aside id="heat-readout" aria-live="polite">{_trajectory_stats(doc, trajectory)}'
        '<p id="heat-point" class="empty">Point at the map to read the error there.</p></aside></div>',
    )


def _engine_maps(doc: BlendSpaceDocument) -> tuple[BlendQualityDoc | None, FloatArray, FloatArray | None]:
    """The engine-played grids: the build's `blend_quality`, else (an older document, a
    hand-made one) the trajectory error computed from the document, without foot skate."""
    quality = doc.blend_quality
    if quality is None and doc.triangles:
        return None, runtime_grid(doc).distance, None
    if quality is None:
        return None, np.full((2, 2), np.nan), None

    def array(rows: list[list[float | None]]) -> FloatArray:
        return np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=np.float64)

    skate = array(quality.foot_skate) if quality.foot_skate is not None else None
    return quality, array(quality.trajectory_error), skate


def _engine_section(doc: BlendSpaceDocument, scene: Scene) -> str:
    quality, error, skate = _engine_maps(doc)
    sync = quality.sync if quality is not None else DEFAULT_SYNC
    horizon = quality.horizon if quality is not None else DEFAULT_HORIZON
    summary = quality.summary if quality is not None else {}
    finite = error[np.isfinite(error)]
    error_top = scale_maximum(float(finite.max()) if finite.size else 0.0)
    figures = [
        _engine_figure(
            doc,
            scene,
            "runtime-heat",
            "trajectory error as the engine plays it",
            error,
            error_top,
            "error, % of an axis range",
            float(finite.max()) if finite.size else 0.0,
        )
    ]
    if skate is not None:
        values = skate[np.isfinite(skate)]
        top = max(SKATE_SCALE, float(values.max()) if values.size else 0.0)
        figures.append(
            _engine_figure(
                doc,
                scene,
                "skate-heat",
                "foot-skate map",
                skate,
                top,
                "planted-foot sliding, m/s",
                float(values.max()) if values.size else 0.0,
            )
        )
    else:
        figures.append(
            '<figure id="skate-heat-figure" class="empty"><p>No foot-skate map: the build did not play the '
            "blend on the clips (rigs without recognisable feet, or a document from an older build).</p></figure>"
        )
    rows = [
        ("sync", escape(sync)),
        (
            "max trajectory error",
            f"{_g(summary.get('trajectory_error_max', float(finite.max()) if finite.size else 0.0))} %",
        ),
        (
            "mean trajectory error",
            f"{_g(summary.get('trajectory_error_mean', float(finite.mean()) if finite.size else 0.0))} %",
        ),
    ]
    if "drift_max" in summary:
        rows.append(
            (
                f"max drift after {horizon:g} s",
                f"{_g(summary['drift_max'])} m, {_g(summary.get('drift_turn_max', 0.0))}°",
            )
        )
    if "foot_skate_max" in summary:
        rows.append(
            (
                "foot skate (max / mean)",
                f"{_g(summary['foot_skate_max'])} / {_g(summary['foot_skate_mean'])} m/s",
            )
        )
    table = (
        '<table class="meta" id="engine-stats">'
        + "".join(f"<tr><th scope='row'>{k}</th><td>{v}</td></tr>" for k, v in rows)
        + "</table>"
    )
    return _section(
        "engine-blend",
        "Blend as the engine plays it",
        f"<p class=\"note\">Each point blends its triangle's clips with the engine's weights, synced "
        f"<code>{escape(sync)}</code> (clip lengths stretched to their weighted mean, as Unity blend trees and "
        "Unreal blend spaces do), each clip at its playback rate: a clip played slower moves and turns slower. "
        "Left: how far the delivered motion is from the requested point. Right: how fast the blended pose's "
        "planted feet slide.</p>"
        f'<div class="engine-maps">{"".join(figures)}</div>{table}',
    )


def _engine_figure(
    doc: BlendSpaceDocument,
    scene: Scene,
    ident: str,
    label: str,
    values: FloatArray,
    top: float,
    unit: str,
    maximum: float,
) -> str:
    axes = axis_ranges(doc)
    placed = np.asarray([s.position for s in doc.samples], dtype=np.float64).reshape(-1, 2)
    triangles = [list(t) for t in doc.triangles]
    normalised = normalise(placed, axes)
    points = _pixels(scene, normalised)
    used = np.unique(np.asarray(triangles, dtype=np.int64)).tolist()
    hull = _pixels(scene, np.asarray(convex_hull(normalised[used]))) if used else []
    edges = triangle_edges(triangles)
    view = HeatView("measured", png_data_uri(heat_rgba(values, top)), points, edges, hull)
    bar = (
        f'<div class="colour-bar"><span class="bar" style="background:{css_gradient()}"></span>'
        f'<span class="bar-labels"><span>0</span><span>{top / 2:.3g}</span><span>≥ {top:.3g}</span></span>'
        f'<span class="bar-title">{escape(unit)}</span></div>'
    )
    return (
        f'<figure id="{ident}-figure" data-max="{maximum:.6g}">'
        f"{heat_map(scene, [view], values.shape, ident=ident, label=label)}{bar}"
        f"<figcaption>{escape(label)}: max {_g(maximum)} {escape(unit.split(', ')[-1])}</figcaption></figure>"
    )


def _trajectory_stats(doc: BlendSpaceDocument, trajectory: Trajectory) -> str:
    x, y = doc.axes
    rows = []
    for label, grid in (("measured", trajectory.measured), ("by hand", trajectory.manual)):
        if grid is None:
            continue
        inside = grid.inside.any()
        ex = float(np.nanmax(grid.error_x)) if inside else 0.0
        ey = float(np.nanmax(grid.error_y)) if inside else 0.0
        rows.append(
            f"<tr><th scope='row'>{label}</th><td>{_g(grid.max_distance)}</td>"
            f"<td>{_g(grid.mean_distance)}</td>"
            f"<td>{_g(ex)} {escape(x.unit)}</td><td>{_g(ey)} {escape(y.unit)}</td></tr>"
        )
    return (
        '<table class="meta"><thead><tr><th>placement</th><th>max %</th><th>mean %</th>'
        f"<th>max {escape(x.feature)}</th><th>max {escape(y.feature)}</th></tr></thead>"
        f"{''.join(rows)}</table>"
    )


def _g(value: float) -> str:
    """Three significant digits; below 1e-9 it is rounding noise of an exact result, shown as 0."""
    return "0" if abs(value) < 1e-9 else f"{value:.3g}"


def _heat_view(
    doc: BlendSpaceDocument, scene: Scene, mode: str, grid: TrajectoryErrorGrid, top: float
) -> HeatView:
    axes = axis_ranges(doc)
    if mode == "manual":
        placed, triangles = manual_positions(doc), manual_triangles(doc)
    else:
        placed = np.asarray([s.position for s in doc.samples], dtype=np.float64).reshape(-1, 2)
        triangles = [list(t) for t in doc.triangles]
    normalised = normalise(placed, axes)
    points = _pixels(scene, normalised)
    used = np.unique(np.asarray(triangles, dtype=np.int64)).tolist()
    hull = _pixels(scene, np.asarray(convex_hull(normalised[used]))) if used else []
    edges = triangle_edges(triangles)
    arrows = []
    if mode == "manual":
        measured = _pixels(scene, normalise(measured_positions(doc), axes))
        arrows = [
            (points[i], measured[i]) for i, s in enumerate(doc.samples) if s.manual_position is not None
        ]
    return HeatView(mode, png_data_uri(heat_rgba(grid.distance, top)), points, edges, hull, arrows)


def _pixels(scene: Scene, normalised: np.ndarray[Any, Any]) -> list[tuple[float, float]]:
    if len(normalised) == 0:
        return []
    return [(float(x), float(y)) for x, y in scene.layout.project(normalised)]


def _data(doc: BlendSpaceDocument, scene: Scene, trajectory: Trajectory) -> dict[str, Any]:
    """What the script needs, once: details for the side panel and the error grids for hover."""
    involved: list[list[int]] = [[] for _ in doc.samples]
    index = {s.name: i for i, s in enumerate(doc.samples)}
    for i, d in enumerate(doc.diagnostics):
        for name in d.clips:
            if name in index:
                involved[index[name]].append(i)
    lay = scene.layout
    return {
        "axes": [{"feature": a.feature, "unit": a.unit, "min": a.min, "max": a.max} for a in doc.axes],
        "samples": [
            _without_empty(
                {
                    "name": s.name,
                    "source": s.source,
                    "generated": s.generated,
                    "fix": s.fix,
                    "features": {k: _finite(v) for k, v in s.features.items()},
                    "position": _finites(s.position),
                    "snap": _finites(s.snapping_error),
                    "manual": _finites(s.manual_position),
                    "diagnostics": involved[i],
                    "clip": _clip_facts(s.clip),
                    "contacts": s.contacts,
                }
            )
            for i, s in enumerate(doc.samples)
        ],
        "diagnostics": [
            {
                "rule": d.rule,
                "code": d.code,
                "severity": d.severity,
                "message": d.message,
                "hint": d.hint,
                "fix": d.fix,
                "clips": d.clips,
                "position": _finites(d.position),
                "where": _where(d),
            }
            for d in doc.diagnostics
        ],
        "placeholders": [
            {
                "position": _finites(p.position),
                "priority": p.priority,
                "rule": p.rule,
                "reason": p.reason,
                "features": {k: _finite(v) for k, v in p.features.items()},
            }
            for p in doc.placeholders
        ],
        "heat": {
            "max": trajectory.maximum,
            "box": [lay.left, lay.top, lay.left + lay.plot_width, lay.top + lay.plot_height],
            "nx": int(trajectory.measured.xs.size),
            "ny": int(trajectory.measured.ys.size),
            "measured": _grid_data(trajectory.measured),
            "manual": _grid_data(trajectory.manual) if trajectory.manual is not None else None,
        },
    }


def _without_empty(entry: dict[str, Any]) -> dict[str, Any]:
    """Leave out null, false and empty values: the script reads a missing key the same way."""
    return {
        k: v for k, v in entry.items() if not (v is None or v is False or (type(v) in (list, dict) and not v))
    }


def _finite(value: float) -> float | None:
    """NaN and infinities as null: JSON has neither. Values keep full precision so that the
    script's tables format them exactly as the Python-rendered first page does."""
    return value if math.isfinite(value) else None


def _finites(values: Sequence[float] | None) -> list[float | None] | None:
    return None if values is None else [_finite(v) for v in values]


def _where(diagnostic: DiagnosticDoc) -> str | None:
    location = diagnostic.location
    if location is None:
        return None
    return f"{location.path}:{location.line}" if location.line else location.path


def _clip_facts(info: ClipInfoDoc | None) -> dict[str, Any] | None:
    """What the clip table shows of a clip beyond its features (short keys: one per clip)."""
    if info is None:
        return None
    return _without_empty(
        {
            "duration": info.duration,
            "fps": info.fps,
            "frames": info.frames,
            "mpu": info.meters_per_unit,
            "units": info.units_source,
            "up": info.up_axis,
            "root": info.root,
            "facing": info.facing,
            "range": info.range,
            "auto": info.range_auto,
            "guesses": info.guesses,
            "notes": info.notes,
            "phases": info.plant_phases,
        }
    )


def _grid_data(grid: TrajectoryErrorGrid) -> dict[str, Any]:
    """Per-axis errors, row-major from the axis minimum; null outside the hull. Three digits are
    plenty for a hover readout and halve the size of the grids."""

    def short(values: FloatArray) -> list[float | None]:
        return [
            None if math.isnan(v) else (0.0 if abs(v) < 1e-9 else float(f"{v:.3g}")) for v in values.ravel()
        ]

    return {"ex": short(grid.error_x), "ey": short(grid.error_y)}


def _script_json(data: dict[str, Any]) -> str:
    """JSON safe inside <script>: no `</script>` or `<!--` can appear in a string."""
    try:
        text = json.dumps(data, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    except ValueError:  # a NaN or infinity the gathering did not expect: null, as JSON allows
        text = json.dumps(_finite_all(data), separators=(",", ":"), ensure_ascii=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _finite_all(value: Any) -> Any:
    """NaN and infinities as null, recursively (the slow path of `_script_json`)."""
    if isinstance(value, float):
        return _finite(value)
    if isinstance(value, dict):
        return {k: _finite_all(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_all(v) for v in value]
    return value
