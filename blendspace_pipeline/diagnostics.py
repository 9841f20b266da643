"""Diagnostics and placeholders: what every stage and every rule reports.

A `Diagnostic` names its rule (slug and code), a severity, the clips involved and, when it has
one, a position in the blend space; the CLI formats it and the JSON/report carry it. Stages
(reading, placement, triangulation) and rules emit the same type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

Severity = Literal["error", "warning", "info"]
SEVERITY_ORDER: dict[str, int] = {"error": 0, "warning": 1, "info": 2}


@dataclass(frozen=True)
class Placeholder:
    """A clip the set should gain: the paper's orange (necessary) and green (suggested) markers."""

    position: tuple[float, float]
    priority: Literal["necessary", "suggested"]
    rule: str
    reason: str
    features: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Diagnostic:
    rule: str
    code: str
    severity: Severity
    message: str
    clips: tuple[str, ...] = ()
    position: tuple[float, float] | None = None
    fix: str | None = None
    hint: str | None = None
    placeholders: tuple[Placeholder, ...] = ()
    # Where in the manifest: filled in by the pipeline from the first clip's entry.
    path: str | None = None
    line: int | None = None
    column: int | None = None
    # What the fix needs (data for the engine, never applied by the rule itself).
    fix_data: dict[str, object] | None = None

    def sort_key(self) -> tuple[int, str, tuple[str, ...], str]:
        return (SEVERITY_ORDER[self.severity], self.rule, self.clips, self.message)
