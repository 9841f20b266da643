"""The report's tables: diagnostics, placeholders, clips and build metadata (escaped HTML)."""

from __future__ import annotations

import json
from html import escape
from typing import Any

from blendspace_pipeline.features import FEATURE_UNITS as UNITS
from blendspace_pipeline.space.document import BlendSpaceDocument, SampleDoc

SEVERITIES = ("error", "warning", "info")
# Axis features first, then the rest of spec.md's features in its order, then anything else.
FEATURE_ORDER = (
    "speed",
    "turn_rate",
    "direction",
    "turn",
    "forward_speed",
    "lateral_speed",
    "displacement_speed",
    "duration",
)


def e(value: object) -> str:
    return escape(str(value), quote=True)


def num(value: float | None, digits: int = 4) -> str:
    if value is None:
        return "–"
    return f"{value:.{digits}g}"


def pair(values: list[float] | None, digits: int = 4) -> str:
    return "–" if values is None else "(" + ", ".join(num(v, digits) for v in values) + ")"


def _clip_list(names: list[str]) -> str:
    return " ".join(f'<span class="clip-ref">{e(n)}</span>' for n in names) or "–"


PAGE_SIZE = 50  # rows per page of a long table: the browser holds only one page in the DOM


def diagnostic_rows(doc: BlendSpaceDocument, limit: int | None = None) -> list[str]:
    """Rows of the diagnostics table (the first ``limit``); `report.js` `diagnosticRow` mirrors it."""
    rows = []
    for i, d in enumerate(doc.diagnostics[:limit]):
        where = ""
        if d.location is not None:
            where = f"{d.location.path}:{d.location.line}" if d.location.line else d.location.path
        rows.append(
            f'<tr data-diagnostic="{i}" data-severity="{e(d.severity)}" data-rule="{e(d.rule)}" tabindex="0">'
            f'<td><span class="sev sev-{e(d.severity)}">{e(d.severity)}</span></td>'
            f"<td><code>{e(d.rule)}</code><br><small>{e(d.code)}</small></td><td>{_clip_list(d.clips)}</td>"
            f"<td>{e(d.message)}{_fix_note(d.fix)}</td><td>{e(d.hint or '')}"
            f"{f'<br><small>{e(where)}</small>' if where else ''}</td></tr>"
        )
    return rows


def diagnostics_table(doc: BlendSpaceDocument, rows: list[str]) -> str:
    """The table with its first page, ``rows``; the script pages through the rest."""
    if not doc.diagnostics:
        return '<p class="empty">No diagnostics: every rule passed.</p>'
    return (
        pager("diagnostics-table", len(doc.diagnostics), "find a clip, rule or message")
        + '<table id="diagnostics-table"><thead><tr><th>severity</th><th>rule</th><th>clips</th>'
        "<th>message</th>"
        f"<th>hint</th></tr></thead><tbody>{''.join(rows[:PAGE_SIZE])}</tbody></table>"
    )


def pager(table: str, total: int, placeholder: str) -> str:
    """Filter box and page buttons of a long table (wired by the report's script)."""
    shown = min(total, PAGE_SIZE)
    return (
        f'<div class="pager" data-for="{table}"><input type="search" placeholder="{e(placeholder)}" '
        f'aria-label="filter the rows"><button type="button" data-step="-1" disabled>‹ previous</button>'
        f'<span class="page-info">{"1–" + str(shown) if shown else "0"} of {total}</span>'
        f'<button type="button" data-step="1"{" disabled" if total <= PAGE_SIZE else ""}>next ›</button></div>'
    )


def _fix_note(fix: str | None) -> str:
    return f' <span class="fix">fix: {e(fix)}</span>' if fix else ""


def diagnostic_filters(doc: BlendSpaceDocument) -> str:
    counts = {s: sum(d.severity == s for d in doc.diagnostics) for s in SEVERITIES}
    boxes = "".join(
        f'<label><input type="checkbox" name="severity" value="{s}" checked> '
        f'<span class="sev sev-{s}">{s}</span> {counts[s]}</label>'
        for s in SEVERITIES
    )
    rules = sorted({d.rule for d in doc.diagnostics})
    options = "".join(f'<option value="{e(r)}">{e(r)}</option>' for r in rules)
    return (
        f'<div class="filters" id="diagnostic-filters">{boxes}<label>rule <select name="rule">'
        f'<option value="">all rules</option>{options}</select></label>'
        '<span id="diagnostic-count"></span></div>'
    )


def placeholder_rows(doc: BlendSpaceDocument, limit: int | None = None) -> list[str]:
    """Rows of the placeholders table; `report.js` `placeholderRow` mirrors it."""
    x, y = doc.axes
    return [
        f'<tr data-placeholder-row="{i}"><td><span class="prio {p.priority}">{p.priority}</span></td>'
        f"<td>{num(p.position[0])} {e(x.unit)}, {num(p.position[1])} {e(y.unit)}</td>"
        f"<td>{_features_text(p.features)}</td><td><code>{e(p.rule)}</code></td><td>{e(p.reason)}</td></tr>"
        for i, p in enumerate(doc.placeholders[:limit])
    ]


def placeholders_table(doc: BlendSpaceDocument, rows: list[str]) -> str:
    if not doc.placeholders:
        return '<p class="empty">No clips to add.</p>'
    return (
        pager("placeholders-table", len(doc.placeholders), "find a rule or reason")
        + '<table id="placeholders-table"><thead><tr><th>priority</th><th>position</th><th>clip to author</th>'
        f"<th>rule</th><th>why</th></tr></thead><tbody>{''.join(rows[:PAGE_SIZE])}</tbody></table>"
    )


