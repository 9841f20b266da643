"""missing-opposite: a turning or sidestepping clip whose mirror image is not in the set."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import any_closer_each, distance

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView, placeholder

# Features whose sign flips when the motion is mirrored across the character's sagittal plane.
MIRROR_FLIPS = frozenset({"turn_rate", "turn", "direction", "lateral_speed"})


class MissingOpposite(Rule):
    """A clip that turns (or steps sideways) one way has no counterpart near its mirrored
    position, so the character turns better to one side than the other and the triangulation
    on the empty side stretches across the space. Mirroring the clip across the character's
    sagittal plane (left/right joints swapped) makes the opposite; the build does that when
    `fixes.mirror` is on. A counterpart counts as present when a sample lies within
    `thresholds.too_close` (normalised) of the mirrored position. Only axes driven by a
    mirror-odd feature (turn_rate, turn, direction, lateral_speed) are mirrored.
    """

    slug = "missing-opposite"
    code = "BS109"
    severity = "warning"
    summary = "turning or sidestepping clip without its mirror image"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        signs = tuple(-1.0 if axis.feature in MIRROR_FLIPS else 1.0 for axis in space.axes)
        if signs == (1.0, 1.0):
            return
        near = space.thresholds["too_close"]
        on_axis = space.thresholds["misalignment"]
        mirrors = [(s.position[0] * signs[0], s.position[1] * signs[1]) for s in space.samples]
        targets = [space.to_normalised(mirrored) for mirrored in mirrors]
        # Whether some sample lies near each mirrored position, all at once (k-d tree, exact).
        taken = any_closer_each([other.normalised for other in space.samples], targets, near)
        for sample, mirrored, target, near_one in zip(space.samples, mirrors, targets, taken, strict=True):
            if distance(target, sample.normalised) <= 2.0 * on_axis:
                continue  # on the mirror axis: it is its own opposite
            if not all(axis.contains(value) for axis, value in zip(space.axes, mirrored, strict=True)):
                continue
            if near_one:
                continue
            yield self.report(
                f"{sample.name} has no mirrored counterpart near ({mirrored[0]:.3g}, {mirrored[1]:.3g})",
                clips=[sample.name],
                position=mirrored,
                hint="author the opposite clip, or let the build mirror this one (fixes.mirror: true)",
                fix="mirror",
                fix_data={"source": sample.name, "position": list(mirrored)},
                placeholders=[
                    placeholder(space, mirrored, "suggested", self.slug, f"mirror of {sample.name}")
                ],
            )
