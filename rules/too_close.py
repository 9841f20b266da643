"""too-close: samples so close that they add cost and flip-flop between styles."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import distance

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView, placeholder


class TooClose(Rule):
    """Samples closer than `thresholds.too_close` (normalised units; τd = 8 is the paper's value;
    a pair exactly τd apart is not too close) are grouped into clusters (single linkage); each
    cluster is one finding. Keep one representative (the clip nearest the cluster centre) or
    replace the cluster by their interpolation (`fixes.too_close`). The suggested placeholder is
    where the merged clip would go (the paper's green marker): the mean of the members' measured
    positions. The fix never drops a key clip (on a main axis, or a hull corner).
    """

    slug = "too-close"
    code = "BS004"
    severity = "warning"
    summary = "samples closer than too_close"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["too_close"]
        # Clusters: samples linked by chains of pairs closer than tau (a k-d tree finds the pairs).
        clusters = {members[0]: members for members in space.close_groups(tau)}
        for members in clusters.values():
            if len(members) < 2:
                continue
            names = [space.samples[i].name for i in members]
            cx = sum(space.samples[i].position[0] for i in members) / len(members)
            cy = sum(space.samples[i].position[1] for i in members) / len(members)
            centre_n = space.to_normalised((cx, cy))
            mx = sum(space.samples[i].measured[0] for i in members) / len(members)
            my = sum(space.samples[i].measured[1] for i in members) / len(members)
            # Rounded so that equal distances (both ends of a pair, always) fall to the name, not to float noise.
            keep = min(
                members,
                key=lambda i: (
                    round(distance(space.samples[i].normalised, centre_n), 9),
                    space.samples[i].name,
                ),
            )
            yield self.report(
                f"{len(names)} clips lie closer than {tau:g} (normalised): {', '.join(names)}",
                clips=names,
                position=(cx, cy),
                hint=f"keep one representative ({space.samples[keep].name} is nearest the centre) or merge them "
                "(fixes.too_close: keep-representative | merge)",
                fix="too-close",
                fix_data={"keep": space.samples[keep].name, "centre": [cx, cy]},
                placeholders=[
                    placeholder(space, (mx, my), "suggested", self.slug, f"merge of {', '.join(names)}")
                ],
            )