def _features_text(features: dict[str, float]) -> str:
    return ", ".join(f"{e(k)} {num(v)} {e(UNITS.get(k, ''))}" for k, v in features.items()) or "–"


def feature_columns(doc: BlendSpaceDocument) -> list[str]:
    names = {k for s in doc.samples for k in s.features}
    axis_first = [a.feature for a in doc.axes]
    ordered = [*axis_first, *(f for f in FEATURE_ORDER if f not in axis_first)]
    return [f for f in ordered if f in names] + sorted(names - set(ordered))


def clip_rows(doc: BlendSpaceDocument, limit: int | None = None) -> list[str]:
    """Rows of the clips table; `report.js` `clipRow` mirrors it."""
    features = feature_columns(doc)
    return [_clip_row(i, s, features) for i, s in enumerate(doc.samples[:limit])]


def clips_table(doc: BlendSpaceDocument, rows: list[str]) -> str:
    features = feature_columns(doc)
    heads = "".join(f"<th>{e(f)}<br><small>{e(UNITS.get(f, ''))}</small></th>" for f in features)
    return (
        pager("clips-table", len(doc.samples), "find a clip by name or file")
        + '<div class="scroll"><table id="clips-table"><thead><tr><th>clip</th><th>position</th>'
        f"<th>snapping error</th><th>by hand</th>{heads}<th>fps</th><th>frames</th><th>units</th>"
        f"<th>skeleton</th><th>foot contacts<br><small>L / R over the clip</small></th><th>notes</th>"
        f"</tr></thead><tbody>{''.join(rows[:PAGE_SIZE])}</tbody></table></div>"
    )


def contacts_strip(sample: SampleDoc) -> str:
    """The clip's foot contacts as two bars over its duration (left above, right below), with
    the stride phase each foot plants at."""
    duration = sample.features.get("duration", 0.0)
    if sample.contacts is None or duration <= 0.0:
        return "–"
    width, row = 120.0, 8.0
    bars = []
    for lane, foot in enumerate(("left", "right")):
        for start, end in sample.contacts.get(foot, []):
            x0, x1 = start / duration * width, end / duration * width
            bars.append(
                f'<rect class="contact {foot}" x="{x0:.1f}" y="{lane * (row + 2):.1f}" '
                f'width="{max(x1 - x0, 0.5):.1f}" height="{row:.0f}"><title>{foot} foot down '
                f"{start:.2f}–{end:.2f} s</title></rect>"
            )
    phases = sample.clip.plant_phases if sample.clip is not None else None
    label = (
        f"<br><small>plants at phase L {phases['left']:.2f}, R {phases['right']:.2f}</small>"
        if phases
        else ""
    )
    return (
        f'<svg class="contacts-strip" width="{width:.0f}" height="{2 * row + 2:.0f}" role="img" '
        f'aria-label="foot contacts of {e(sample.name)}">{"".join(bars)}</svg>{label}'
    )


def _clip_row(index: int, sample: SampleDoc, features: list[str]) -> str:
    kind = (
        f'<br><span class="tag generated">generated: {e(sample.fix or "fix")}</span>'
        if sample.generated
        else ""
    )
    cells = "".join(f"<td>{num(sample.features.get(f))}</td>" for f in features)
    info = sample.clip
    if info is None:
        facts = f"<td>–</td><td>–</td><td>–</td><td>–</td><td>{contacts_strip(sample)}</td><td>–</td>"
    else:
        trim = (
            f"<br>range {pair(info.range)} s" + (" (auto)" if info.range_auto else "") if info.range else ""
        )
        trim += "".join(f'<br><span class="tag guess">{e(g)}</span>' for g in info.guesses)
        facts = (
            f"<td>{num(info.fps)}</td><td>{info.frames}</td>"
            f"<td>{num(info.meters_per_unit)} m/unit<br><small>{e(info.units_source)}</small></td>"
            f"<td>up {e(info.up_axis)}<br>root {e(info.root)}<br>facing {e(info.facing)}{trim}</td>"
            f"<td>{contacts_strip(sample)}</td>"
            f"<td>{'<br>'.join(e(n) for n in info.notes) or '–'}</td>"
        )
    return (
        f'<tr data-clip-row="{index}"><th scope="row">{e(sample.name)}{kind}'
        f"<br><small>{e(sample.source)}</small></th>"
        f"<td>{pair(sample.position)}</td><td>{pair(sample.snapping_error, 3)}</td>"
        f"<td>{pair(sample.manual_position)}</td>{cells}{facts}</tr>"
    )


def build_table(doc: BlendSpaceDocument, written_at: str) -> str:
    x, y = doc.axes
    rows: list[tuple[str, str]] = [("blend space", e(doc.name)), ("dated", e(written_at))]
    for axis in (x, y):
        rows.append(
            (
                f"axis {axis.name}",
                f"{e(axis.feature)} {num(axis.min)}…{num(axis.max)} {e(axis.unit)}, "
                f"{axis.divisions} divisions "
                f"(step {num((axis.max - axis.min) / axis.divisions)})",
            )
        )
    if doc.build is not None:
        b = doc.build
        rows += [("tool version", e(b.tool_version)), ("manifest", f"<code>{e(b.manifest)}</code>")]
        rows.append(("thresholds", ", ".join(f"{e(k)} {num(v)}" for k, v in b.thresholds.items()) or "–"))
        rows += [(f"setting: {e(k)}", f"<code>{e(_json(v))}</code>") for k, v in b.settings.items()]
    body = "".join(f"<tr><th scope='row'>{k}</th><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="meta">{body}</table>'


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)
