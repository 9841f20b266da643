"""The `blendspace` command line: one parser, one error handler, exit codes from spec.md.

Each sub-command lives in `blendspace_pipeline.commands.<name>` and exposes ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. `main(argv)` is testable without a
subprocess; it never lets a traceback reach the user: input errors exit 2 with
`path:line: message`, anything unexpected exits 3 with one line and the path of a log file.

Only the command being run is imported (numpy, pxr and the rest load with it): `--version` and
`--help` answer from the help lines in `COMMAND_HELP`, well under 0.3 s. When a build server
runs (`blendspace server start`), the command line hands the command to it instead: see
`blendspace_pipeline.server`.
The crash log is private to the user: `<user cache>/blendspace-pipeline/crash.log` in a 0700
folder, opened without following symlinks; when it cannot be written the one line says so.
"""

from __future__ import annotations

import functools
import os
import sys

from blendspace_pipeline import __version__

TYPE_CHECKING = False  # the name mypy reads as true; `typing` costs a served command 4 ms
if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence
    from pathlib import Path
    from typing import NoReturn

# What a command handed to the build server imports is only `server.client` (json, socket): the
# modules a local run needs (argparse, the error types, traceback; ~20 ms of a served command's
# client) are imported in `run_here` and the functions below it.

COMMANDS = ("build", "check", "rules", "schema", "eval", "export", "index", "suggest", "server")
# Each command module's HELP, repeated here so the top-level help needs no import
# (tests/test_hostile_inputs.py checks they agree).
COMMAND_HELP: dict[str, str] = {
    "build": "build blend-space assets (JSON, USD, HTML report, PNG) from manifest(s)",
    "check": "analyse manifest(s) and run the rules without writing anything (for CI and pre-commit)",
    "rules": "list every available rule (built-in, entry points, BLENDSPACE_RULE_PATH)",
    "schema": "print the JSON Schema of the manifest (default) or of the blend-space JSON",
    "eval": "blend weights (and playback rates) the blend graph gives at one query point",
    "export": "write the blend space for Godot (.tres), Unity (.controller) or Unreal (editor Python script)",
    "index": "measure a whole mocap library into a shared store of features (on Dask)",
    "suggest": "propose library clips (from `blendspace index`) that fill a manifest's placeholders",
    "server": "start, stop or query the build server that keeps the tool loaded between commands",
}
# Commands a running build server may run for the caller (`index` starts Dask workers of its own;
# `server` manages the server).
SERVED = frozenset(COMMANDS) - {"index", "server"}


@functools.cache
def _parser_class() -> type[argparse.ArgumentParser]:
    import argparse

    from blendspace_pipeline.errors import EXIT_INPUT

    class _Parser(argparse.ArgumentParser):
        """argparse exits 2 on usage errors already; we only make the message follow our format."""

        def error(self, message: str) -> NoReturn:
            self.print_usage(sys.stderr)
            sys.stderr.write(f"blendspace: error: {message}\n")
            raise SystemExit(EXIT_INPUT)

    return _Parser


def _command_module(name: str) -> object | None:
    import importlib

    try:
        return importlib.import_module(f"blendspace_pipeline.commands.{name}")
    except ModuleNotFoundError as error:
        if error.name != f"blendspace_pipeline.commands.{name}":
            raise
        return None


def build_parser(only: str | None = None, *, lazy: bool = False) -> argparse.ArgumentParser:
    """The full parser; with ``lazy``, only the command ``only`` is imported and given its arguments
    (the others are listed with their help line, which is all `--help` shows)."""
    parser_class = _parser_class()
    parser = parser_class(prog="blendspace", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--version", action="version", version=f"blendspace-pipeline {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=parser_class)
    for name in COMMANDS:
        if lazy and name != only:
            help_line = COMMAND_HELP.get(name)
            sub.add_parser(name, help=help_line, description=help_line)
            continue
        module = _command_module(name)
        if module is None:
            continue
        command = sub.add_parser(
            name, help=getattr(module, "HELP", None), description=getattr(module, "HELP", None)
        )
        module.add_arguments(command)  # type: ignore[attr-defined]
        command.set_defaults(handler=module.run)  # type: ignore[attr-defined]
    return parser


def _chosen_command(argv: Sequence[str]) -> str | None:
    # The top level takes no option with a value, so the first word that is not an option is it.
    return next((word for word in argv if not word.startswith("-")), None)


def crash_log_path() -> Path:
    from pathlib import Path

    base = os.environ.get("XDG_CACHE_HOME") or os.environ.get("LOCALAPPDATA") or str(Path.home() / ".cache")
    return Path(base) / "blendspace-pipeline" / "crash.log"


def _log_internal_error() -> tuple[Path | None, str]:
    """Write the traceback to the private crash log; (path, "") or (None, why it was not written)."""
    import traceback

    log = crash_log_path()
    try:
        log.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        folder = os.lstat(log.parent)
        if not os.path.isdir(log.parent) or os.path.islink(log.parent):
            return None, f"{log.parent} is not a plain folder"
        if hasattr(os, "getuid") and folder.st_uid != os.getuid():
            return None, f"{log.parent} belongs to another user"
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0)
        handle = os.open(log, flags, 0o600)
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(f"blendspace-pipeline {__version__}\n{traceback.format_exc()}")
        return log, ""
    except OSError as error:  # a planted symlink (ELOOP), a read-only home, a full disk
        return None, f"cannot write {log}: {error.strerror or error}"


