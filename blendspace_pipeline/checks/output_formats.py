"""Printing diagnostics for people and machines: text, json, sarif (2.1.0) and github."""

from __future__ import annotations

import json
import ntpath
import posixpath
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath, PurePosixPath, PureWindowsPath
from urllib.parse import quote

from blendspace_pipeline import __version__
from blendspace_pipeline.diagnostics import Diagnostic, Severity
from blendspace_pipeline.errors import printable, printable_hint

FORMATS = ("text", "json", "sarif", "github")
_SARIF_LEVEL = {"error": "error", "warning": "warning", "info": "note"}
# SARIF resolves relative artifact URIs against this base; code scanning maps it to the checkout.
SRCROOT = "%SRCROOT%"
_WINDOWS_DRIVE = re.compile(r"^[A-Za-z]:[\\/]|^[\\/]{2}[^\\/]")  # C:\… or \\server\share


@dataclass(frozen=True)
class RuleInfo:
    """What SARIF's `tool.driver.rules[]` says about a rule, whoever reported through it."""

    code: str
    summary: str  # one line
    doc: str  # the full explanation (a rule's docstring)
    severity: Severity  # the default, before a manifest's `rules.severity` overrides


def _where(d: Diagnostic) -> str:
    if d.path is None:
        return "blendspace"
    return f"{d.path}:{d.line or 1}:{d.column or 1}"


def as_text(diagnostics: Sequence[Diagnostic], summary: str = "") -> str:
    """One line per finding (and an indented hint): control characters in a clip name, a path or a
    plugin's message are escaped, so no finding can forge a line of its own (`::error ...`)."""
    lines = []
    for d in diagnostics:
        lines.append(printable(f"{_where(d)}: {d.severity} {d.rule}: {d.message}"))
        if d.hint:
            lines.append(f"    hint: {printable_hint(d.hint, '          ')}")
    counts = {s: sum(1 for d in diagnostics if d.severity == s) for s in ("error", "warning", "info")}
    tally = ", ".join(f"{n} {s}{'s' if n != 1 else ''}" for s, n in counts.items())
    # A build's summary ends with a newline on purpose (a line of its own before the tally).
    head = printable(summary.removesuffix("\n")) + ("\n" if summary.endswith("\n") else "")
    lines.append(f"{head}{tally}" if summary else tally)
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


def _directory_uri(root: PurePath) -> str:
    """`file:///abs/root/`: a base URI must end with `/` or its last segment is dropped on resolve."""
    uri = root.as_uri()
    return uri if uri.endswith("/") else uri + "/"


def artifact_location(path: str, root: PurePath) -> dict[str, str]:
    """A SARIF `artifactLocation` for ``path``: relative to ``root`` (%SRCROOT%) when under it,
    else an absolute `file:///` URI; percent-encoded either way, with forward slashes.

    Windows paths (a drive or a UNC share) are recognised on any OS, so a log made from
    Windows paths stays valid wherever it is written.
    """
    windows = isinstance(root, PureWindowsPath) or bool(_WINDOWS_DRIVE.match(path))
    flavour = ntpath if windows else posixpath
    absolute = flavour.normpath(flavour.join(str(root), path))
    try:
        relative = flavour.relpath(absolute, str(root))
    except ValueError:  # another drive than root's
        relative = flavour.pardir
    if relative != flavour.pardir and not relative.startswith(flavour.pardir + flavour.sep):
        # Relative references encode `:` too, or a first segment like `c:` would read as a scheme.
        segments = relative.replace(flavour.sep, "/") if windows else relative
        return {"uri": quote(segments, safe="/", errors="surrogateescape"), "uriBaseId": SRCROOT}
    pure: PurePath = PureWindowsPath(absolute) if windows else PurePosixPath(absolute)
    return {"uri": pure.as_uri()}


def _sarif_rule(slug: str, info: RuleInfo) -> dict[str, object]:
    return {
        "id": slug,
        "name": slug,
        "shortDescription": {"text": info.summary},
        "fullDescription": {"text": info.doc},
        "help": {"text": info.doc},
        "defaultConfiguration": {"level": _SARIF_LEVEL[info.severity]},
        "properties": {"code": info.code},
    }


