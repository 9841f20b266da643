"""foot-phase-mismatch: clips blended together whose feet plant at different points of the stride."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Field, Rule, RuleOptions, SpaceView


def _phase_distance(a: float, b: float) -> float:
    d = abs(a - b) % 1.0
    return min(d, 1.0 - d)


class FootPhaseMismatch(Rule):
    """Engines sync a blend by stride phase (or by foot-down markers). Two clips that share a
    triangle edge and are in step by the swing of their legs should also put each foot down at
    the same point of the stride; when one clip's left foot lands while the other's is still in
    the air (or the other's right foot lands), the blended foot hangs between a plant and a swing,
    slides, and at half a stride apart the blend crosses the legs. Each clip's foot-down phase
    (0..1 of a stride, from its foot contacts) is compared foot by foot; a difference above the
    threshold is reported. Re-cut the cycle of one clip so it starts on the same foot event as
    its neighbours, or mirror it if its feet are swapped; with marker sync
    (LeftFootDown/RightFootDown) the engine aligns the plants instead of the swing.
    """

    slug = "foot-phase-mismatch"
    code = "BS121"
    severity = "warning"
    summary = "clips blended together whose foot-down phases disagree"

    class Options(RuleOptions):
        threshold: float = Field(
            0.15,
            gt=0,
            le=0.5,
            description="Largest accepted difference of a foot's plant phase, in strides (0.5 = opposite).",
        )

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        assert self.options is not None and isinstance(self.options, self.Options)
        limit = self.options.threshold
        for i, j in space.edges():
            a, b = space.samples[i], space.samples[j]
            if a.plant_phases is None or b.plant_phases is None:
                continue
            feet = [f for f in ("left", "right") if f in a.plant_phases and f in b.plant_phases]
            if not feet:
                continue
            gaps = {f: _phase_distance(a.plant_phases[f], b.plant_phases[f]) for f in feet}
            worst = max(gaps, key=lambda f: gaps[f])
            if gaps[worst] <= limit:
                continue
            crossed = all(
                _phase_distance(a.plant_phases[f], b.plant_phases[o]) < limit
                for f, o in (("left", "right"), ("right", "left"))
                if f in a.plant_phases and o in b.plant_phases
            )
            what = (
                "the blend crosses the legs (one clip's left foot lands with the other's right)"
                if crossed
                else ("the blended foot slides between a plant and a swing")
            )
            middle = (0.5 * (a.position[0] + b.position[0]), 0.5 * (a.position[1] + b.position[1]))
            yield self.report(
                f"{a.name} and {b.name} plant the {worst} foot {gaps[worst]:.2f} of a stride apart "
                f"(at phase {a.plant_phases[worst]:.2f} vs {b.plant_phases[worst]:.2f}): {what}",
                clips=[a.name, b.name],
                position=middle,
                hint=f"re-cut the cycle of {b.name} (or {a.name}) so both start on the same foot event"
                + ("; mirroring one of them swaps its feet" if crossed else "")
                + "; marker sync (LeftFootDown/RightFootDown) aligns plants instead of the swing",
            )
