"""axis-zero-off-grid: an axis whose zero is not a grid point."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class AxisZeroOffGrid(Rule):
    """When 0 lies inside an axis range but is not a grid value, idle and the key clips on the
    main axes cannot be placed on those axes: they snap beside them, and edges then cross the
    axes. Choose `divisions` so that (0 - min) / (max - min) * divisions is a whole number.
    """

    slug = "axis-zero-off-grid"
    code = "BS106"
    severity = "warning"
    summary = "axis range contains 0 but 0 is not a grid point"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for axis in space.axes:
            if axis.inside(0.0) and not axis.zero_on_grid():
                yield self.report(
                    f"axis {axis.name} ({axis.feature} {axis.minimum:g}..{axis.maximum:g}, {axis.divisions} divisions) "
                    f"has no grid point at 0; nearest is {axis.snap(0.0):g}",
                    hint=f"pick divisions so that {-axis.minimum:g}/{axis.step * axis.divisions:g} x divisions is whole",
                )
