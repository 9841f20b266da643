"""Typed rule options, `rules:` names that must exist, and rules that misbehave: each a finding or
an exit-2 manifest error with its line, never a crash, a silent skip or NaN in the outputs."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.procedural import GaitSpec, generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip

SPECS = (
    GaitSpec("idle", duration=1.0),
    GaitSpec("walk", speed=1.4, duration=0.8),
    GaitSpec("tip_left", turn_rate=90.0, duration=1.0),
    GaitSpec("tip_right", turn_rate=-90.0, duration=1.0),
    GaitSpec("back", speed=1.1, direction=180.0, duration=1.0),
)

SHORT_CLIPS = '''
from blendspace_pipeline.api import Field, Rule, RuleOptions


class ShortOptions(RuleOptions):
    min_seconds: float = Field(1.0, gt=0, description="Shortest acceptable clip, seconds.")


class Short(Rule):
    """Flags clips shorter than min_seconds."""

    slug = "studio-short"
    code = "ST501"
    severity = "warning"
    summary = "clip shorter than min_seconds"
    Options = ShortOptions

    def check(self, space):
        for sample in space.samples:
            if sample.features["duration"] < self.options.min_seconds:
                yield self.report(f"{sample.name} is short", clips=[sample.name])
'''


def _project(tmp_path: Path, extra: str = "", plugin: str = SHORT_CLIPS) -> Path:
    for spec in SPECS:
        path = tmp_path / "clips" / f"{spec.name}.usda"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_usd_clip(generate(spec), path, meters_per_unit=1.0, up_axis="y")
    (tmp_path / "house.py").write_text(textwrap.dedent(plugin), encoding="utf-8")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\nplugins: [house.py]\n" + extra,
        encoding="utf-8",
    )
    return manifest


def _check(manifest: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, list[dict[str, object]], str]:
    code = main(["check", str(manifest), "--format", "json"])
    captured = capsys.readouterr()
    found = json.loads(captured.out)["diagnostics"] if captured.out.strip() else []
    return code, found, captured.err


def _error(manifest: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Exit code and stderr of a text-format check (where input errors print)."""
    code = main(["check", str(manifest)])
    return code, capsys.readouterr().err


def _rules(found: list[dict[str, object]], slug: str) -> list[dict[str, object]]:
    return [d for d in found if d["rule"] == slug]


@pytest.mark.parametrize(
    ("options", "flagged"), [("", 1), ("{min_seconds: 0.5}", 0), ("{min_seconds: 2}", 5)]
)
def test_options_reach_the_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: str, flagged: int
) -> None:
    extra = f"rules:\n  options:\n    studio-short: {options}\n" if options else ""
    _, found, _ = _check(_project(tmp_path, extra), capsys)
    assert len(_rules(found, "studio-short")) == flagged


def test_options_by_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _, found, _ = _check(_project(tmp_path, "rules:\n  options:\n    ST501: {min_seconds: 2}\n"), capsys)
    assert len(_rules(found, "studio-short")) == 5


@pytest.mark.parametrize(
    ("options", "where", "message"),
    [
        ("{min_second: 2}", ":8:20", "rules.options.studio-short.min_second: Extra inputs are not permitted"),
        (
            "{min_seconds: soon}",
            ":8:20",
            "rules.options.studio-short.min_seconds: Input should be a valid number",
        ),
        (
            "{min_seconds: -1}",
            ":8:20",
            "rules.options.studio-short.min_seconds: Input should be greater than 0",
        ),
    ],
)
def test_bad_options_are_exit_2_at_their_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: str, where: str, message: str
) -> None:
    manifest = _project(tmp_path, f"rules:\n  options:\n    studio-short: {options}\n")
    code, err = _error(manifest, capsys)
    assert code == 2
    assert f"{manifest}{where}" in err and message in err, err
    assert "min_seconds" in err  # the hint lists the rule's options


def test_options_for_a_rule_without_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _project(tmp_path, "rules:\n  options:\n    too-close: {keep: 1}\n")
    code, err = _error(manifest, capsys)
    assert code == 2 and f"{manifest}:8:5" in err and "takes no options" in err


