"""Arguments, exit-code logic and reporting shared by `build` and `check`."""

from __future__ import annotations

import argparse
import inspect
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.checks.output_formats import FORMATS, RuleInfo, render
from blendspace_pipeline.checks.trust import NO_PLUGINS_VARIABLE
from blendspace_pipeline.commands._arguments import given, given_path
from blendspace_pipeline.cpus import JOBS_VARIABLE, auto_jobs, capped_processes
from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.errors import EXIT_DIAGNOSTICS, EXIT_OK, InputError
from blendspace_pipeline.pipeline.cache import LIBRARY_VARIABLE

if TYPE_CHECKING:  # the analysis loads only when a command runs one (a no-op replay never does)
    from blendspace_pipeline.space.model import BlendSpace

INVALID_INPUT = "invalid-input"
# The engine's own codes: BS900-BS902 in rule_engine, BS903/BS904 in fix_loop; this is the next.
INVALID_INPUT_CODE = "BS905"


# Findings that come from the engine rather than from a Rule class still need a SARIF descriptor.
# Built on first use: the rule engine loads only when a command runs the rules.
@cache
def engine_rules() -> dict[str, RuleInfo]:
    from blendspace_pipeline.checks.rule_engine import ENGINE_CODES

    return {
        "plugin-error": RuleInfo(
            ENGINE_CODES["plugin-error"],
            "a rule plugin could not be loaded",
            "A rule plugin (from `plugins:`, BLENDSPACE_RULE_PATH or an entry point) failed to import "
            "or defines an incomplete or duplicate rule. The other rules still ran.",
            "error",
        ),
        "unused-suppression": RuleInfo(
            ENGINE_CODES["unused-suppression"],
            "a clip's `ignore:` entry suppressed nothing",
            "A clip entry ignores a rule that reported nothing on it: the suppression is stale.",
            "warning",
        ),
        "rule-crashed": RuleInfo(
            ENGINE_CODES["rule-crashed"],
            "a rule raised an exception",
            "A rule crashed while checking the blend space; its findings are missing, the other rules ran.",
            "error",
        ),
        "unknown-rule": RuleInfo(
            ENGINE_CODES["unknown-rule"],
            "`rules:` names a rule that is not loaded",
            "A rule slug or code in `rules:` matches no loaded rule while a plugin failed to load (it may "
            "be that plugin's). Without a broken plugin an unknown name is a manifest error.",
            "warning",
        ),
        "fix-skipped": RuleInfo(
            "BS903",
            "an automatic fix was not applied",
            "A fixable finding was left as it is because its fix could not be made safely.",
            "info",
        ),
        "fix-removed": RuleInfo(
            "BS904",
            "a fix left a clip out of the blend space",
            "A fix (e.g. too-close: keep-representative or merge) took a clip out of the blend space.",
            "info",
        ),
        "fix-rejected": RuleInfo(
            "BS907",
            "a fix that would have made the space worse, and why it was not applied",
            "The build tried the fix, analysed the space again and kept it only if the findings improved "
            "(fewer errors, then fewer warnings, then more coverage) and no authored key clip was lost.",
            "info",
        ),
        INVALID_INPUT: RuleInfo(
            INVALID_INPUT_CODE,
            "a manifest or one of its clips cannot be read or is invalid",
            "The manifest does not validate, or a clip it names is missing or unreadable. Nothing was "
            "checked for this manifest; the message says where and the hint how to fix it.",
            "error",
        ),
    }


def add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "manifests", nargs="+", type=given_path, metavar="MANIFEST", help="manifest YAML file(s)"
    )
    parser.add_argument(
        "--format", choices=FORMATS, default="text", help="how to print diagnostics (default: text)"
    )
    parser.add_argument("--strict", action="store_true", help="exit 1 on warnings too")
    parser.add_argument(
        "--no-plugins",
        action="store_true",
        help="an untrusted run: load only built-in and installed entry-point rules, not `plugins:` "
        f"or BLENDSPACE_RULE_PATH (same as {NO_PLUGINS_VARIABLE}=1)",
    )
    parser.add_argument(
        "--jobs",
        type=_jobs,
        default=os.environ.get(JOBS_VARIABLE) or "auto",
        metavar="N",
        help="use N processes to measure clips, play the foot-skate map and write outputs; 'auto' "
        "uses the CPUs this process may use on Linux (its affinity and cgroup quota), 1 elsewhere "
        f"(default: {JOBS_VARIABLE}, else auto)",
    )
    parser.add_argument(
        "--library",
        type=given,
        metavar="STORE",
        help="read measurements from a store written by `blendspace index` (a folder or fsspec URL) "
        f"before measuring a clip; same as {LIBRARY_VARIABLE}=STORE",
    )


