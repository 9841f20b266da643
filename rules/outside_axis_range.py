"""outside-axis-range: measured values the axes cannot hold."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class OutsideAxisRange(Rule):
    """A clip measured outside an axis range cannot be placed where it belongs: engines clamp it
    to the border, so blends near it deliver the wrong motion. It is reported, never clamped
    silently. Widen the axis or trim/replace the clip.
    """

    slug = "outside-axis-range"
    code = "BS102"
    severity = "error"
    summary = "clip measured outside an axis range"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            for index, axis in enumerate(space.axes):
                value = sample.measured[index]
                if axis.contains(value):
                    continue
                yield self.report(
                    f"{sample.name} measures {axis.feature} {value:.4g}, outside the {axis.name} axis "
                    f"range [{axis.minimum:g}, {axis.maximum:g}]",
                    clips=[sample.name],
                    position=sample.position,
                    hint=f"widen axes.{axis.name} (min/max) or check the clip's units and `range:`",
                )
