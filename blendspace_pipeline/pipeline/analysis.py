"""The one place that knows the order of the build.

manifest → clip files → read + measure (cached) → placement → triangulation → layers → rules →
fixes → document → writers. Each stage is a function of typed inputs; I/O happens only in the
readers at the start and the writers at the end, so `check` runs everything but the last step.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from blendspace_pipeline.checks.locate_diagnostics import anchor
from blendspace_pipeline.checks.rule_engine import run_rules
from blendspace_pipeline.manifest import load_manifest
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.pipeline.layers import analyse_layers
from blendspace_pipeline.pipeline.measure_stage import measure_files
from blendspace_pipeline.pipeline.own_outputs import authored
from blendspace_pipeline.pipeline.placeholders import converge_placeholders
from blendspace_pipeline.pipeline.progress import Progress
from blendspace_pipeline.space.model import BlendSpace, assemble


def analyse(
    manifest_path: Path,
    *,
    jobs: int = 1,
    progress: Progress | None = None,
    with_layers: bool = True,
    converge: bool = True,
    on_placed: Callable[[BlendSpace], None] | None = None,
    out: Path | None = None,
    while_converging: Callable[[BlendSpace], None] | None = None,
) -> BlendSpace:
    """Everything `check` does: read, measure, place, triangulate, analyse layers, run the rules.

    ``converge``: check the suggested placeholders by simulation (`placeholders`); `build` leaves
    it to the end of the fix loop, whose last space is the one it reports.
    ``on_placed``: called with the space once it is placed, triangulated and has its layers,
    before the rules (`build` starts the blend quality maps there: `early_quality`).
    ``out``: the build's --out (else the manifest's `output.dir`): the clips its last build placed
    there are outputs, not takes, when a glob of `clips:` reaches them (`own_outputs.authored`).
    ``while_converging``: work done while the placeholder simulations run in other processes
    (`converge_placeholders`' ``meanwhile``).
    """
    loaded = load_manifest(manifest_path)
    files = authored(loaded, resolve_clip_files(loaded), out)
    clips = measure_files(loaded, files, jobs=jobs, progress=progress)
    space = assemble(loaded, clips)
    if with_layers:

        def analyse_beta(path: Path) -> BlendSpace:
            return analyse(path, jobs=jobs, progress=progress, with_layers=False, converge=converge)

        space.layer_spaces = analyse_layers(space, analyse_beta, jobs=jobs, progress=progress)
    if on_placed is not None:
        on_placed(space)
    finish_analysis(space)
    if converge:
        converge_placeholders(space, jobs=jobs, meanwhile=while_converging)
    return space


def finish_analysis(space: BlendSpace) -> None:
    """Run the rules on an assembled space and anchor their findings at manifest lines."""
    run_rules(space)
    space.diagnostics = anchor(space, space.diagnostics)
