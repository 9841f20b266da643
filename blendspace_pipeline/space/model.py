"""The analysed blend space as data: measured clips, placed samples, triangles, layers.

Every later stage (rules, fixes, document, writers) reads these types; building them is the
pipeline's job (`pipeline/analysis.py`), checking them the rules' (`checks/`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendspace_pipeline.diagnostics import Diagnostic, Placeholder
from blendspace_pipeline.manifest import LoadedManifest
from blendspace_pipeline.manifest.models import ClipEntry, Mask
from blendspace_pipeline.motion.measure import Measurement
from blendspace_pipeline.space.geometry import AxisRange, normalise
from blendspace_pipeline.space.placement import Axis, place
from blendspace_pipeline.space.triangulate import triangulate


@dataclass
class MeasuredClip:
    """One animation of one file, measured, with where it came from in the manifest."""

    name: str
    source: Path
    entry: ClipEntry
    line: int
    column: int
    measurement: Measurement
    extra: dict[str, object] = field(default_factory=dict)

    @property
    def time_range(self) -> tuple[float, float] | None:
        """Seconds of the file this clip is: the entry's `range:`, or what `range: auto` chose."""
        if self.entry.range == "auto":
            return self.measurement.range_used
        return tuple(self.entry.range) if self.entry.range is not None else None  # type: ignore[return-value]


@dataclass
class Sample:
    """A clip placed in the space."""

    clip: MeasuredClip
    position: tuple[float, float]
    measured: tuple[float, float]
    generated: bool = False
    fix: str | None = None

    @property
    def name(self) -> str:
        return self.clip.name

    @property
    def snapping_error(self) -> tuple[float, float]:
        return (self.position[0] - self.measured[0], self.position[1] - self.measured[1])


@dataclass
class BlendSpace:
    """The analysed space: everything the rules, fixes and writers need."""

    manifest: LoadedManifest
    axes: tuple[Axis, Axis]
    samples: list[Sample]
    triangles: list[tuple[int, int, int]]
    diagnostics: list[Diagnostic] = field(default_factory=list)
    placeholders: list[Placeholder] = field(default_factory=list)
    layer_spaces: list[Layer] = field(default_factory=list)
    # The rules loaded for this manifest (plugins included), kept so that the fix loop's rounds
    # and the SARIF rule catalogue do not import every plugin again. It holds a
    # `checks.rule_engine.LoadedRules`; typed loosely so the space model does not depend on the
    # checks layer above it (`rule_engine.loaded_rules_of` reads it back with its type).
    rules: object | None = None

    @property
    def name(self) -> str:
        return self.manifest.model.name

    def all_diagnostics(self) -> list[Diagnostic]:
        """This space's findings and those of its beta layers (anchored in their own manifests)."""
        found = list(self.diagnostics)
        for layer in self.layer_spaces:
            if isinstance(layer, BetaSpace):
                found += layer.space.all_diagnostics()
        return found

    def axis_ranges(self) -> tuple[AxisRange, AxisRange]:
        return (
            AxisRange(self.axes[0].minimum, self.axes[0].maximum),
            AxisRange(self.axes[1].minimum, self.axes[1].maximum),
        )

    def normalised_positions(self) -> np.ndarray:
        points = np.array([s.position for s in self.samples], dtype=np.float64).reshape(-1, 2)
        return normalise(points, self.axis_ranges())


def axes_of(loaded: LoadedManifest) -> tuple[Axis, Axis]:
    axes = loaded.model.axes
    return (
        Axis("x", axes.x.feature, axes.x.min, axes.x.max, axes.x.divisions),
        Axis("y", axes.y.feature, axes.y.min, axes.y.max, axes.y.divisions),
    )


def place_samples(clips: list[MeasuredClip], axes: tuple[Axis, Axis]) -> list[Sample]:
    samples = []
    for clip in clips:
        placement = place(clip.measurement.features, axes)
        samples.append(Sample(clip=clip, position=placement.position, measured=placement.measured))
    return samples


def assemble(loaded: LoadedManifest, clips: list[MeasuredClip]) -> BlendSpace:
    """Placement and triangulation of measured clips, with the diagnostics of those stages."""
    axes = axes_of(loaded)
    samples = place_samples(clips, axes)
    space = BlendSpace(manifest=loaded, axes=axes, samples=samples, triangles=[])
    mesh = triangulate(space.normalised_positions())
    space.triangles = mesh.triangles
    return space


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
