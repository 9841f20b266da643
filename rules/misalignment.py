"""misalignment: clips meant for a main axis that sit slightly off it, or off their `expect:`."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import main_axes

from blendspace_pipeline.api import FEATURE_UNITS, Diagnostic, Rule, SampleView, SpaceView, placeholder

# How far a measured feature may be from its `expect:` value before it is reported.
EXPECT_TOLERANCE = {"m/s": 0.05, "deg/s": 1.5, "deg": 2.0, "s": 0.05}


# Offsets below this (normalised units, 1e-4 of the axis range) are measurement noise, not a
# turn: ours, not the paper's; far below a grid step or anything a viewer can show.
NOISE = 0.01


class Misalignment(Rule):
    """A clip whose measured (unsnapped) position is off a main axis by more than measurement
    noise (`NOISE`) and at most `thresholds.misalignment` (normalised units, inclusive; 3 is our
    default, the paper gives no number), for example a "run forward" that turns a little.
    The offset is measured, never snapped: a drift smaller than half a grid step snaps onto the
    axis in the engine but is still a turning clip at a key position. Exact placement keeps the
    trajectory right, but the axis then lacks its key clip. Clips whose measurement differs from
    their `expect:` values are reported too (`EXPECT_TOLERANCE`: our numbers, about a 1% speed
    error of a walk, and a turn error below what a viewer notices). The necessary placeholder sits
    at the intended position.
    """

    slug = "misalignment"
    code = "BS003"
    severity = "warning"
    summary = "clip just off a main axis, or off its expect: values"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["misalignment"]
        lines = main_axes(space)
        for sample in space.samples:
            # Generated clips are checked like authored ones: a merge of a turning and a straight
            # walk turns a little, and must get the same verdict when fed back as a source.
            covered: set[str] = set()  # expect: features this finding already speaks for
            for axis_index, line in enumerate(lines):
                if line is None:
                    continue
                axis = space.axes[axis_index]
                offset = abs(space.to_normalised(sample.measured)[axis_index] - line)
                if offset <= NOISE or offset > tau:
                    continue
                intended = list(sample.measured)
                intended[axis_index] = 0.0
                # An `expect: {feature: 0}` says the same thing: one finding, not two.
                expected = sample.expect.get(axis.feature) == 0 if sample.expect else False
                if expected:
                    covered.add(axis.feature)
                yield self.report(
                    f"{sample.name} sits {sample.measured[axis_index]:+.3g} {FEATURE_UNITS.get(axis.feature, '')} "
                    f"off the {axis.feature} = 0 axis ({offset:.2f} normalised, at most {tau:g})"
                    + (f"; its expect: says {axis.feature} 0" if expected else ""),
                    clips=[sample.name],
                    position=sample.position,
                    hint=f"if {sample.name} is meant to have {axis.feature} 0, re-author it straight "
                    "(or enable fixes.straighten); otherwise set `expect:` to say so",
                    fix="straighten" if axis.feature in ("turn_rate", "turn") else None,
                    fix_data={"axis": axis.name},
                    placeholders=[
                        placeholder(
                            space, intended, "necessary", self.slug, f"straight version of {sample.name}"
                        )
                    ],
                )
            yield from self._expectations(space, sample, covered)

    def _expectations(self, space: SpaceView, sample: SampleView, covered: set[str]) -> Iterator[Diagnostic]:
        if not sample.expect:
            return
        for feature, wanted in sorted(sample.expect.items()):
            if feature in covered:
                continue
            measured = sample.features.get(feature)
            if measured is None:
                continue
            unit = FEATURE_UNITS.get(feature, "")
            if abs(measured - wanted) <= EXPECT_TOLERANCE.get(unit, 0.05):
                continue
            intended = [
                wanted if axis.feature == feature else sample.position[i] for i, axis in enumerate(space.axes)
            ]
            yield self.report(
                f"{sample.name} measures {feature} {measured:.3g} {unit} but expects {wanted:g}",
                clips=[sample.name],
                position=sample.position,
                hint=f"re-author {sample.name} to match, or correct its `expect:` in the manifest",
                placeholders=[
                    placeholder(
                        space,
                        intended,
                        "necessary",
                        self.slug,
                        f"{sample.name} as intended ({feature} {wanted:g})",
                    )
                ],
            )
