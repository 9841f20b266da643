"""crossing-axis: triangle edges that blend opposite motions across a main axis."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import distance, main_axes

from blendspace_pipeline.api import Diagnostic, Placeholder, Rule, SpaceView, placeholder


class CrossingAxis(Rule):
    """A triangle edge crossing a main axis (speed = 0 or turning = 0, the lines through idle)
    blends opposite motions, forward with backward or left with right turns, which gives
    abnormal feet. Edges whose two ends both lie farther than `thresholds.crossing_axis`
    (normalised units, paper: 5) from the axis they cross are reported. The cure is key clips on
    the axes: idle, turn in place at ±half the turn range, and the fastest forward and backward
    clips at zero turn. The automatic fix bakes an interpolated clip where the edge crosses.
    """

    slug = "crossing-axis"
    code = "BS001"
    severity = "error"
    summary = "triangle edge crossing a main axis with both ends away from it"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["crossing_axis"]
        x0, y0 = main_axes(space)
        found = False
        for a, b in space.edges():
            pa, pb = space.samples[a].normalised, space.samples[b].normalised
            for axis_index, line in ((0, x0), (1, y0)):
                if line is None:
                    continue
                da, db = pa[axis_index] - line, pb[axis_index] - line
                if da * db >= 0 or min(abs(da), abs(db)) <= tau:
                    continue
                found = True
                yield self._crossing(space, a, b, axis_index, line)
        if found:
            yield from self._missing_key_clips(space)

    def _crossing(self, space: SpaceView, a: int, b: int, axis_index: int, line: float) -> Diagnostic:
        pa, pb = space.samples[a].normalised, space.samples[b].normalised
        t = (line - pa[axis_index]) / (pb[axis_index] - pa[axis_index])
        cross_norm = (pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1]))
        along = space.to_axis_units(cross_norm)
        point = (0.0, round(along[1], 9)) if axis_index == 0 else (round(along[0], 9), 0.0)
        axis = space.axes[axis_index]
        names = (space.samples[a].name, space.samples[b].name)
        return self.report(
            f"edge {names[0]} - {names[1]} crosses {axis.feature} = 0 at "
            f"({point[0]:.3g}, {point[1]:.3g}): it blends opposite motions",
            clips=names,
            position=point,
            hint=f"add a clip with {axis.feature} = 0 near ({point[0]:.3g}, {point[1]:.3g}), "
            "or let the build bake one (fixes.axis_clips)",
            fix="axis-clip",
            fix_data={"edge": [names[0], names[1]], "axis": axis.name, "point": list(point)},
            placeholders=[
                placeholder(space, point, "necessary", self.slug, f"crossing of edge {names[0]} - {names[1]}")
            ],
        )

    def _missing_key_clips(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["crossing_axis"]
        x_axis, y_axis = space.axes
        keys: list[tuple[tuple[float, float], str]] = []
        if x_axis.minimum <= 0.0 <= x_axis.maximum and y_axis.minimum <= 0.0 <= y_axis.maximum:
            keys.append(((0.0, 0.0), "idle"))
            if x_axis.minimum < 0.0:
                keys.append(
                    ((x_axis.minimum / 2.0, 0.0), f"{x_axis.feature} {x_axis.minimum / 2:g} in place")
                )
            if x_axis.maximum > 0.0:
                keys.append(
                    ((x_axis.maximum / 2.0, 0.0), f"{x_axis.feature} {x_axis.maximum / 2:g} in place")
                )
            ys = [s.position[1] for s in space.samples]
            if any(y > 0 for y in ys):
                keys.append(((0.0, max(ys)), f"fastest {y_axis.feature} forward at {x_axis.feature} 0"))
            if any(y < 0 for y in ys):
                keys.append(((0.0, min(ys)), f"fastest {y_axis.feature} backward at {x_axis.feature} 0"))
        for position, label in keys:
            target = space.to_normalised(position)
            if any(distance(s.normalised, target) <= tau for s in space.samples):
                continue
            mark: Placeholder = placeholder(
                space, position, "necessary", self.slug, f"missing key clip: {label}"
            )
            yield self.report(
                f"key clip missing on the main axes: {label} at ({position[0]:g}, {position[1]:g})",
                position=position,
                hint="key clips on the axes keep triangle edges from crossing them; "
                "author one or let mirroring/axis-clip fixes make it",
                placeholders=[mark],
            )
