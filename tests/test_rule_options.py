"""Typed rule options, `rules:` names that must exist, and rules that misbehave: each a finding or
an exit-2 manifest error with its line, never a crash, a silent skip or NaN in the outputs."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
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
        ("studio-nan", "not a finite number"),
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


# -- rules the loader refuses, and findings the engine refuses ---------------------------------------

BAD_OPTIONS = """
from pydantic import BaseModel

from blendspace_pipeline.api import Field, Rule, RuleOptions


class NoDefault(RuleOptions):
    limit: float = Field(description="no default")


class Lenient(BaseModel):
    limit: float = Field(1.0, description="unknown keys would be ignored")


class Undocumented(RuleOptions):
    limit: float = 1.0


def _rule(slug, code, options):
    return type(slug, (Rule,), {
        "__doc__": "x", "slug": slug, "code": code, "severity": "warning", "summary": "x",
        "Options": options, "__module__": __name__, "check": lambda self, space: iter(()),
    })


A = _rule("studio-no-default", "ST701", NoDefault)
B = _rule("studio-lenient", "ST702", Lenient)
C = _rule("studio-undocumented", "ST703", Undocumented)
D = _rule("studio-dict-options", "ST704", {"limit": 1.0})
E = _rule("rule-crashed", "ST705", None)
F = _rule("studio-engine-code", "BS950", None)
"""


def test_rules_with_unusable_options_or_engine_names_are_plugin_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, found, err = _check(_project(tmp_path, plugin=BAD_OPTIONS), capsys)
    assert code == 1 and "Traceback" not in err  # NoDefault used to crash the run (exit 3)
    problems = " | ".join(str(d["message"]) for d in _rules(found, "plugin-error"))
    for expected in [
        "'limit' needs a default",
        "must forbid unknown keys",
        "'limit' needs a description",
        "must be a RuleOptions subclass",
        "rule rule-crashed (ST705)",
        "rule studio-engine-code (BS950)",
    ]:
        assert expected in problems, problems
    assert len(_rules(found, "plugin-error")) == 6
    # None of them ran, so none of them reported anything.
    assert not [d for d in found if str(d["rule"]).startswith("studio-")]


ODD_FINDINGS = '''
import math
import sys

from blendspace_pipeline.api import Diagnostic, Placeholder, Rule


class Fatal(Rule):
    """Invents a severity."""
    slug, code, severity, summary = "studio-fatal", "ST801", "warning", "bad severity"

    def check(self, space):
        yield Diagnostic(rule=self.slug, code=self.code, severity="fatal", message="m")


class Impostor(Rule):
    """Reports as another rule."""
    slug, code, severity, summary = "studio-impostor", "ST802", "warning", "not its own"

    def check(self, space):
        yield Diagnostic(rule="too-close", code="BS004", severity="warning", message="m")


class ListClips(Rule):
    """Names clips in a list."""
    slug, code, severity, summary = "studio-list", "ST803", "warning", "list of clips"

    def check(self, space):
        yield Diagnostic(rule=self.slug, code=self.code, severity="warning", message="m", clips=["walk"])


class NanPlaceholder(Rule):
    """A placeholder whose features are NaN."""
    slug, code, severity, summary = "studio-nan-mark", "ST804", "warning", "NaN placeholder"

    def check(self, space):
        mark = Placeholder((0.0, 0.0), "suggested", self.slug, "r", {"speed": math.inf})
        yield self.report("m", placeholders=[mark])


class Exits(Rule):
    """Calls sys.exit while checking."""
    slug, code, severity, summary = "studio-exits", "ST805", "warning", "exits"

    def check(self, space):
        sys.exit(4)


class HalfWay(Rule):
    """Reports once, then crashes."""
    slug, code, severity, summary = "studio-half-way", "ST806", "warning", "crashes half way"

    def check(self, space):
        yield self.report("first", clips=["walk"])
        raise RuntimeError("boom")
'''


def test_findings_the_outputs_cannot_hold_are_rule_crashed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, found, err = _check(_project(tmp_path, plugin=ODD_FINDINGS), capsys)
    assert code == 1 and "Traceback" not in err  # "fatal" used to fail sorting (exit 3)
    crashed = {str(d["message"]).split()[1]: str(d["message"]) for d in _rules(found, "rule-crashed")}
    assert "severity 'fatal'" in crashed["studio-fatal"]
    assert "a finding of too-close (BS004), not its own" in crashed["studio-impostor"]
    assert "not a tuple of clip names" in crashed["studio-list"]
    assert "not a finite number" in crashed["studio-nan-mark"]
    assert "SystemExit: 4" in crashed["studio-exits"]  # used to end the run silently
    assert "RuntimeError: boom" in crashed["studio-half-way"]
    # A crashed rule's findings so far are dropped with it.
    assert not [d for d in found if str(d["rule"]).startswith("studio-")]
    assert not [d for d in _rules(found, "too-close") if d["message"] == "m"]


def test_build_survives_rules_that_report_nan_or_unknown_clips(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path, plugin=MISBEHAVING)
    code = main(["build", str(manifest), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err, err
    report = json.loads(next((tmp_path / "out").rglob("*.json")).read_text(encoding="utf-8"))
    assert "NaN" not in json.dumps(report)


def test_a_custom_base_exception_on_import_is_a_plugin_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plugin = "class Stop(BaseException):\n    pass\n\n\nraise Stop('no')\n"
    code, found, _ = _check(_project(tmp_path, plugin=plugin), capsys)
    assert code == 1
    [problem] = _rules(found, "plugin-error")
    assert "Stop: no" in str(problem["message"])


# -- options in the manifest -------------------------------------------------------------------------

LISTED = '''
from typing import Literal

from pydantic import model_validator

from blendspace_pipeline.api import Field, Rule, RuleOptions


class ListedOptions(RuleOptions):
    names: list[str] = Field(default_factory=list, description="Clips to look at.")
    mode: Literal["strict", "loose"] = Field("loose", description="How hard to look.")
    low: float = Field(0.0, description="Lower bound.")
    high: float = Field(1.0, description="Upper bound.")

    @model_validator(mode="after")
    def _ordered(self):
        if self.low > self.high:
            raise ValueError("low must not exceed high")
        return self


class Listed(Rule):
    """Looks at the named clips."""
    slug, code, severity, summary = "studio-listed", "ST901", "info", "named clips"
    Options = ListedOptions

    def check(self, space):
        for name in self.options.names:
            yield self.report(f"{name} ({self.options.mode})", clips=[name])
'''


def test_an_option_error_inside_a_list_points_at_the_item(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    extra = "rules:\n  options:\n    studio-listed:\n      names:\n        - walk\n        - [idle]\n"
    manifest = _project(tmp_path, extra, plugin=LISTED)
    code, err = _error(manifest, capsys)
    assert code == 2
    assert f"{manifest}:11:11: rules.options.studio-listed.names.1: Input should be a valid string" in err


def test_a_whole_options_error_has_no_dangling_dot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path, "rules:\n  options:\n    studio-listed: {low: 2, high: 1}\n", plugin=LISTED)
    code, err = _error(manifest, capsys)
    assert code == 2
    assert f"{manifest}:8:5: rules.options.studio-listed: Value error, low must not exceed high" in err


@pytest.mark.parametrize("section", ["options", "severity"])
def test_a_rule_configured_by_slug_and_by_code_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], section: str
) -> None:
    value = "{names: [walk]}" if section == "options" else "info"
    other = "{names: [idle]}" if section == "options" else "error"
    extra = f"rules:\n  {section}:\n    studio-listed: {value}\n    ST901: {other}\n"
    manifest = _project(tmp_path, extra, plugin=LISTED)
    code, err = _error(manifest, capsys)
    assert code == 2
    assert f"{manifest}:9:5: rules.{section}.ST901: studio-listed is already configured" in err


def test_options_do_not_leak_between_manifests(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    configured = _project(tmp_path / "a", "rules:\n  options:\n    studio-listed: {names: [walk]}\n", LISTED)
    plain = _project(tmp_path / "b", plugin=LISTED)
    _, first, _ = _check(configured, capsys)
    _, second, _ = _check(plain, capsys)
    assert [d["clips"] for d in _rules(first, "studio-listed")] == [["walk"]]
    assert _rules(second, "studio-listed") == []


def test_rules_command_prints_option_types_and_json_defaults(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "listed.py").write_text(textwrap.dedent(LISTED), encoding="utf-8")
    monkeypatch.setenv("BLENDSPACE_RULE_PATH", str(tmp_path))
    assert main(["rules", "--format", "json"]) == 0
    rows = {row["slug"]: row for row in json.loads(capsys.readouterr().out)["rules"]}
    options = {o["name"]: (o["type"], o["default"]) for o in rows["studio-listed"]["options"]}
    assert options["names"] == ("list[str]", [])  # a default_factory is listed by its value
    assert options["mode"] == ("Literal['strict', 'loose']", "loose")
    assert main(["rules"]) == 0
    assert "option mode: Literal['strict', 'loose'] = \"loose\"  How hard to look." in capsys.readouterr().out


# -- the rule-author harness and the views ----------------------------------------------------------


def test_harness_views_are_read_only() -> None:
    from blendspace_pipeline.testing import space_from_positions

    features = {"walk": {"duration": 0.5}}
    space = space_from_positions({"idle": (0, 0), "walk": (0, 1.4), "run": (0, 4.0)}, features=features)
    with pytest.raises(TypeError):
        space.samples[1].features["duration"] = 9.0  # type: ignore[index]
    with pytest.raises(TypeError):
        space.thresholds["too_close"] = 0.0  # type: ignore[index]
    features["walk"]["duration"] = 9.0  # the caller's dict is copied, not shared
    assert space.sample("walk").features["duration"] == 0.5


def test_harness_takes_options_and_checks_like_the_engine(tmp_path: Path) -> None:
    import importlib.util

    from blendspace_pipeline.testing import run_rule, space_from_positions

    path = tmp_path / "odd_rules.py"
    path.write_text(textwrap.dedent(ODD_FINDINGS + LISTED + BAD_OPTIONS), encoding="utf-8")
    spec = importlib.util.spec_from_file_location("odd_rules", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    space = space_from_positions({"idle": (0, 0), "walk": (0, 1.4), "run": (0, 4.0)})

    [finding] = run_rule(module.Listed, space, names=["walk"], mode="strict")
    assert finding.message == "walk (strict)"
    with pytest.raises(ValueError, match="valid string"):
        run_rule(module.Listed, space, names=[1])
    with pytest.raises(AssertionError, match="rule-crashed: it yielded severity 'fatal'"):
        run_rule(module.Fatal, space)
    with pytest.raises(AssertionError, match=r"loader would refuse .*'limit' needs a default"):
        run_rule(module.A, space)
    with pytest.raises(TypeError, match="takes ListedOptions"):
        module.Listed(options=module.NoDefault.model_construct())
