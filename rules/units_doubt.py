"""units-doubt: clips of one skeleton read with different units or up axes."""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SampleView, SpaceView


class UnitsDoubt(Rule):
    """Clips that share a skeleton (same joint names, hierarchy and rest offsets) come from one
    rig and one export, so they must be read with one up axis and one length unit. When they
    are not (a per-entry `skeleton:` override on some of them, or evidence that differs from
    clip to clip), at least one set of speeds is wrong by the ratio of the units. The finding
    names the clips that differ from the rest; guesses themselves are `detection-guess`.
    """

    slug = "units-doubt"
    code = "BS103"
    severity = "error"
    summary = "clips of one skeleton read with different units or up axes"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        groups: dict[str, list[SampleView]] = defaultdict(list)
        for sample in space.samples:
            if sample.skeleton_key and not sample.generated:
                groups[sample.skeleton_key].append(sample)
        for samples in groups.values():
            readings = Counter(_reading(s) for s in samples)
            if len(readings) < 2:
                continue
            common, _count = readings.most_common(1)[0]
            odd = [s for s in samples if _reading(s) != common]
            details = ", ".join(
                f"{s.name} ({s.up_axis.upper()} up, {s.meters_per_unit:.4g} m/unit, {s.units_source})"
                for s in odd
            )
            yield self.report(
                f"{len(samples)} clips share one skeleton but {details} differ from the rest "
                f"({common[0].upper()} up, {common[1]:.4g} m/unit)",
                clips=[s.name for s in odd],
                hint="set the same `skeleton: {units: ..., up: ...}` for all of them (top level or per entry)",
            )


def _reading(sample: SampleView) -> tuple[str, float]:
    return sample.up_axis, round(sample.meters_per_unit, 9)
