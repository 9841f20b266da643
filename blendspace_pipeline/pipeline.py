"""The one place that knows the order of the build.

manifest → clip files → read + measure (cached) → placement → triangulation → rules → fixes →
document → writers. Each stage is a function of typed inputs; I/O happens only in the readers at
the start and the writers at the end, so `check` runs everything but the last step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from blendspace_pipeline.diagnostics import Diagnostic, Placeholder
from blendspace_pipeline.geometry import AxisRange, normalise
from blendspace_pipeline.layers import BetaSpace, Layer, analyse_layers
from blendspace_pipeline.manifest import LoadedManifest, load_manifest
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.measure_stage import MeasuredClip, measure_files
from blendspace_pipeline.placement import Axis, place
from blendspace_pipeline.triangulate import triangulate

if TYPE_CHECKING:
    from blendspace_pipeline.rule_engine import LoadedRules

Progress = Callable[[int, int, str], None]


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
    # and the SARIF rule catalogue do not import every plugin again.
    rules: LoadedRules | None = None

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


def analyse(
    manifest_path: Path, *, jobs: int = 1, progress: Progress | None = None, with_layers: bool = True
) -> BlendSpace:
    """Everything `check` does: read, measure, place, triangulate, analyse layers, run the rules."""
    loaded = load_manifest(manifest_path)
    files = resolve_clip_files(loaded)
    clips = measure_files(loaded, files, jobs=jobs, progress=progress)
    space = assemble(loaded, clips)
    if with_layers:
        space.layer_spaces = analyse_layers(space, jobs=jobs, progress=progress)
    finish_analysis(space)
    return space


def finish_analysis(space: BlendSpace) -> None:
    """Run the rules on an assembled space and anchor their findings at manifest lines."""
    from blendspace_pipeline.locate_diagnostics import anchor
    from blendspace_pipeline.rule_engine import run_rules

    run_rules(space)
    space.diagnostics = anchor(space, space.diagnostics)
