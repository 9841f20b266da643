"""Anchor each diagnostic at a manifest line, so editors, CI and pre-commit can point at it."""

from __future__ import annotations

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.space.model import BetaSpace, BlendSpace, Layer

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
    # A finding about a layer's clip (a style clip of another rig) points at the layers.
    in_layers = {name for layer in space.layer_spaces for name in _layer_clip_names(layer)}
    where = str(manifest.path)
    anchored = []
    for diagnostic in diagnostics:
        clip = next((by_name[n] for n in diagnostic.clips if n in by_name), None)
        if clip is not None:
            line, column = clip.line, clip.column
        elif any(n in in_layers for n in diagnostic.clips):
            line, column = manifest.locate(("layers",))
        else:
            line, column = manifest.locate(_RULE_ANCHORS.get(diagnostic.rule, ("clips",)))
        anchored.append(diagnostic.evolve(path=where, line=line, column=column))
    return anchored


def _layer_clip_names(layer: Layer) -> list[str]:
    if isinstance(layer, BetaSpace):
        return [s.name for s in layer.space.samples]
    return [clip.name for clip in layer.clips]
