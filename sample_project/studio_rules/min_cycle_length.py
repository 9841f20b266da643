"""A worked studio rule: locomotion clips must hold at least one second of motion.

Our (fictional) studio's foot-IK warms up over the first frames of a clip, and clips under a
second blend with visible foot pops. This is the kind of house rule a studio keeps next to its
assets; it is loaded through the manifest's `plugins:` list and uses only the public
`blendspace_pipeline.api`, exactly like the built-in rules.
"""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class MinCycleLength(Rule):
    """Moving clips shorter than `MIN_SECONDS` (1 s) pop when our foot-IK re-plants the feet.
    Idles and turns in place are exempt (no feet to re-plant at speed). Re-export a longer take,
    or loop the clip twice in the DCC.
    """

    slug = "studio-min-cycle-length"
    code = "ST001"
    severity = "warning"
    summary = "moving clip shorter than one second"

    MIN_SECONDS = 1.0
    MOVING = 0.2  # m/s: below this the clip counts as standing

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            duration = sample.features["duration"]
            if abs(sample.features["speed"]) >= self.MOVING and duration < self.MIN_SECONDS - 1e-6:
                yield self.report(
                    f"{sample.name} lasts {duration:.2f} s; our foot-IK needs {self.MIN_SECONDS:.0f} s",
                    clips=[sample.name],
                    position=sample.position,
                    hint="export a longer take, or loop the cycle twice in the DCC",
                )