def as_sarif(
    diagnostics: Sequence[Diagnostic],
    rules: Mapping[str, RuleInfo] | None = None,
    root: PurePath | None = None,
) -> str:
    """SARIF 2.1.0: one result per diagnostic, anchored at the manifest line.

    ``rules`` describes the rules for `tool.driver.rules[]`; a slug it lacks is described from
    its first diagnostic. ``root`` (default: the working directory) is what %SRCROOT% means.
    """
    base = root if root is not None else Path.cwd()
    known = dict(rules or {})
    for d in diagnostics:
        known.setdefault(d.rule, RuleInfo(d.code, d.message.split("\n", 1)[0], d.message, d.severity))
    rule_ids = sorted(known)
    index = {slug: i for i, slug in enumerate(rule_ids)}
    results = []
    uses_root = False
    for d in diagnostics:
        result: dict[str, object] = {
            "ruleId": d.rule,
            "ruleIndex": index[d.rule],
            "level": _SARIF_LEVEL[d.severity],
            "message": {"text": d.message + (f"\nhint: {d.hint}" if d.hint else "")},
            "properties": {"code": d.code, "clips": list(d.clips)},
        }
        if d.path:
            where = artifact_location(d.path, base)
            uses_root = uses_root or "uriBaseId" in where
            physical: dict[str, object] = {"artifactLocation": where}
            if d.line is not None:  # SARIF lines start at 1; an unknown line has no region at all
                region: dict[str, int] = {"startLine": d.line}
                if d.column is not None:
                    region["startColumn"] = d.column
                physical["region"] = region
            result["locations"] = [{"physicalLocation": physical}]
        results.append(result)
    run: dict[str, object] = {
        "tool": {
            "driver": {
                "name": "blendspace-pipeline",
                "version": __version__,
                "rules": [_sarif_rule(slug, known[slug]) for slug in rule_ids],
            }
        },
        "results": results,
    }
    if uses_root:
        run["originalUriBaseIds"] = {SRCROOT: {"uri": _directory_uri(base)}}
    document = {
        "$schema": "https://json.schemastore.org/sarif-2.1.0.json",
        "version": "2.1.0",
        "runs": [run],
    }
    return json.dumps(document, indent=2) + "\n"


def _escape_github(text: str) -> str:
    # %0A is GitHub's own line break inside an annotation; other control characters (ESC, U+2028)
    # are shown escaped, as in text output.
    return printable(text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A"))


def _escape_github_property(text: str) -> str:
    """Property values also escape `:` and `,`, which separate the command's parts (actions/toolkit)."""
    return _escape_github(text).replace(":", "%3A").replace(",", "%2C")


def as_github(diagnostics: Sequence[Diagnostic]) -> str:
    """GitHub Actions workflow commands (`::error file=…,line=…::message`)."""
    kinds = {"error": "error", "warning": "warning", "info": "notice"}
    lines = []
    for d in diagnostics:
        props: list[tuple[str, str]] = []
        if d.path:
            props.append(("file", d.path))
            # Without a known line the annotation goes on the whole file, not on a made-up line 1.
            if d.line is not None:
                props.append(("line", str(d.line)))
                if d.column is not None:
                    props.append(("col", str(d.column)))
        props.append(("title", d.rule))
        # Every value goes through the property escape: a path may hold `,` or `:`.
        rendered = ",".join(f"{key}={_escape_github_property(value)}" for key, value in props)
        message = d.message + (f"\nhint: {d.hint}" if d.hint else "")
        lines.append(f"::{kinds[d.severity]} {rendered}::{_escape_github(message)}")
    return "\n".join(lines) + ("\n" if lines else "")


def render(
    fmt: str,
    diagnostics: Sequence[Diagnostic],
    *,
    summary: str = "",
    extra: dict[str, object] | None = None,
    rules: Mapping[str, RuleInfo] | None = None,
) -> str:
    if fmt == "json":
        return as_json(diagnostics, extra)
    if fmt == "sarif":
        return as_sarif(diagnostics, rules)
    if fmt == "github":
        return as_github(diagnostics)
    return as_text(diagnostics, summary)