def _one_line(error: BaseException) -> str:
    from blendspace_pipeline.errors import printable

    text = str(error).strip().split("\n", 1)[0]  # Qhull's messages run to 30 lines
    return printable(f"{type(error).__name__}: {text}"[:300])


def main(argv: Sequence[str] | None = None) -> int:
    """The `blendspace` entry point. As the command line (no ``argv``) it hands the command to the
    build server when one runs; called with a list (tests, scripts) it always runs here."""
    words = list(sys.argv[1:] if argv is None else argv)
    if argv is None and _chosen_command(words) in SERVED:
        from blendspace_pipeline.server.client import forward

        code = forward(words)
        if code is not None:
            return code
    if argv is None:  # a process of its own: measuring in it (--jobs 1) reuses its freed pages
        from blendspace_pipeline.cpus import own_process
        from blendspace_pipeline.memory import collect_less, keep_freed_memory

        own_process()
        keep_freed_memory()
        collect_less()
        _exit_now(run_here(words))
    return run_here(words)


def _exit_now(code: int) -> NoReturn:
    """End the command's own process without the interpreter's teardown, which frees every
    object one by one: 0.22-0.26 s after a 1,000-clip build had finished its work. The output is
    flushed first; nothing here needs `atexit` (forked children and temporary folders are
    cleaned up by the command itself, before it returns)."""
    import contextlib

    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe (`| head`), a closed stream
            stream.flush()
    os._exit(code)


# Variables whose value must be a whole number: (lowest, highest, what it is for: the hint).
WHOLE_NUMBER_VARIABLES = {
    "SOURCE_DATE_EPOCH": (
        0,
        253_402_300_799,
        "seconds since 1970 (not milliseconds), as `git log -1 --format=%ct` prints them",
    ),
    "BLENDSPACE_MAX_FRAMES": (1, 10**9, "the most frames a clip may have (default 100000)"),
}


def check_environment() -> None:
    """A setting read from the environment that is not a whole number in its range is bad input
    (exit 2), said before the command runs: `SOURCE_DATE_EPOCH=1.5e9` crashed numpy's import
    (exit 3) when not served and was ignored when served, a value in milliseconds crashed the
    report's date, and `BLENDSPACE_MAX_FRAMES=abc` was ignored."""
    from blendspace_pipeline.errors import InputError

    for name, (lowest, highest, meaning) in WHOLE_NUMBER_VARIABLES.items():
        value = os.environ.get(name)
        if value is None or not value.strip():
            continue
        text = value.strip()
        if not (text.isascii() and text.isdigit()) or not lowest <= int(text) <= highest:
            raise InputError(
                f"{name}={value!r} is not a whole number from {lowest} to {highest}",
                hint=f"set it to {meaning}, or unset it",
            )


def run_here(words: list[str]) -> int:
    """Run the command in this process (also what the build server's forked process calls)."""
    from blendspace_pipeline.errors import EXIT_INPUT, EXIT_INTERNAL, InputError, printable

    try:
        parser = build_parser(_chosen_command(words), lazy=True)
        args = parser.parse_args(words)
        check_environment()
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
        try:
            log, problem = _log_internal_error()
            where = f"details in {log}" if log is not None else f"no crash log: {problem}"
        except Exception as logging_error:  # never a traceback, even from the logger
            where = f"no crash log: {type(logging_error).__name__}"
        sys.stderr.write(f"blendspace: internal error: {_one_line(error)} ({printable(where)})\n")
        return EXIT_INTERNAL
