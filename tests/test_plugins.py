"""Studio rules load through one loader from every source, and every way of failing is visible.

Each test writes a small project (procedural clips as USD, a manifest, rule modules) into
``tmp_path`` and runs the real command line (`blendspace_pipeline.cli.main`), so what is tested
is what a user or CI sees: the JSON diagnostics, their manifest lines and the exit code. The
last tests run the examples of CONTRIBUTING.md ("Writing a rule") so the docs cannot rot.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
import tomllib
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import tidy_set

from blendspace_pipeline.checks.rule_engine import ENGINE_CODES, ENTRY_POINT_GROUP, RULE_PATH_VARIABLE
from blendspace_pipeline.cli import build_parser, main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip

REPO = Path(__file__).resolve().parents[1]

# A set without error-severity findings: idle, straight and turning walks, turns in place, a
# backward walk, and a run that drifts 5 deg/s left (one misalignment warning).
SPECS = {**tidy_set(), "run_drift": GaitSpec("run_drift", speed=3.0, turn_rate=5.0, duration=1.0)}
ENGINE_SLUGS = set(ENGINE_CODES)


def write_project(root: Path, extra: str = "", entries: dict[str, str] | None = None) -> Path:
    """Clips of ``SPECS`` under root/clips and a manifest listing each; returns the manifest.

    ``entries`` adds YAML lines (indented under the clip's entry) per clip name; ``extra`` is
    appended at the top level of the manifest.
    """
    (root / "clips").mkdir(parents=True, exist_ok=True)
    lines = ["schema_version: 1", "name: plugtest", "clips:"]
    for name, spec in SPECS.items():
        path = root / "clips" / f"{name}.usda"
        write_usd_clip(generate(spec, source=path), path, meters_per_unit=1.0, up_axis="y")
        lines.append(f"  - path: clips/{name}.usda")
        for extra_line in (entries or {}).get(name, "").splitlines():
            lines.append(f"    {extra_line}")
    manifest = root / "manifest.yaml"
    manifest.write_text("\n".join(lines) + "\n" + textwrap.dedent(extra), encoding="utf-8")
    return manifest


def rule_module(
    slug: str, code: str, *, clip: str = "walk_fwd", severity: str = "warning", body: str = ""
) -> str:
    """Source of a rule module whose rule flags ``clip`` (plus any extra ``body`` code)."""
    class_name = "Rule_" + re.sub(r"\W", "_", slug)
    return textwrap.dedent(
        f'''
        from blendspace_pipeline.api import Rule, SpaceView


        class {class_name}(Rule):
            """Flags one named clip, so a test can see the rule ran."""

            slug = "{slug}"
            code = "{code}"
            severity = "{severity}"
            summary = "test rule {slug}"

            def check(self, space: SpaceView):
                for sample in space.samples:
                    if sample.name == "{clip}":
                        yield self.report(f"{{sample.name}} flagged by {slug}", clips=[sample.name],
                                          position=sample.position, hint="a test hint")
        '''
    ) + textwrap.dedent(body)


def check(manifest: Path, capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, list[dict[str, Any]]]:
    """Run `blendspace check MANIFEST --format json` in-process: exit code and diagnostics."""
    code = main(["check", str(manifest), "--format", "json", *args])
    out = capsys.readouterr().out
    return code, json.loads(out)["diagnostics"]


def line_of(manifest: Path, needle: str) -> int:
    """1-based line of the first manifest line containing ``needle``."""
    for number, text in enumerate(manifest.read_text(encoding="utf-8").splitlines(), start=1):
        if needle in text:
            return number
    raise AssertionError(f"{needle!r} not in {manifest}")


def by_rule(diagnostics: list[dict[str, Any]], rule: str) -> list[dict[str, Any]]:
    return [d for d in diagnostics if d["rule"] == rule]


def unique(stem: str) -> str:
    """A module name no other test (or earlier import) has used: sys.modules caches imports."""
    return f"{stem}_{uuid.uuid4().hex[:10]}"


@pytest.fixture
def forget_modules() -> Iterator[None]:
    """Drop modules a test imported by name, so they do not leak into later tests."""
    before = set(sys.modules)
    yield
    for name in set(sys.modules) - before:
        if name.startswith(("studio_", "acme_")):
            del sys.modules[name]


# -- where rules come from ----------------------------------------------------------------------


def test_plugin_path_relative_to_the_manifest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "house").mkdir()
    (tmp_path / "house" / "house_rules.py").write_text(rule_module("studio-path", "ST101"), encoding="utf-8")
    manifest = write_project(tmp_path, "plugins: [house/house_rules.py]\n")
    code, found = check(manifest, capsys)
    [finding] = by_rule(found, "studio-path")
    assert finding["code"] == "ST101" and finding["clips"] == ["walk_fwd"]
    assert finding["location"]["line"] == line_of(manifest, "clips/walk_fwd.usda")
    assert not [d for d in found if d["rule"] in ENGINE_SLUGS]
    assert code == 0  # warnings only
    # Relative to the manifest, not to the working directory: from another folder, with a relative
    # manifest path, the plugin still loads.
    monkeypatch.chdir(tmp_path / "house")
    assert main(["check", "../manifest.yaml", "--format", "json"]) == 0
    again = json.loads(capsys.readouterr().out)["diagnostics"]
    assert [d["code"] for d in by_rule(again, "studio-path")] == ["ST101"]
    assert not by_rule(again, "plugin-error")


def test_plugin_as_an_importable_module(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, forget_modules: None
) -> None:
    modules = tmp_path / "site"
    modules.mkdir()
    name = unique("studio_mod")
    (modules / f"{name}.py").write_text(
        rule_module("studio-module", "ST102", clip="walk_bwd"), encoding="utf-8"
    )
    monkeypatch.syspath_prepend(str(modules))
    manifest = write_project(tmp_path / "project", f"plugins: [{name}]\n")
    code, found = check(manifest, capsys)
    [finding] = by_rule(found, "studio-module")
    assert finding["clips"] == ["walk_bwd"] and code == 0
    assert finding["location"]["line"] == line_of(manifest, "clips/walk_bwd.usda")


def test_rule_path_directories(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    first, second = tmp_path / "team_a", tmp_path / "team b"  # a space in a folder name is fine
    first.mkdir()
    second.mkdir()
    (first / "rules_a.py").write_text(
        rule_module("studio-team-a", "ST103", clip="walk_left"), encoding="utf-8"
    )
    (second / "rules_b.py").write_text(
        rule_module("studio-team-b", "ST104", clip="walk_right"), encoding="utf-8"
    )
    (second / "notes.txt").write_text("not a rule module", encoding="utf-8")
    monkeypatch.setenv(RULE_PATH_VARIABLE, f"{first}{os.pathsep}{second}")
    manifest = write_project(tmp_path / "project")
    code, found = check(manifest, capsys)
    assert [d["clips"] for d in by_rule(found, "studio-team-a")] == [["walk_left"]]
    assert [d["clips"] for d in by_rule(found, "studio-team-b")] == [["walk_right"]]
    assert code == 0
    # `blendspace rules` lists them with where they came from.
    assert main(["rules", "--format", "json"]) == 0
    rows = {row["slug"]: row for row in json.loads(capsys.readouterr().out)["rules"]}
    assert rows["studio-team-a"]["code"] == "ST103"
    assert str(second / "rules_b.py") in rows["studio-team-b"]["origin"]


def test_missing_rule_path_directory_is_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(RULE_PATH_VARIABLE, str(tmp_path / "nowhere"))
    manifest = write_project(tmp_path / "project")
    code, found = check(manifest, capsys)
    [problem] = by_rule(found, "plugin-error")
    assert problem["code"] == "BS900" and "nowhere" in problem["message"] and code == 1


def _dist_info(site: Path, entry_points: str) -> None:
    """An installed distribution as importlib.metadata sees it: a .dist-info folder on sys.path."""
    info = site / "studio_rules-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: studio_rules\nVersion: 0.1\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(entry_points, encoding="utf-8")


def test_entry_points_name_a_module_or_a_rule_class(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, forget_modules: None
) -> None:
    site = tmp_path / "site"
    site.mkdir()
    whole, single = unique("studio_ep_module"), unique("studio_ep_class")
    (site / f"{whole}.py").write_text(
        rule_module("studio-ep-module", "ST105", clip="tip_left"), encoding="utf-8"
    )
    # The second module defines two rules; the entry point picks one class, the other is not loaded.
    (site / f"{single}.py").write_text(
        rule_module("studio-ep-class", "ST106", clip="tip_right")
        + rule_module("studio-ep-unlisted", "ST107", clip="idle"),
        encoding="utf-8",
    )
    _dist_info(
        site,
        f"[{ENTRY_POINT_GROUP}]\nhouse = {whole}\none = {single}:Rule_studio_ep_class\n"
        "[console_scripts]\nunrelated = os:getcwd\n",
    )
    monkeypatch.syspath_prepend(str(site))
    manifest = write_project(tmp_path / "project")
    code, found = check(manifest, capsys)
    assert [d["clips"] for d in by_rule(found, "studio-ep-module")] == [["tip_left"]]
    assert [d["clips"] for d in by_rule(found, "studio-ep-class")] == [["tip_right"]]
    assert by_rule(found, "studio-ep-unlisted") == []
    assert not [d for d in found if d["rule"] in ENGINE_SLUGS] and code == 0
    assert main(["rules", "--format", "json"]) == 0
    rows = {row["slug"]: row for row in json.loads(capsys.readouterr().out)["rules"]}
    assert rows["studio-ep-module"]["origin"] == f"entry point house = {whole}"
    assert rows["studio-ep-class"]["origin"] == f"entry point one = {single}:Rule_studio_ep_class"


def test_broken_entry_points_are_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, forget_modules: None
) -> None:
    site = tmp_path / "site"
    site.mkdir()
    broken, plain = unique("studio_ep_broken"), unique("studio_ep_plain")
    (site / f"{broken}.py").write_text(
        "raise ImportError('the render farm module is missing')\n", encoding="utf-8"
    )
    (site / f"{plain}.py").write_text("VALUE = 3\n", encoding="utf-8")
    _dist_info(site, f"[{ENTRY_POINT_GROUP}]\nbad = {broken}\nnot_a_rule = {plain}:VALUE\n")
    monkeypatch.syspath_prepend(str(site))
    manifest = write_project(tmp_path / "project")
    code, found = check(manifest, capsys)
    messages = sorted(d["message"] for d in by_rule(found, "plugin-error"))
    assert len(messages) == 2, messages
    bad = next(m for m in messages if f"entry point bad = {broken}" in m)
    assert "the render farm module is missing" in bad
    value = next(m for m in messages if f"entry point not_a_rule = {plain}:VALUE" in m)
    assert "neither a module nor a Rule" in value
    assert by_rule(found, "misalignment"), "the built-in rules still ran"
    assert code == 1


# -- failures are visible -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("def broken(:\n    pass\n", "SyntaxError"),
        ("import blendspace_no_such_dependency\n", "No module named 'blendspace_no_such_dependency'"),
        ("raise RuntimeError('studio config not found')\n", "RuntimeError: studio config not found"),
    ],
    ids=["syntax-error", "import-error", "raises"],
)
def test_plugin_that_fails_to_import_is_a_diagnostic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], source: str, expected: str
) -> None:
    (tmp_path / "house").mkdir()
    (tmp_path / "house" / "broken_rules.py").write_text(source, encoding="utf-8")
    (tmp_path / "house" / "good_rules.py").write_text(rule_module("studio-good", "ST108"), encoding="utf-8")
    manifest = write_project(tmp_path, "plugins:\n  - house/broken_rules.py\n  - house/good_rules.py\n")
    code, found = check(manifest, capsys)
    [problem] = by_rule(found, "plugin-error")
    assert problem["code"] == "BS900" and problem["severity"] == "error"
    assert "house/broken_rules.py" in problem["message"] and expected in problem["message"]
    # Where, in the plugin: "rule plugin plugin house/..." said neither which line nor said it once.
    assert problem["message"].startswith("rule plugin house/broken_rules.py failed to import: ")
    if "No module" not in expected:
        assert problem["message"].endswith(f"{tmp_path / 'house' / 'broken_rules.py'}:1)")
    assert problem["hint"]
    assert problem["location"]["line"] == line_of(manifest, "plugins:")
    # The other plugin and the built-in rules still ran; the error fails the check.
    assert by_rule(found, "studio-good") and by_rule(found, "misalignment")
    assert code == 1


def test_missing_plugins_are_diagnostics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = write_project(tmp_path, "plugins: [house/absent.py, studio_module_that_does_not_exist]\n")
    code, found = check(manifest, capsys)
    messages = sorted(d["message"] for d in by_rule(found, "plugin-error"))
    assert len(messages) == 2
    assert "house/absent.py not found" in messages[0] and str(tmp_path / "house" / "absent.py") in messages[0]
    assert "studio_module_that_does_not_exist" in messages[1]
    assert code == 1


def test_duplicate_slugs_keep_the_first_and_name_both_sources(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "house").mkdir()
    (tmp_path / "house" / "shadow.py").write_text(
        rule_module("too-close", "ST109", clip="idle"), encoding="utf-8"
    )
    team = tmp_path / "team"
    team.mkdir()
    (team / "team_rules.py").write_text(
        rule_module("studio-dup", "ST110", clip="walk_left"), encoding="utf-8"
    )
    (tmp_path / "house" / "again.py").write_text(
        rule_module("studio-dup", "ST111", clip="walk_right"), encoding="utf-8"
    )
    monkeypatch.setenv(RULE_PATH_VARIABLE, str(team))
    manifest = write_project(tmp_path, "plugins: [house/shadow.py, house/again.py]\n")
    code, found = check(manifest, capsys)
    messages = sorted(d["message"] for d in by_rule(found, "plugin-error"))
    assert len(messages) == 2, messages
    assert "'studio-dup'" in messages[0] and "house/again.py" in messages[0]
    assert str(team / "team_rules.py") in messages[0]
    assert "'too-close'" in messages[1] and "house/shadow.py" in messages[1]
    assert "built-in rules/too_close.py" in messages[1]
    # The first definitions are the ones that ran.
    assert [d["code"] for d in by_rule(found, "studio-dup")] == ["ST110"]
    assert all(d["code"] == "BS004" for d in by_rule(found, "too-close"))
    assert code == 1


def test_a_crashing_rule_does_not_stop_the_others(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    crash = '''

    class Crashes(Rule):
        """Divides by the number of sprint clips, of which there are none."""

        slug = "studio-crash"
        code = "ST112"
        severity = "warning"
        summary = "always crashes"

        def check(self, space):
            yield self.report("never reached: " + str(1 / len([s for s in space.samples if "sprint" in s.name])))
    '''
    (tmp_path / "house.py").write_text(rule_module("studio-fine", "ST113", body=crash), encoding="utf-8")
    manifest = write_project(tmp_path, "plugins: [house.py]\n")
    code, found = check(manifest, capsys)
    [crashed] = by_rule(found, "rule-crashed")
    assert crashed["code"] == "BS902" and crashed["severity"] == "error"
    assert "studio-crash" in crashed["message"] and "ZeroDivisionError" in crashed["message"]
    assert "(rule plugin house.py) crashed" in crashed["message"]  # where the rule came from
    line = next(
        i
        for i, text in enumerate((tmp_path / "house.py").read_text().splitlines(), 1)
        if "never reached" in text
    )
    assert crashed["message"].endswith(f"({tmp_path / 'house.py'}:{line})")  # and the line that raised
    assert (
        by_rule(found, "studio-fine") and by_rule(found, "misalignment") and by_rule(found, "in-place-clip")
    )
    assert not by_rule(found, "studio-crash")
    assert code == 1


def test_incomplete_rule_class_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = rule_module("studio-bad-severity", "ST114", severity="fatal")
    (tmp_path / "house.py").write_text(source, encoding="utf-8")
    manifest = write_project(tmp_path, "plugins: [house.py]\n")
    code, found = check(manifest, capsys)
    [problem] = by_rule(found, "plugin-error")
    assert "Rule_studio_bad_severity" in problem["message"] and "plugin house.py" in problem["message"]
    assert not by_rule(found, "studio-bad-severity") and code == 1


# -- selection, severities, suppressions ----------------------------------------------------------


def _rules_seen(found: list[dict[str, Any]]) -> set[str]:
    return {d["rule"] for d in found}


@pytest.mark.parametrize("key", ["misalignment", "BS003"])
def test_select_by_slug_or_code(tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str) -> None:
    manifest = write_project(tmp_path, f"rules: {{select: [{key}]}}\n")
    _, found = check(manifest, capsys)
    assert _rules_seen(found) == {"misalignment"}
    assert [d["clips"] for d in found] == [["run_drift"]]


@pytest.mark.parametrize("keys", [["in-place-clip", "uncovered-area"], ["BS101", "BS005"]])
def test_ignore_by_slug_or_code(tmp_path: Path, capsys: pytest.CaptureFixture[str], keys: list[str]) -> None:
    baseline = write_project(tmp_path / "a")
    _, before = check(baseline, capsys)
    assert {"in-place-clip", "uncovered-area", "misalignment"} <= _rules_seen(before)
    manifest = write_project(tmp_path / "b", f"rules: {{ignore: [{', '.join(keys)}]}}\n")
    _, found = check(manifest, capsys)
    assert _rules_seen(found) == _rules_seen(before) - {"in-place-clip", "uncovered-area"}


@pytest.mark.parametrize("key", ["misalignment", "BS003"])
def test_severity_override_by_slug_or_code(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str
) -> None:
    manifest = write_project(tmp_path / "up", f"rules: {{severity: {{{key}: error}}}}\n")
    code, found = check(manifest, capsys)
    assert [d["severity"] for d in by_rule(found, "misalignment")] == ["error"] and code == 1
    manifest = write_project(
        tmp_path / "off", f"rules: {{severity: {{{key}: off, uncovered-area: warning}}}}\n"
    )
    code, found = check(manifest, capsys)
    assert not by_rule(found, "misalignment")
    assert [d["severity"] for d in by_rule(found, "uncovered-area")] == ["warning"]
    assert code == 0


def test_selection_and_severity_apply_to_plugin_rules(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "house.py").write_text(rule_module("studio-select", "ST115"), encoding="utf-8")
    manifest = write_project(
        tmp_path, "plugins: [house.py]\nrules: {select: [ST115], severity: {ST115: error}}\n"
    )
    code, found = check(manifest, capsys)
    assert [(d["rule"], d["severity"]) for d in found] == [("studio-select", "error")]
    assert code == 1


@pytest.mark.parametrize("key", ["in-place-clip", "BS101"])
def test_clip_ignore_with_reason(tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str) -> None:
    manifest = write_project(
        tmp_path, entries={"idle": f'ignore: [{{rule: {key}, reason: "idle by design"}}]'}
    )
    code, found = check(manifest, capsys)
    assert not by_rule(found, "in-place-clip")
    assert not by_rule(found, "unused-suppression")
    assert by_rule(found, "misalignment") and code == 0


def test_clip_ignore_of_a_plugin_rule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "house.py").write_text(rule_module("studio-ignorable", "ST116"), encoding="utf-8")
    manifest = write_project(
        tmp_path, "plugins: [house.py]\n", entries={"walk_fwd": "ignore: [{rule: ST116, reason: reviewed}]"}
    )
    _, found = check(manifest, capsys)
    assert not by_rule(found, "studio-ignorable") and not by_rule(found, "unused-suppression")


def test_unused_suppression_is_reported_at_its_clip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = write_project(
        tmp_path,
        entries={
            "walk_fwd": 'ignore: [{rule: too-close, reason: "kept for the style"}]',
            "idle": "ignore: [{rule: in-place-clip, reason: idle}]",
        },
    )
    code, found = check(manifest, capsys)
    [stale] = by_rule(found, "unused-suppression")
    assert stale["code"] == "BS901" and stale["severity"] == "warning"
    assert stale["clips"] == ["walk_fwd"] and "too-close" in stale["message"]
    assert stale["location"]["line"] == line_of(manifest, "clips/walk_fwd.usda")
    assert code == 0
    assert main(["check", str(manifest), "--strict"]) == 1
    capsys.readouterr()


def test_an_ignore_of_a_rule_that_does_not_exist_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A typo in a clip's `ignore:` was only "reported nothing on it"; in `rules:` it is exit 2.
    At the clip it is an `unknown-rule` warning with the nearest slug."""
    manifest = write_project(tmp_path, entries={"idle": "ignore: [{rule: in-place-clp, reason: idle}]"})
    _, found = check(manifest, capsys)
    [typo] = by_rule(found, "unknown-rule")
    assert typo["clips"] == ["idle"] and "ignores 'in-place-clp', which is not a rule" in typo["message"]
    assert typo["hint"].startswith("did you mean 'in-place-clip'?")
    assert typo["location"]["line"] == line_of(manifest, "clips/idle.usda")
    assert not by_rule(found, "unused-suppression")
    assert by_rule(found, "in-place-clip")  # not silenced by the typo


def test_an_ignore_on_a_glob_entry_counts_for_the_entry(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One clip of the glob uses the ignore: no stale warning for the others; an ignore that no
    clip of the glob uses is reported once, at the entry."""
    manifest = write_project(tmp_path)
    manifest.write_text(
        "schema_version: 1\nname: plugtest\nclips:\n  - path: clips/*.usda\n"
        "    ignore: [{rule: in-place-clip, reason: idle}, {rule: acute-triangle, reason: later}]\n",
        encoding="utf-8",
    )
    _, found = check(manifest, capsys)
    assert not by_rule(found, "in-place-clip")
    [stale] = by_rule(found, "unused-suppression")
    assert "'clips/*.usda'" in stale["message"] and "acute-triangle" in stale["message"]
    assert stale["location"]["line"] == 4


# -- CONTRIBUTING.md examples ---------------------------------------------------------------------

CONTRIBUTING = REPO / "CONTRIBUTING.md"
_BLOCK = re.compile(r"<!-- example: (?P<name>[\w-]+) -->\s*```(?P<lang>\w+)\n(?P<code>.*?)```", re.S)


def contributing_examples() -> dict[str, str]:
    """The fenced code blocks of CONTRIBUTING.md that follow an `<!-- example: NAME -->` marker."""
    text = CONTRIBUTING.read_text(encoding="utf-8")
    return {m["name"]: m["code"] for m in _BLOCK.finditer(text)}


def test_every_code_block_in_contributing_is_an_example() -> None:
    text = CONTRIBUTING.read_text(encoding="utf-8")
    fences = len(re.findall(r"^```\w+$", text, flags=re.M))
    examples = contributing_examples()
    assert fences == len(examples), "every fenced block needs an `<!-- example: NAME -->` marker and a test"
    assert {"rule", "rule-test", "manifest", "pyproject", "rule-path", "setup", "checks"} <= set(examples)


def _import_from(path: Path, name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_contributing_rule_and_its_test_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forget_modules: None
) -> None:
    examples = contributing_examples()
    rule_source = examples["rule"]
    # The example uses only the public API.
    imports = re.findall(r"^(?:from|import) ([\w.]+)", rule_source, flags=re.M)
    assert set(imports) <= {"__future__", "collections.abc", "blendspace_pipeline.api"}, imports
    (tmp_path / "acme_rules.py").write_text(rule_source, encoding="utf-8")
    (tmp_path / "test_acme_rules.py").write_text(examples["rule-test"], encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    tests = _import_from(tmp_path / "test_acme_rules.py", "acme_rule_tests")
    names = [n for n in vars(tests) if n.startswith("test_")]
    assert len(names) >= 3
    for name in names:
        getattr(tests, name)()
    # The examples meet the house lint rules too (isort order, line length...).
    ruff = shutil.which("ruff")
    if ruff is not None:
        files = [str(tmp_path / "acme_rules.py"), str(tmp_path / "test_acme_rules.py")]
        lint = subprocess.run(
            [ruff, "check", "--no-cache", "--config", str(REPO / "pyproject.toml"), *files],
            capture_output=True,
            text=True,
            check=False,
        )
        assert lint.returncode == 0, lint.stdout + lint.stderr


def _write_clips(root: Path, names: list[str]) -> None:
    (root / "clips").mkdir(parents=True, exist_ok=True)
    for name in names:
        path = root / "clips" / f"{name}.usda"
        write_usd_clip(generate(SPECS[name], source=path), path, meters_per_unit=1.0, up_axis="y")


def test_contributing_manifest_loads_the_example_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    examples = contributing_examples()
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(examples["manifest"], encoding="utf-8")
    plugin = re.search(r"plugins: \[(.+?)\]", examples["manifest"])
    assert plugin is not None
    (tmp_path / plugin[1]).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / plugin[1]).write_text(examples["rule"], encoding="utf-8")
    _write_clips(tmp_path, list(SPECS))
    code, found = check(manifest, capsys)
    assert not [d for d in found if d["rule"] in ENGINE_SLUGS], found
    # The set tops out at 3 m/s: the example's top-speed rule asks for a sprint clip.
    [top] = by_rule(found, "acme-top-speed")
    assert top["code"] == "ACME001" and top["severity"] == "warning"
    assert code == 0


def test_contributing_entry_point_and_rule_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, forget_modules: None
) -> None:
    examples = contributing_examples()
    pyproject = tomllib.loads(examples["pyproject"])
    points = pyproject["project"]["entry-points"][ENTRY_POINT_GROUP]
    [(point_name, target)] = points.items()
    module_name = target.split(":")[0]
    assert module_name.startswith("acme_")
    site = tmp_path / "site"
    package = site.joinpath(*module_name.split(".")[:-1])
    package.mkdir(parents=True)
    for depth in range(1, module_name.count(".") + 1):
        site.joinpath(*module_name.split(".")[:depth], "__init__.py").write_text("", encoding="utf-8")
    site.joinpath(*module_name.split(".")).with_suffix(".py").write_text(examples["rule"], encoding="utf-8")
    lines = [f"{name} = {value}" for name, value in points.items()]
    _dist_info(site, f"[{ENTRY_POINT_GROUP}]\n" + "\n".join(lines) + "\n")
    monkeypatch.syspath_prepend(str(site))
    assert main(["rules", "--format", "json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    rows = {row["slug"]: row for row in listing["rules"]}
    assert listing["problems"] == []
    assert {"acme-top-speed", "acme-unpaired-run-turn"} <= set(rows)
    assert rows["acme-top-speed"]["origin"] == f"entry point {point_name} = {target}"
    assert rows["acme-unpaired-run-turn"]["fixable"] is True
    # The rule-path example: its variable is the one the engine reads, its commands parse.
    shell = examples["rule-path"]
    assert f"export {RULE_PATH_VARIABLE}=" in shell
    _assert_commands_parse(shell)


def _assert_commands_parse(shell: str) -> None:
    commands = [line.split("#")[0].strip() for line in shell.splitlines() if line.startswith("blendspace ")]
    assert commands
    for command in commands:
        build_parser().parse_args(command.split()[1:])


def test_contributing_setup_and_checks_match_readme_and_ci() -> None:
    examples = contributing_examples()
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    for line in examples["setup"].strip().splitlines():
        assert line in readme, f"setup command {line!r} differs from README's"
    for line in examples["checks"].strip().splitlines():
        command = line.split("#")[0].strip()
        if command.startswith("blendspace "):
            build_parser().parse_args(command.split()[1:])
        else:
            assert command in ci, f"{command!r} is not what CI runs"


@pytest.mark.parametrize(
    ("slug", "code"), [("", ""), ("studio-ok", " "), ("studio\\nrule", "ST104"), (" padded", "ST105")]
)
def test_a_rule_a_manifest_cannot_name_is_a_plugin_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], slug: str, code: str
) -> None:
    """Slugs and codes are what `select`, `ignore` and per-clip `ignore:` name: an empty one was
    a blank row in `blendspace rules`."""
    (tmp_path / "rules").mkdir()
    (tmp_path / "rules" / "odd.py").write_text(rule_module(slug, code), encoding="utf-8")
    manifest = write_project(tmp_path, "plugins: [rules/odd.py]\n")
    _, found = check(manifest, capsys)
    [problem] = by_rule(found, "plugin-error")
    assert "both must be non-empty text without control characters" in problem["message"]


def test_existing_studio_slugs_and_codes_still_load(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`studio_min_cycle` / `ST-001` are written in manifests as they are: they load."""
    (tmp_path / "rules").mkdir()
    (tmp_path / "rules" / "ok.py").write_text(rule_module("studio_min_cycle", "ST-001"), encoding="utf-8")
    manifest = write_project(tmp_path, "plugins: [rules/ok.py]\n")
    _, found = check(manifest, capsys)
    assert not by_rule(found, "plugin-error") and by_rule(found, "studio_min_cycle")
