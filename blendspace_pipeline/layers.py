"""Beta and style layers: the extra dimensions of paper §4, analysed like the main space.

A **beta** layer is a second blend space (BS2, e.g. lateral steps) in its own manifest on the same
axes; it is analysed by the same pipeline (its own rules, its own diagnostics anchored in its own
manifest) and blended with the main space by beta in [0, 1]. A **style** layer is a 1D space of
clips over one feature of the main space (the speed axis when there is one), mixed in by an
intensity, optionally through a per-joint mask (MechWarrior's feathering). The layer rules in
`rules/layer_checks.py` see both through `SpaceView.layers`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline.errors import ManifestError
from blendspace_pipeline.manifest.models import BetaLayer, ClipEntry, Mask, StyleLayer
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.measure_stage import MeasuredClip, measure_files
from blendspace_pipeline.placement import Axis

if TYPE_CHECKING:
    from blendspace_pipeline.pipeline import BlendSpace, Progress


@dataclass
class StyleSpace:
    """A style layer: clips placed on one axis of the main space."""

    name: str
    index: int  # position in the manifest's `layers:` list
    axis: Axis
    clips: list[MeasuredClip]
    positions: list[float]
    mask: Mask | None


@dataclass
class BetaSpace:
    """A beta layer: a whole second blend space, analysed on its own."""

    name: str
    index: int
    manifest: Path
    space: BlendSpace
    axes_match: bool
    notes: list[str] = field(default_factory=list)


Layer = StyleSpace | BetaSpace


def style_axis(axes: tuple[Axis, Axis]) -> Axis:
    """The main-space axis a style is laid out on: speed when an axis measures it, else y."""
    for axis in axes:
        if axis.feature == "speed":
            return axis
    return axes[1]


def analyse_layers(space: BlendSpace, *, jobs: int = 1, progress: Progress | None = None) -> list[Layer]:
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
            layers.append(_beta(space, layer, index, jobs, progress))
    return layers


def _style(
    space: BlendSpace, layer: StyleLayer, index: int, jobs: int, progress: Progress | None
) -> StyleSpace:
    entries = [ClipEntry(path=item) if isinstance(item, str) else item for item in layer.clips]
    files = resolve_clip_files(space.manifest, entries=entries, key=("layers", index, "clips"))
    clips = measure_files(space.manifest, files, jobs=jobs, progress=progress)
    axis = style_axis(space.axes)
    positions = [axis.snap(clip.measurement.features[axis.feature]) for clip in clips]
    return StyleSpace(layer.name, index, axis, clips, positions, layer.mask)


def _beta(space: BlendSpace, layer: BetaLayer, index: int, jobs: int, progress: Progress | None) -> BetaSpace:
    from blendspace_pipeline.pipeline import analyse

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
    if path.resolve() == loaded.path.resolve():
        raise fail(
            "it points at this manifest itself",
            "a beta layer is a second manifest (e.g. lateral.yaml) with its own clips",
        )
    sub = analyse(path, jobs=jobs, progress=progress, with_layers=False)
    if sub.manifest.model.layers:
        raise fail(
            f"{layer.manifest} has layers of its own; layers do not nest",
            f"remove `layers:` from {layer.manifest}, or add its layers to this manifest",
        )
    match = [(a.feature, a.minimum, a.maximum) for a in sub.axes] == [
        (a.feature, a.minimum, a.maximum) for a in space.axes
    ]
    return BetaSpace(layer.name, index, path, sub, match)
