"""`blendspace rules [--format text|json]`: every rule with slug, code, severity, fixability."""

from __future__ import annotations

import argparse
import json
import sys

from blendspace_pipeline.rule_engine import load_rules

HELP = "list every available rule (built-in, entry points, BLENDSPACE_RULE_PATH)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--format", choices=("text", "json"), default="text")


def run(args: argparse.Namespace) -> int:
    loaded = load_rules()
    rows = [
        {
            "slug": slug,
            "code": rule.code,
            "severity": rule.severity,
            "fixable": rule.fixable,
            "summary": rule.summary,
            "origin": loaded.origins[slug],
            "doc": rule.documentation(),
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
        for problem in loaded.problems:
            sys.stdout.write(f"error: {problem.message}\n")
    return 0
