"""partial-stride: a stepping clip measured over less than one whole stride."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class PartialStride(Rule):
    """The pelvis turns with each step (a few degrees on a calm walk, up to 25 on a swaggering
    one), once a stride. Measured over whole strides that sway cancels; over part of one (a clip
    cut shorter than a stride, a short `range:`) it stays in the turn and the direction: a
    straight walk over 0.2 s read 19 deg/s. The clip is placed by those numbers, so it says so.
    """

    slug = "partial-stride"
    code = "BS113"
    severity = "warning"
    summary = "stepping clip measured over less than one stride: turn and direction keep the sway"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            if sample.partial_stride and not sample.generated:
                duration = sample.features.get("duration", 0.0)
                yield self.report(
                    f"{sample.name} steps, but its measured {duration:.2f} s hold no whole stride: its "
                    f"turn rate ({sample.features.get('turn_rate', 0.0):.1f}°/s) and direction "
                    f"({sample.features.get('direction', 0.0):.1f}°) keep the pelvis sway",
                    clips=[sample.name],
                    position=sample.position,
                    hint="measure one whole stride or more: widen its `range:` (or use `range: auto` on a "
                    "longer take), or export the whole cycle",
                )
