"""The `blendspace` command line: one parser, one error handler, exit codes from spec.md.

Each sub-command lives in `blendspace_pipeline.commands.<name>` and exposes ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. `main(argv)` is testable without a
subprocess; it never lets a traceback reach the user: input errors exit 2 with
`path:line: message`, anything unexpected exits 3 with one line and the path of a log file.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
import traceback
from collections.abc import Sequence
from pathlib import Path

from blendspace_pipeline import __version__
from blendspace_pipeline.errors import EXIT_INPUT, EXIT_INTERNAL, InputError

COMMANDS = ("build", "check", "rules", "schema", "eval", "export", "index", "suggest")


class _Parser(argparse.ArgumentParser):
    """argparse exits 2 on usage errors already; we only make the message follow our format."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        sys.stderr.write(f"blendspace: error: {message}\n")
        raise SystemExit(EXIT_INPUT)


def _available_commands() -> dict[str, object]:
    modules: dict[str, object] = {}
    for name in COMMANDS:
        try:
            modules[name] = importlib.import_module(f"blendspace_pipeline.commands.{name}")
        except ModuleNotFoundError as error:
            if error.name != f"blendspace_pipeline.commands.{name}":
                raise
    return modules


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="blendspace", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--version", action="version", version=f"blendspace-pipeline {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name, module in _available_commands().items():
        command = sub.add_parser(
            name, help=getattr(module, "HELP", None), description=getattr(module, "HELP", None)
        )
        module.add_arguments(command)  # type: ignore[attr-defined]
        command.set_defaults(handler=module.run)  # type: ignore[attr-defined]
    return parser


def _log_internal_error() -> Path:
    log = Path(tempfile.gettempdir()) / "blendspace-crash.log"
    log.write_text(f"blendspace-pipeline {__version__}\n{traceback.format_exc()}", encoding="utf-8")
    return log


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        result: int = args.handler(args)
        return result
    except SystemExit as stop:
        return int(stop.code) if isinstance(stop.code, int) else EXIT_INPUT
    except InputError as error:
        sys.stderr.write(f"{error.render()}\n")
        return EXIT_INPUT
    except KeyboardInterrupt:
        sys.stderr.write("blendspace: interrupted\n")
        return 130
    except Exception as error:  # the one place that turns a bug into exit 3
        log = _log_internal_error()
        sys.stderr.write(f"blendspace: internal error: {type(error).__name__}: {error} (details in {log})\n")
        return EXIT_INTERNAL
