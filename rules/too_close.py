"""too-close: samples so close that they add cost and flip-flop between styles."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.rules._geometry import distance

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class TooClose(Rule):
    """Samples closer than `thresholds.too_close` (normalised units, paper: 8) are grouped into
    clusters; each cluster is one finding. Keep one representative (the clip nearest the cluster
    centre) or replace the cluster by their interpolation (`fixes.too_close`).
    """

    slug = "too-close"
    code = "BS004"
    severity = "warning"
    summary = "samples closer than too_close"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["too_close"]
        count = len(space.samples)
        parent = list(range(count))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        closest: dict[int, float] = {}
        # Candidate pairs from a k-d tree, in the order the all-pairs loop visited them.
        for i, j in space.close_pairs(tau).tolist():
            d = distance(space.samples[i].normalised, space.samples[j].normalised)
            if d < tau:
                parent[root(j)] = root(i)
                closest[root(i)] = min(closest.get(root(i), d), d)
        clusters: dict[int, list[int]] = {}
        for i in range(count):
            clusters.setdefault(root(i), []).append(i)
        for members in clusters.values():
            if len(members) < 2:
                continue
            names = [space.samples[i].name for i in members]
            cx = sum(space.samples[i].position[0] for i in members) / len(members)
            cy = sum(space.samples[i].position[1] for i in members) / len(members)
            centre_n = space.to_normalised((cx, cy))
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
            )
