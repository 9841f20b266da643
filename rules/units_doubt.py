"""units-doubt: clips of one skeleton read with different units or up axes."""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterator

from blendspace_pipeline.rules._agreement import close, most_agreed

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
            # The reading most clips agree with (counted over the distinct readings: a library is
            # thousands of clips of a few readings); the clips that do not agree with it are odd.
            # An up axis the file itself states is the file's (one rig exported Y up and Z up);
            # its unit must still agree (the same rest offsets in two units: one is wrong).
            read = [s for s in samples if s.up_source != "file"] or samples
            common = most_agreed(
                Counter(_reading(s) for s in read), lambda r: r[1], SAME_UNIT, lambda r: r[0]
            )
            odd = [s for s in samples if not _agree(_reading(s), common, any_up=s.up_source == "file")]
            if not odd:
                continue
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


# Units within 1 % of each other are one unit written two ways (`units: 0.0564` for CMU's
# 0.0254 / 0.45 = 0.05644...), not a second reading: the unit mix-ups this rule is for differ
# by 2.2x (CMU's unit and the inch) or more (inch and cm, cm and m).
SAME_UNIT = 0.01


def _reading(sample: SampleView) -> tuple[str, float]:
    return sample.up_axis, sample.meters_per_unit


def _agree(a: tuple[str, float], b: tuple[str, float], *, any_up: bool = False) -> bool:
    return (any_up or a[0] == b[0]) and close(a[1], b[1], SAME_UNIT)
