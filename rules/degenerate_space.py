"""degenerate-space and duplicate-position: layouts that cannot be triangulated well."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class DegenerateSpace(Rule):
    """Fewer than three distinct positions, or all samples on one line, leave the 2D space
    without triangles: the engine cannot blend anything. Add clips off the line.
    """

    slug = "degenerate-space"
    code = "BS104"
    severity = "error"
    summary = "no triangles: samples collinear or fewer than three distinct positions"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        if space.triangles or not space.samples:
            return
        distinct = {s.position for s in space.samples}
        reason = (
            f"only {len(distinct)} distinct position(s)"
            if len(distinct) < 3
            else "all samples lie on one line"
        )
        yield self.report(
            f"the blend space has no triangles: {reason}",
            clips=[s.name for s in space.samples],
            hint="a 2D blend space needs at least three clips that are not on one line; "
            "add clips that vary the other axis feature, or use a 1D blend",
        )


class DuplicatePosition(Rule):
    """Several samples snapped to exactly the same position: the engine keeps one of them and
    the others are dead weight (or the grid is too coarse to separate them).
    """

    slug = "duplicate-position"
    code = "BS105"
    severity = "warning"
    summary = "samples at the same snapped position"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        groups: dict[tuple[float, float], list[str]] = {}
        for sample in space.samples:
            groups.setdefault(sample.position, []).append(sample.name)
        for position, names in groups.items():
            if len(names) > 1:
                yield self.report(
                    f"{len(names)} clips share the position ({position[0]:g}, {position[1]:g}): {', '.join(names)}; "
                    f"the triangulation uses {names[0]}",
                    clips=names,
                    position=position,
                    hint="remove the extra clips, or raise the axes' `divisions` if they really differ",
                )
