"""A worked studio rule: locomotion clips must hold at least one second of motion.

Our (fictional) studio's foot-IK warms up over the first frames of a clip, and clips under a
second blend with visible foot pops. This is the kind of house rule a studio keeps next to its
assets; it is loaded through the manifest's `plugins:` list and uses only the public
`blendspace_pipeline.api`, exactly like the built-in rules. Its limit is a typed option, set in
the manifest under `rules: {options: {studio-min-cycle-length: {min_seconds: 1.0}}}`.
"""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Field, Rule, RuleOptions, SpaceView


class MinCycleLengthOptions(RuleOptions):
    min_seconds: float = Field(1.0, gt=0, description="Shortest moving clip our foot-IK accepts, seconds.")
    moving: float = Field(0.2, ge=0, description="Speed (m/s) below which a clip counts as standing.")


class MinCycleLength(Rule):
    """Moving clips shorter than `min_seconds` (default 1 s) pop when our foot-IK re-plants the
    feet. Idles and turns in place are exempt (no feet to re-plant at speed). Re-export a longer
    take, or loop the clip twice in the DCC.
    """

    slug = "studio-min-cycle-length"
    code = "ST001"
    severity = "warning"
    summary = "moving clip shorter than min_seconds (1 s)"
    Options = MinCycleLengthOptions

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        options = self.options
        assert isinstance(options, MinCycleLengthOptions)  # the engine validated it
        for sample in space.samples:
            duration = sample.features["duration"]
            if abs(sample.features["speed"]) >= options.moving and duration < options.min_seconds - 1e-6:
                yield self.report(
                    f"{sample.name} lasts {duration:.2f} s; our foot-IK needs {options.min_seconds:g} s",
                    clips=[sample.name],
                    position=sample.position,
                    hint="export a longer take, or loop the cycle twice in the DCC",
                )
