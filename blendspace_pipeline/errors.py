"""Errors that map to exit codes.

Every error a user can cause is an `InputError` (exit 2) carrying *where* (a path and, when known,
a line and column), *what* went wrong and a *hint* on how to fix it. The CLI prints it as
`path:line:col: message` followed by an indented `hint:` line and never shows a traceback.
Anything else that escapes is an internal error (exit 3).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path

EXIT_OK = 0
EXIT_DIAGNOSTICS = 1
EXIT_INPUT = 2
EXIT_INTERNAL = 3
MORE_SHOWN = 20


# C0 and C1 control characters and the Unicode line and paragraph separators: printed raw, a clip
# name holding one could start a new line that a CI log obeys (`::error ...`) or move the cursor.
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def printable(text: str) -> str:
    """``text`` with every control character shown as an escape (`\\n`, `\\x1b`): one line, inert."""
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)


def printable_hint(text: str, indent: str) -> str:
    """A hint may span lines on purpose: each line is made printable and indented by ``indent``."""
    return ("\n" + indent).join(printable(line) for line in text.split("\n"))


@dataclass
class InputError(Exception):
    """Bad input from the user: a manifest, a clip file or a command-line argument."""

    message: str
    path: Path | str | None = None
    line: int | None = None
    column: int | None = None
    hint: str | None = None
    # Further errors of the same run, each its own `path:line: message` (every unreadable clip of a
    # build, not one per attempt): rendered after this one, at most `MORE_SHOWN` of them.
    more: list[InputError] = field(default_factory=list)

    def __post_init__(self) -> None:
        super().__init__(self.message)

    def location(self) -> str:
        if self.path is None:
            return ""
        where = str(self.path)
        if self.line is not None:
            where += f":{self.line}"
            if self.column is not None:
                where += f":{self.column}"
        return where

    def render(self) -> str:
        """`path:line:col: message` and, when there is one, an indented hint."""
        where = printable(self.location())
        message = printable(self.message)
        text = f"{where}: {message}" if where else message
        if self.hint:
            text += "\n    hint: " + printable_hint(self.hint, "          ")
        hints = {self.hint}
        shown = []
        for other in self.more[:MORE_SHOWN]:  # a hint said once (ten files failing alike)
            shown.append(other.render() if other.hint not in hints else replace(other, hint=None).render())
            hints.add(other.hint)
        if len(self.more) > MORE_SHOWN:
            shown.append(f"... and {len(self.more) - MORE_SHOWN} more")
        return "\n".join([text, *shown])


class ManifestError(InputError):
    """The manifest cannot be read or does not validate."""


class ClipReadError(InputError):
    """A clip file cannot be read: unsupported format, truncated, garbage, non-finite values."""


class UsageError(InputError):
    """The command line is wrong."""
