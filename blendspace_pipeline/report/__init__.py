"""The build's human-facing outputs: `N.report.html` and `N.png`.

The entry points import their modules on call, so writing the HTML never loads OpenImageIO
(imported only by `png.py`, the image writer).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.space.document import BlendSpaceDocument

if TYPE_CHECKING:
    from blendspace_pipeline.report.html import ReportDraft

__all__ = ["write_html_report", "write_png"]


def write_html_report(
    doc: BlendSpaceDocument,
    path: Path,
    inputs: Sequence[Path] = (),
    *,
    stamp: str | None = None,
    draft: ReportDraft | None = None,
) -> None:
    """Write the self-contained interactive report (inline CSS, JS and SVG) atomically; its
    time is ``stamp``, else that of the newest of ``inputs`` (see `html.build_stamp`).
    ``draft``: the part drawn before the blend quality was set (`html.draft_report`)."""
    from blendspace_pipeline.report.html import write_html_report as write

    write(doc, path, inputs, stamp=stamp, draft=draft)


def write_png(doc: BlendSpaceDocument, path: Path) -> None:
    """Write the blend-space diagram as a PNG (OpenImageIO) atomically."""
    from blendspace_pipeline.report.png import write_png as write

    write(doc, path)