@contextmanager
def command_environment(args: argparse.Namespace) -> Iterator[None]:
    """`--no-plugins` and `--library` for the length of one command: the rule engine and the
    measure stage (and --jobs workers, which inherit the environment) read them from
    `BLENDSPACE_NO_PLUGINS` and `BLENDSPACE_LIBRARY_STORE`; restored afterwards so a caller of
    `cli.main` in the same process is not affected."""
    wanted = {}
    if getattr(args, "no_plugins", False):
        wanted[NO_PLUGINS_VARIABLE] = "1"
    if getattr(args, "library", None):
        wanted[LIBRARY_VARIABLE] = str(args.library)
    before = {name: os.environ.get(name) for name in wanted}
    os.environ.update(wanted)
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _jobs(text: str) -> int:
    """argparse type for --jobs: 'auto' or a whole number of at least 1 (argparse turns the error
    into exit 2). argparse applies it to the default (BLENDSPACE_JOBS, else "auto") too."""
    if text.strip().lower() == "auto":
        return auto_jobs()
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a whole number or 'auto' (given as --jobs or {JOBS_VARIABLE})"
        ) from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} processes cannot measure anything: give 1 or more")
    return capped_processes(value, "--jobs")


def exit_code(diagnostics: Sequence[Diagnostic], strict: bool) -> int:
    failing = {"error", "warning"} if strict else {"error"}
    return EXIT_DIAGNOSTICS if any(d.severity in failing for d in diagnostics) else EXIT_OK


def input_error_diagnostic(error: InputError, manifest: Path) -> Diagnostic:
    """An invalid manifest as a finding, so machine formats still carry it (and the others)."""
    # An error without a path of its own is about the manifest as a whole.
    path = error.path if error.path is not None else manifest
    return Diagnostic(
        rule=INVALID_INPUT,
        code=INVALID_INPUT_CODE,
        severity="error",
        message=error.message,
        hint=error.hint,
        path=str(path),
        line=error.line,
        column=error.column,
    )


def report_input_error(fmt: str, error: InputError, manifest: Path) -> list[Diagnostic]:
    """Text mode prints the error as the CLI always has (`path:line:col: message`, hint) on
    stderr and returns nothing; the other formats get a diagnostic per error (the error and every
    one it carries in `more`: each unreadable clip) to put into their document."""
    if fmt == "text":
        sys.stderr.write(f"{error.render()}\n")
        return []
    return [input_error_diagnostic(each, manifest) for each in (error, *error.more)]


def _spaces(space: BlendSpace) -> Iterator[BlendSpace]:
    from blendspace_pipeline.space.model import BetaSpace

    yield space
    for layer in space.layer_spaces:
        if isinstance(layer, BetaSpace):
            yield from _spaces(layer.space)


def rule_catalogue(spaces: Sequence[BlendSpace]) -> dict[str, RuleInfo]:
    """Every rule these spaces ran (built-ins, entry points, their manifests' plugins), for SARIF."""
    from blendspace_pipeline.checks.rule_engine import loaded_rules_of

    catalogue = dict(engine_rules())
    for space in spaces:
        for each in _spaces(space):
            loaded = loaded_rules_of(each)
            for slug, rule in loaded.rules.items():
                doc = inspect.cleandoc(rule.documentation())
                catalogue.setdefault(slug, RuleInfo(rule.code, rule.summary, doc, rule.severity))
    return catalogue


def emit(
    fmt: str,
    diagnostics: Sequence[Diagnostic],
    summary: str,
    extra: dict[str, object] | None = None,
    spaces: Sequence[BlendSpace] = (),
) -> None:
    # Only SARIF describes rules (the ones each space ran with).
    rules = rule_catalogue(spaces) if fmt == "sarif" else None
    sys.stdout.write(render(fmt, diagnostics, summary=summary, extra=extra, rules=rules))