@pytest.mark.parametrize(
    ("rules", "where", "close"),
    [
        ("{select: [too-clsoe]}", ":6:18", "too-close"),
        ("{ignore: [too_close]}", ":6:18", "too-close"),
        ("{severity: {acute-triangel: error}}", ":6:20", "acute-triangle"),
        ("{options: {studio-shrt: {min_seconds: 1}}}", ":6:19", "studio-short"),
    ],
)
def test_unknown_rule_names_are_exit_2_with_a_suggestion(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], rules: str, where: str, close: str
) -> None:
    manifest = _project(tmp_path, f"rules: {rules}\n")
    code, err = _error(manifest, capsys)
    assert code == 2
    assert f"{manifest}{where}" in err and f"did you mean {close!r}" in err, err


def test_unknown_names_are_a_warning_while_a_plugin_is_broken(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(
        tmp_path, "rules: {select: [all], ignore: [studio-later]}\n", plugin="raise ImportError('x')"
    )
    code, found, _ = _check(manifest, capsys)
    assert code == 1  # the broken plugin is the error
    assert _rules(found, "plugin-error")
    [unknown] = _rules(found, "unknown-rule")
    assert unknown["severity"] == "warning" and "studio-later" in str(unknown["message"])


MISBEHAVING = '''
import math

from blendspace_pipeline.api import Rule


class Text(Rule):
    """Yields a string."""
    slug, code, severity, summary = "studio-text", "ST601", "warning", "yields text"

    def check(self, space):
        yield "walk looks odd"


class NotANumber(Rule):
    """Reports a NaN position."""
    slug, code, severity, summary = "studio-nan", "ST602", "warning", "NaN position"

    def check(self, space):
        yield self.report("here", position=(math.nan, 0.0))


class Ghost(Rule):
    """Names a clip that does not exist."""
    slug, code, severity, summary = "studio-ghost", "ST603", "warning", "unknown clip"

    def check(self, space):
        yield self.report("ghost", clips=["nobody"])


class Mutates(Rule):
    """Tries to change what the next rule sees."""
    slug, code, severity, summary = "studio-mutate", "ST604", "warning", "mutates features"

    def check(self, space):
        space.samples[0].features["duration"] = 99.0
        yield self.report("never")


class SameCode(Rule):
    """Repeats too-close's code."""
    slug, code, severity, summary = "studio-same-code", "BS004", "warning", "duplicate code"

    def check(self, space):
        return iter(())
'''


def test_misbehaving_rules_are_findings_not_crashes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path, plugin=MISBEHAVING)
    code, found, err = _check(manifest, capsys)
    assert code == 1 and "Traceback" not in err
    crashed = " | ".join(str(d["message"]) for d in _rules(found, "rule-crashed"))
    for slug, why in [
        ("studio-text", "not a Diagnostic"),
        ("studio-nan", "not finite"),
        ("studio-ghost", "nobody"),
        ("studio-mutate", "does not support item assignment"),
    ]:
        assert slug in crashed and why in crashed, crashed
    assert not any(d["rule"] in ("studio-text", "studio-nan", "studio-ghost", "studio-mutate") for d in found)
    duplicate = [
        d for d in _rules(found, "plugin-error") if "duplicate rule code 'BS004'" in str(d["message"])
    ]
    assert len(duplicate) == 1 and "too-close" in str(duplicate[0]["message"])
    # too-close (BS004) still ran as itself: the first-loaded rule keeps the code.
    assert all(d["code"] == "BS004" for d in _rules(found, "too-close"))


def test_a_plugin_that_exits_on_import_is_a_plugin_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path, plugin="import sys\nsys.exit(3)\n")
    code, found, _ = _check(manifest, capsys)
    assert code == 1
    [problem] = _rules(found, "plugin-error")
    assert "SystemExit" in str(problem["message"])


def test_rules_command_lists_options_and_fails_on_plugin_problems(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "house.py").write_text(textwrap.dedent(SHORT_CLIPS), encoding="utf-8")
    monkeypatch.setenv("BLENDSPACE_RULE_PATH", str(tmp_path))
    assert main(["rules", "--format", "json"]) == 0
    rows = {row["slug"]: row for row in json.loads(capsys.readouterr().out)["rules"]}
    assert rows["studio-short"]["options"] == [
        {
            "name": "min_seconds",
            "type": "float",
            "default": 1.0,
            "description": "Shortest acceptable clip, seconds.",
        }
    ]
    assert rows["too-close"]["options"] == []
    monkeypatch.setenv("BLENDSPACE_RULE_PATH", str(tmp_path / "missing"))
    assert main(["rules"]) == 1
    assert "does not exist" in capsys.readouterr().out
