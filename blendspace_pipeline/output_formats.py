"""Printing diagnostics for people and machines: text, json, sarif (2.1.0) and github."""

from __future__ import annotations

import json
from collections.abc import Sequence

from blendspace_pipeline import __version__
from blendspace_pipeline.diagnostics import Diagnostic

FORMATS = ("text", "json", "sarif", "github")
_SARIF_LEVEL = {"error": "error", "warning": "warning", "info": "note"}


def _where(d: Diagnostic) -> str:
    if d.path is None:
        return "blendspace"
    return f"{d.path}:{d.line or 1}:{d.column or 1}"


def as_text(diagnostics: Sequence[Diagnostic], summary: str = "") -> str:
    lines = []
    for d in diagnostics:
        lines.append(f"{_where(d)}: {d.severity} {d.rule}: {d.message}")
        if d.hint:
            lines.append(f"    hint: {d.hint}")
    counts = {s: sum(1 for d in diagnostics if d.severity == s) for s in ("error", "warning", "info")}
    tally = ", ".join(f"{n} {s}{'s' if n != 1 else ''}" for s, n in counts.items())
    lines.append(f"{summary}{tally}" if summary else tally)
    return "\n".join(lines) + "\n"


def _as_dict(d: Diagnostic) -> dict[str, object]:
    return {
        "rule": d.rule,
        "code": d.code,
        "severity": d.severity,
        "message": d.message,
        "hint": d.hint,
        "clips": list(d.clips),
        "position": list(d.position) if d.position is not None else None,
        "fix": d.fix,
        "location": {"path": d.path, "line": d.line, "column": d.column} if d.path else None,
    }


def as_json(diagnostics: Sequence[Diagnostic], extra: dict[str, object] | None = None) -> str:
    payload: dict[str, object] = {"diagnostics": [_as_dict(d) for d in diagnostics]}
    payload.update(extra or {})
    return json.dumps(payload, indent=2) + "\n"


def as_sarif(diagnostics: Sequence[Diagnostic], rules: dict[str, tuple[str, str]] | None = None) -> str:
    """SARIF 2.1.0: one result per diagnostic, anchored at the manifest line."""
    known = dict(rules or {})
    for d in diagnostics:
        known.setdefault(d.rule, (d.code, d.rule))
    rule_ids = sorted(known)
    results = []
    for d in diagnostics:
        result: dict[str, object] = {
            "ruleId": d.rule,
            "ruleIndex": rule_ids.index(d.rule),
            "level": _SARIF_LEVEL[d.severity],
            "message": {"text": d.message + (f"\nhint: {d.hint}" if d.hint else "")},
            "properties": {"code": d.code, "clips": list(d.clips)},
        }
        if d.path:
            result["locations"] = [
                {
                    "physicalLocation": {
                        "artifactLocation": {"uri": d.path.replace("\\", "/")},
                        "region": {"startLine": d.line or 1, "startColumn": d.column or 1},
                    }
                }
            ]
        results.append(result)
    document = {
        "$schema": "https://json.schemastore.org/sarif-2.1.0.json",
        "version": "2.1.0",
        "runs": [
            {
                "tool": {
                    "driver": {
                        "name": "blendspace-pipeline",
                        "version": __version__,
                        "rules": [
                            {
                                "id": slug,
                                "name": slug,
                                "properties": {"code": known[slug][0]},
                                "shortDescription": {"text": known[slug][1]},
                            }
                            for slug in rule_ids
                        ],
                    }
                },
                "results": results,
            }
        ],
    }
    return json.dumps(document, indent=2) + "\n"


def _escape_github(text: str) -> str:
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _escape_github_property(text: str) -> str:
    """Property values also escape `:` and `,`, which separate the command's parts (actions/toolkit)."""
    return _escape_github(text).replace(":", "%3A").replace(",", "%2C")


def as_github(diagnostics: Sequence[Diagnostic]) -> str:
    """GitHub Actions workflow commands (`::error file=…,line=…::message`)."""
    kinds = {"error": "error", "warning": "warning", "info": "notice"}
    lines = []
    for d in diagnostics:
        props = [f"title={_escape_github_property(d.rule)}"]
        if d.path:
            path = _escape_github_property(d.path)
            props = [f"file={path}", f"line={d.line or 1}", f"col={d.column or 1}", *props]
        message = d.message + (f"\nhint: {d.hint}" if d.hint else "")
        lines.append(f"::{kinds[d.severity]} {','.join(props)}::{_escape_github(message)}")
    return "\n".join(lines) + ("\n" if lines else "")


def render(
    fmt: str,
    diagnostics: Sequence[Diagnostic],
    *,
    summary: str = "",
    extra: dict[str, object] | None = None,
    rules: dict[str, tuple[str, str]] | None = None,
) -> str:
    if fmt == "json":
        return as_json(diagnostics, extra)
    if fmt == "sarif":
        return as_sarif(diagnostics, rules)
    if fmt == "github":
        return as_github(diagnostics)
    return as_text(diagnostics, summary)
