"""crossing-axis: triangle edges that blend opposite motions across a main axis."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import distance, main_axes

from blendspace_pipeline.api import Diagnostic, Placeholder, Rule, SpaceView, placeholder


class CrossingAxis(Rule):
    """A triangle edge crossing a main axis (speed = 0 or turning = 0, the lines through idle)
    blends opposite motions, forward with backward or left with right turns, which gives
    abnormal feet. Edges whose two ends both lie farther than `thresholds.crossing_axis`
    (normalised units; τχ = 5 is the paper's value) from the axis they cross are reported (an
    end exactly τχ away counts as on the axis). The cure is key clips on the axes, at the
    extremes the authored set covers (paper §3.2a): idle, turn in place at ± the largest turn
    rate any authored clip has, and the fastest forward and fastest backward authored speeds at
    zero turn; never fixed fractions of the axis range. A key position counts as held when a
    clip lies within τχ of it. The automatic fix bakes an interpolated clip where the edge crosses.
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
        keys = key_positions(space)
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


def key_positions(space: SpaceView) -> list[tuple[tuple[float, float], str]]:
    """The key clips the method asks for, as (position in axis units, label).

    They are the extremes the authored set covers on each main axis (generated clips do not
    stretch the set: a mirror repeats an authored extreme): idle; turn in place at ± the largest
    |x| of any authored clip; the fastest forward and the fastest backward authored y at x = 0
    (placed positions: the grid points the engine holds). Turns in place are asked for only when
    the set turns farther than τχ from the axis.
    Only when both main axes cross the rectangle (otherwise there is no idle to anchor them).
    """
    x_axis, y_axis = space.axes
    if not (x_axis.minimum <= 0.0 <= x_axis.maximum and y_axis.minimum <= 0.0 <= y_axis.maximum):
        return []
    authored = [s for s in space.samples if not s.generated] or list(space.samples)
    keys: list[tuple[tuple[float, float], str]] = [((0.0, 0.0), "idle")]
    reach = max((abs(s.position[0]) for s in authored), default=0.0)
    tau = space.thresholds["crossing_axis"]
    if reach > 0.0 and space.to_normalised((reach, 0.0))[0] - space.to_normalised((0.0, 0.0))[0] > tau:
        for side in (-1.0, 1.0):
            value = min(max(side * reach, x_axis.minimum), x_axis.maximum)
            if value != 0.0:
                keys.append(((value, 0.0), f"{x_axis.feature} {value:+.3g} in place (largest authored)"))
    ys = [s.position[1] for s in authored]
    top, bottom = max(ys, default=0.0), min(ys, default=0.0)
    if top > 0.0:
        keys.append(
            ((0.0, min(top, y_axis.maximum)), f"fastest {y_axis.feature} forward at {x_axis.feature} 0")
        )
    if bottom < 0.0:
        keys.append(
            ((0.0, max(bottom, y_axis.minimum)), f"fastest {y_axis.feature} backward at {x_axis.feature} 0")
        )
    return keys
