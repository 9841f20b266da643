"""`blendspace rules [--format text|json]`: every rule with slug, code, severity, fixability."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from blendspace_pipeline.api import Rule

HELP = "list every available rule (built-in, entry points, BLENDSPACE_RULE_PATH)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--format", choices=("text", "json"), default="text")


def run(args: argparse.Namespace) -> int:
    from blendspace_pipeline.checks.rule_engine import load_rules  # only when this command runs

    loaded = load_rules()
    rows: list[dict[str, Any]] = [
        {
            "slug": slug,
            "code": rule.code,
            "severity": rule.severity,
            "fixable": rule.fixable,
            "summary": rule.summary,
            "origin": loaded.origins[slug],
            "doc": rule.documentation(),
            "options": _options(rule),
        }
        for slug, rule in sorted(loaded.rules.items(), key=lambda item: item[1].code)
    ]
    if args.format == "json":
        sys.stdout.write(
            json.dumps({"rules": rows, "problems": [p.message for p in loaded.problems]}, indent=2) + "\n"
        )
    else:
        for row in rows:
            fix = "fixable" if row["fixable"] else ""
            sys.stdout.write(
                f"{row['code']:<6} {row['slug']:<24} {row['severity']:<8} {fix:<8} {row['summary']}\n"
            )
            for option in row["options"]:
                sys.stdout.write(
                    f"{'':<6} option {option['name']}: {option['type']} = {json.dumps(option['default'])}"
                    f"  {option['description']}\n"
                )
        for problem in loaded.problems:
            sys.stdout.write(f"error: {problem.message}\n")
    # A broken plugin must fail a CI step that lists rules, not scroll by.
    return 1 if loaded.problems else 0


def _options(rule: type[Rule]) -> list[dict[str, Any]]:
    """A rule's typed options (`rules: {options: {slug: {...}}}`): name, type, default, description."""
    if rule.Options is None:
        return []
    # The loader checked that the defaults dump to JSON (options are written in YAML).
    defaults = rule.Options().model_dump(mode="json")
    return [
        {
            "name": name,
            "type": _type_name(info.annotation),
            "default": defaults[name],
            "description": info.description or "",
        }
        for name, info in rule.Options.model_fields.items()
    ]


def _type_name(annotation: object) -> str:
    """`float`, `list[str]`, `Literal['a', 'b']`: how the type reads in a rule's source."""
    if isinstance(annotation, type):
        return annotation.__name__  # a plain class (a generic alias like list[str] is not a type)
    return str(annotation).replace("typing.", "")
