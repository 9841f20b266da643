"""Beta and style layers: the extra dimensions of paper §4, analysed like the main space.

A **beta** layer is a second blend space (BS2, e.g. lateral steps) in its own manifest on the same
axes; it is analysed by the same pipeline (its own rules, its own diagnostics anchored in its own
manifest) and blended with the main space by beta in [0, 1]. A **style** layer is a 1D space of
clips over one feature of the main space (the speed axis when there is one), mixed in by an
intensity, optionally through a per-joint mask (MechWarrior's feathering). The layer rules in
`rules/layer_checks.py` see both through `SpaceView.layers`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from blendspace_pipeline.errors import ManifestError
from blendspace_pipeline.manifest.models import BetaLayer, StyleLayer
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.pipeline.measure_stage import measure_files
from blendspace_pipeline.pipeline.progress import Progress
from blendspace_pipeline.readers import supported_suffixes
from blendspace_pipeline.space.model import BetaSpace, BlendSpace, Layer, StyleSpace, style_axis

# Analyses a beta layer's own manifest (without layers of its own): the pipeline passes its
# `analyse` in, so this module does not import the pipeline back.
AnalyseBeta = Callable[[Path], BlendSpace]


def analyse_layers(
    space: BlendSpace, analyse_beta: AnalyseBeta, *, jobs: int = 1, progress: Progress | None = None
) -> list[Layer]:
    loaded = space.manifest
    layers: list[Layer] = []
    seen: dict[str, int] = {}
    for index, layer in enumerate(loaded.model.layers):
        if layer.name in seen:  # `eval --layer NAME=VALUE` and the USD prims need one layer a name
            raise loaded.error_at(
                ("layers", index, "name"),
                f"layers: the name {layer.name!r} is already used by layer {seen[layer.name] + 1}",
                "give every layer its own name",
            )
        seen[layer.name] = index
        if isinstance(layer, StyleLayer):
            layers.append(_style(space, layer, index, jobs, progress))
        elif isinstance(layer, BetaLayer):
            layers.append(_beta(space, layer, index, analyse_beta))
    return layers


def _style(
    space: BlendSpace, layer: StyleLayer, index: int, jobs: int, progress: Progress | None
) -> StyleSpace:
    files = resolve_clip_files(space.manifest, entries=layer.entries(), key=("layers", index, "clips"))
    clips = measure_files(space.manifest, files, jobs=jobs, progress=progress, part=f"layer {layer.name}")
    axis = style_axis(space.axes)
    positions = [axis.snap(clip.measurement.features[axis.feature]) for clip in clips]
    return StyleSpace(layer.name, index, axis, clips, positions, layer.mask)


def _beta(space: BlendSpace, layer: BetaLayer, index: int, analyse_beta: AnalyseBeta) -> BetaSpace:
    loaded = space.manifest
    path = loaded.path.parent / Path(layer.manifest.replace("\\", "/"))
    line, column = loaded.locate(("layers", index, "manifest"))

    def fail(message: str, hint: str) -> ManifestError:
        return ManifestError(
            f"beta layer {layer.name!r}: {message}", path=loaded.path, line=line, column=column, hint=hint
        )

    if not path.is_file():
        raise fail(
            f"manifest {layer.manifest} not found (looked at {path})", "the path is relative to this manifest"
        )
    if path.suffix.lower() in supported_suffixes():  # a clip named here read as "invalid YAML"
        raise fail(
            f"{layer.manifest} is a clip file, not a manifest (a beta layer's manifest lists its clips)",
            "point `manifest:` at a second manifest (e.g. lateral.yaml) that lists the layer's clips",
        )
    if path.resolve() == loaded.path.resolve():
        raise fail(
            "it points at this manifest itself",
            "a beta layer is a second manifest (e.g. lateral.yaml) with its own clips",
        )
    sub = analyse_beta(path)
    if sub.manifest.model.layers:
        raise fail(
            f"{layer.manifest} has layers of its own; layers do not nest",
            f"remove `layers:` from {layer.manifest}, or add its layers to this manifest",
        )
    match = [(a.feature, a.minimum, a.maximum) for a in sub.axes] == [
        (a.feature, a.minimum, a.maximum) for a in space.axes
    ]
    return BetaSpace(layer.name, index, path, sub, match)
