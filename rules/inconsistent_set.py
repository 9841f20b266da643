"""inconsistent-fps and inconsistent-skeleton: clips that do not belong in one blend."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class InconsistentFps(Rule):
    """Clips sampled at different rates blend fine in engines but usually reveal a mixed export
    (a 30 fps clip among 120 fps mocap); generated clips and cadence sync assume one rate.
    """

    slug = "inconsistent-fps"
    code = "BS107"
    severity = "info"
    summary = "clips with different frame rates"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        rates = Counter(round(s.fps, 3) for s in space.samples if not s.generated)
        if len(rates) < 2:
            return
        common = rates.most_common(1)[0][0]
        odd = [s.name for s in space.samples if round(s.fps, 3) != common and not s.generated]
        yield self.report(
            f"most clips run at {common:g} fps but {', '.join(odd)} do not",
            clips=odd,
            hint="re-export at one frame rate",
        )


class InconsistentSkeleton(Rule):
    """Blending needs the same joints in every clip. A clip whose joint names differ from the
    set's usual skeleton cannot be blended with the rest, mirrored against it, or interpolated.
    """

    slug = "inconsistent-skeleton"
    code = "BS108"
    severity = "warning"
    summary = "clips whose joints differ from the rest of the set"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        layouts = Counter(s.joint_names for s in space.samples if s.joint_names)
        if len(layouts) < 2:
            return
        common = layouts.most_common(1)[0][0]
        for sample in space.samples:
            if sample.joint_names and sample.joint_names != common:
                missing = sorted(set(common) - set(sample.joint_names))[:5]
                extra = sorted(set(sample.joint_names) - set(common))[:5]
                yield self.report(
                    f"{sample.name} has a different skeleton ({len(sample.joint_names)} joints vs {len(common)}; "
                    f"missing {missing or '-'}, extra {extra or '-'})",
                    clips=[sample.name],
                    position=sample.position,
                    hint="retarget the clip onto the set's skeleton before blending",
                )
