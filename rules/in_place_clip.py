"""in-place-clip: clips with no root motion would sit silently at the origin."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class InPlaceClip(Rule):
    """A clip with no measurable root motion (ground speed below 0.05 m/s and turn rate below
    3°/s) lands at the origin. That is right for an idle, and wrong for a locomotion clip
    exported "in place" (root motion stripped), which then hides the idle and makes characters
    slide. Idles should say so with `ignore: [{rule: in-place-clip, reason: ...}]`.
    """

    slug = "in-place-clip"
    code = "BS101"
    severity = "warning"
    summary = "clip without root motion"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            if sample.in_place and not sample.generated:
                yield self.report(
                    f"{sample.name} has no root motion (speed {sample.features['speed']:.3f} m/s, "
                    f"turn rate {sample.features['turn_rate']:.2f}°/s): it sits at the origin",
                    clips=[sample.name],
                    position=sample.position,
                    hint="if it is an idle, add `ignore: [{rule: in-place-clip, reason: idle}]` to its entry; "
                    "otherwise export it with root motion (not 'in place')",
                )
