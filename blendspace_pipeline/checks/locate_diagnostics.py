"""Anchor each diagnostic at a manifest line, so editors, CI and pre-commit can point at it."""

from __future__ import annotations

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.space.model import BlendSpace

# Set-level findings point at the manifest block they are about.
_RULE_ANCHORS: dict[str, tuple[str | int, ...]] = {
    "axis-zero-off-grid": ("axes",),
    "uncovered-area": ("axes",),
    "plugin-error": ("plugins",),
    "layer-axes": ("layers",),
    "style-coverage": ("layers",),
    "mask-joints": ("layers",),
}


def anchor(space: BlendSpace, diagnostics: list[Diagnostic]) -> list[Diagnostic]:
    manifest = space.manifest
    by_name = {s.name: s.clip for s in space.samples}
    where = str(manifest.path)
    anchored = []
    for diagnostic in diagnostics:
        clip = next((by_name[n] for n in diagnostic.clips if n in by_name), None)
        if clip is not None:
            line, column = clip.line, clip.column
        else:
            line, column = manifest.locate(_RULE_ANCHORS.get(diagnostic.rule, ("clips",)))
        anchored.append(diagnostic.evolve(path=where, line=line, column=column))
    return anchored
