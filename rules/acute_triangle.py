"""acute-triangle: sliver triangles whose weights jump for tiny input changes."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from blendspace_pipeline.rules._geometry import (
    ANGLE_MARGIN,
    angles,
    circumcenter,
    inside_rectangle,
    smallest_angles,
)

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView, placeholder


class AcuteTriangle(Rule):
    """A triangle with an angle below `thresholds.acute_angle` (degrees, strictly below; 15 is our
    default: the paper names the problem but gives no number), measured in normalised axis space,
    is a sliver: a long edge, a tiny area, and blend weights that change
    abruptly for small parameter changes (popping). The suggested placeholder is the triangle's
    circumcentre (the point Delaunay refinement inserts), or the middle of its longest edge when
    the circumcentre falls outside the axis rectangle.
    """

    slug = "acute-triangle"
    code = "BS002"
    severity = "warning"
    summary = "triangle with an angle below acute_angle"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        limit = space.thresholds["acute_angle"]
        # Only triangles whose numpy angle is near or below the limit (or not a number) are
        # measured exactly, in order: the findings of a loop over all of them.
        rough = smallest_angles(space.normalised_positions[space.triangle_array])
        for index in np.flatnonzero(~(rough >= limit + ANGLE_MARGIN)):
            tri = space.triangles[index]
            corners = [space.samples[i].normalised for i in tri]
            tri_angles = angles(*corners)
            smallest = min(tri_angles)
            if smallest >= limit:
                continue
            names = tuple(space.samples[i].name for i in tri)
            at = names[tri_angles.index(smallest)]
            centre = circumcenter(*corners)
            if centre is None or not inside_rectangle(centre):
                lengths = [
                    (
                        (corners[i][0] - corners[(i + 1) % 3][0]) ** 2
                        + (corners[i][1] - corners[(i + 1) % 3][1]) ** 2,
                        i,
                    )
                    for i in range(3)
                ]
                _, i = max(lengths)
                a, b = corners[i], corners[(i + 1) % 3]
                centre = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
            suggestion = space.to_axis_units(centre)
            yield self.report(
                f"triangle {' - '.join(names)} has a {smallest:.1f}° angle at {at} (below {limit:g}°)",
                clips=names,
                position=suggestion,
                hint=f"add a clip near ({suggestion[0]:.3g}, {suggestion[1]:.3g}) or move/remove one of these clips",
                placeholders=[
                    placeholder(
                        space, suggestion, "suggested", self.slug, f"repairs the sliver {' - '.join(names)}"
                    )
                ],
            )
