"""cadence-mismatch: clips blended together whose gait periods are far apart."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Field, Rule, RuleOptions, SpaceView


class CadenceMismatch(Rule):
    """Two clips that share a triangle edge are blended together, and an engine syncs their
    strides: between them each plays faster or slower than authored so both cover one stride in
    the same time. When their stride periods differ a lot (a 0.8 s run stride next to a 0.5 s
    one), the blend's legs run at a rate neither clip was made for, its root speed and turn rate
    drift from what the position promises, and its feet slide. The difference is the longer
    period over the shorter one, minus one; a clip without a gait (idle, turning on the spot) is
    not compared. Retime one clip (resample it so its stride matches its neighbour's, keeping its
    root speed by scaling the stride length), re-cut its cycle to another number of strides, or
    add a clip with an intermediate cadence between them.
    """

    slug = "cadence-mismatch"
    code = "BS120"
    severity = "warning"
    summary = "clips blended together whose gait periods differ beyond a threshold"

    class Options(RuleOptions):
        threshold: float = Field(
            0.25, gt=0, description="Largest accepted difference of stride periods (longer / shorter - 1)."
        )

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        assert self.options is not None and isinstance(self.options, self.Options)
        limit = self.options.threshold
        for i, j in space.edges():
            a, b = space.samples[i], space.samples[j]
            if a.gait_period is None or b.gait_period is None or min(a.gait_period, b.gait_period) <= 0:
                continue
            slow, fast = (a, b) if a.gait_period >= b.gait_period else (b, a)
            assert slow.gait_period is not None and fast.gait_period is not None
            difference = slow.gait_period / fast.gait_period - 1.0
            if difference <= limit:
                continue
            middle = (0.5 * (a.position[0] + b.position[0]), 0.5 * (a.position[1] + b.position[1]))
            yield self.report(
                f"{slow.name} ({slow.gait_period:.2f} s stride) and {fast.name} ({fast.gait_period:.2f} s "
                f"stride) are blended together but their cadences differ by {difference:.0%} "
                f"(threshold {limit:.0%})",
                clips=[slow.name, fast.name],
                position=middle,
                hint=f"retime {slow.name} towards a {fast.gait_period:.2f} s stride (or {fast.name} "
                f"towards {slow.gait_period:.2f} s), re-cut one cycle to another number of strides, or "
                "add a clip with an intermediate cadence between them",
            )
