"""units-doubt: a length unit or up axis the tool had to guess."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class UnitsDoubt(Rule):
    """The clip's file does not state its length unit (BVH never does) and the hip height did
    not match metres, centimetres, millimetres or inches, so the unit was estimated from a
    0.9 m hip height. Speeds may be off by the ratio of the real hip height to that reference.
    Set `skeleton.units` (a unit name or metres per unit) to be exact.
    """

    slug = "units-doubt"
    code = "BS103"
    severity = "warning"
    summary = "length unit guessed from the skeleton's size"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            if sample.units_guessed and not sample.generated:
                yield self.report(
                    f"{sample.name}: unknown length unit, estimated {sample.meters_per_unit:.4g} m per unit "
                    "from the hip height",
                    clips=[sample.name],
                    position=sample.position,
                    hint="set `skeleton.units` in the manifest (m, cm, mm, in, or metres per unit as a number)",
                )
