"""The Python entry point: `build`, `check` and `evaluate` for scripts that embed us.

A Maya, Houdini or farm script calls these instead of a shell. They do what the commands do and
return typed results; the CLI's exit codes map onto them:

- exit 2 (invalid input) is an `errors.InputError` raised with ``path``, ``line``, ``column`` and
  ``hint`` (``str(error)`` is the CLI's one-line message);
- exit 1 (error findings, or warnings with ``strict``) is ``result.exit_code == 1`` with the
  findings in ``result.diagnostics``: findings are results, not exceptions;
- exit 3 (a bug) is whatever exception escaped.

    from blendspace_pipeline.scripting import build, check, evaluate

    result = check("chars/hero/locomotion.yaml")
    if not result.ok:
        for finding in result.diagnostics:
            print(finding.rule, finding.message)

Heavy modules (USD, OpenImageIO, scipy) load inside the calls, so importing this is cheap.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.errors import EXIT_DIAGNOSTICS, EXIT_OK

if TYPE_CHECKING:
    from blendspace_pipeline.space.evaluate import Evaluation
    from blendspace_pipeline.space.model import BlendSpace

PathLike = str | os.PathLike[str]

__all__ = ["BuildOutcome", "CheckOutcome", "build", "check", "evaluate"]


def _exit_code(diagnostics: list[Diagnostic], strict: bool) -> int:
    failing = {"error", "warning"} if strict else {"error"}
    return EXIT_DIAGNOSTICS if any(d.severity in failing for d in diagnostics) else EXIT_OK


@dataclass(frozen=True)
class CheckOutcome:
    """What `check` found: the analysed space and its findings (beta layers' included)."""

    space: BlendSpace
    diagnostics: list[Diagnostic]
    exit_code: int  # what `blendspace check` would exit with: 0, or 1 for failing findings

    @property
    def ok(self) -> bool:
        return self.exit_code == EXIT_OK


@dataclass(frozen=True)
class BuildOutcome(CheckOutcome):
    """What `build` wrote, on top of what it found."""

    out_dir: Path
    outputs: list[Path]  # every file written, generated clips included
    document_path: (
        Path | None
    )  # the N.blendspace.json (the input of `evaluate`), unless output.formats omits json
    generated: list[str]  # clips the fixes made (beta layers' as "layer/clip")


def check(manifest: PathLike, *, strict: bool = False, jobs: int = 1) -> CheckOutcome:
    """Analyse ``manifest`` and run the rules; writes nothing (like `blendspace check`)."""
    from blendspace_pipeline.pipeline.analysis import analyse

    space = analyse(Path(manifest), jobs=_jobs(jobs))
    found = space.all_diagnostics()
    return CheckOutcome(space, found, _exit_code(found, strict))


def build(
    manifest: PathLike,
    *,
    out: PathLike | None = None,
    fix: bool = True,
    strict: bool = False,
    jobs: int = 1,
) -> BuildOutcome:
    """Build ``manifest`` like `blendspace build`: fixes (unless ``fix=False``), then every output."""
    from blendspace_pipeline.pipeline.outputs import build as build_outputs

    result = build_outputs(Path(manifest), Path(out) if out is not None else None, jobs=_jobs(jobs), fix=fix)
    found = result.space.all_diagnostics()
    document = next((p for p in result.written if p.name.endswith(".blendspace.json")), None)
    return BuildOutcome(
        space=result.space,
        diagnostics=found,
        exit_code=_exit_code(found, strict),
        out_dir=result.out_dir,
        outputs=list(result.written),
        document_path=document,
        generated=result.generated_names(),
    )


def evaluate(
    document: PathLike,
    x: float,
    y: float,
    *,
    layers: Mapping[str, float] | None = None,
    joint: str | None = None,
    cull: float | None = None,
) -> Evaluation:
    """The clips, weights and playback rates a built space blends at (x, y), in axis units."""
    from blendspace_pipeline.space.evaluate import DEFAULT_CULL
    from blendspace_pipeline.space.evaluate import evaluate as evaluate_document
    from blendspace_pipeline.space.layers_doc import read_document

    doc = read_document(Path(document))
    return evaluate_document(
        doc, x, y, layers=layers, joint=joint, cull=DEFAULT_CULL if cull is None else cull
    )


def _jobs(jobs: int) -> int:
    from blendspace_pipeline.errors import UsageError

    if jobs < 1:
        raise UsageError(f"jobs must be 1 or more (got {jobs})", hint="jobs=1 measures in this process")
    return jobs
