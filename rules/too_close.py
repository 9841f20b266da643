"""too-close: samples so close that they add cost and flip-flop between styles."""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator

import numpy as np

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView, placeholder


class TooClose(Rule):
    """Samples closer than `thresholds.too_close` (normalised units; τd = 8 is the paper's value;
    a pair exactly τd apart is not too close). Each finding is one representative and the samples
    closer than τd to it: the representative is, among the samples not yet in a finding, the one
    with the most such neighbours (ties: nearest the centre of its group, then by name). So every
    member of a finding lies within τd of its representative, and no chain of close pairs runs
    across a dense library (linking them transitively made one 1,000-clip "cluster" of a random
    1,000-clip library, and keep-representative would have dropped 999 clips). Keeping every
    finding's representative (`fixes.too_close: keep-representative`) leaves no two samples
    closer than τd, and each dropped clip has a kept one within τd; `merge` replaces a finding by
    the equal-weight blend of its members. The suggested placeholder is where the merged clip
    would go (the paper's green marker): the mean of the members' measured positions. The fix
    never drops a key clip (on a main axis, or a hull corner).
    """

    slug = "too-close"
    code = "BS004"
    severity = "warning"
    summary = "samples closer than too_close"
    fixable = True

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        tau = space.thresholds["too_close"]
        for keep, members in sorted(_leader_groups(space, tau), key=lambda group: group[1][0]):
            names = [space.samples[i].name for i in members]
            others = [space.samples[i].name for i in members if i != keep]
            cx = sum(space.samples[i].position[0] for i in members) / len(members)
            cy = sum(space.samples[i].position[1] for i in members) / len(members)
            mx = sum(space.samples[i].measured[0] for i in members) / len(members)
            my = sum(space.samples[i].measured[1] for i in members) / len(members)
            verb = "lies" if len(others) == 1 else "lie"
            yield self.report(
                f"{', '.join(others)} {verb} closer than {tau:g} (normalised) to {space.samples[keep].name}",
                clips=names,
                position=(cx, cy),
                hint=f"keep one representative ({space.samples[keep].name}: the others lie within {tau:g} "
                "of it) or merge them (fixes.too_close: keep-representative | merge)",
                fix="too-close",
                fix_data={"keep": space.samples[keep].name, "centre": [cx, cy]},
                placeholders=[
                    placeholder(space, (mx, my), "suggested", self.slug, f"merge of {', '.join(names)}")
                ],
            )


def _leader_groups(space: SpaceView, tau: float) -> list[tuple[int, list[int]]]:
    """(representative, sorted members) groups, greedily: the free sample with the most free
    neighbours closer than ``tau`` takes them. A heap with lazy re-evaluation keeps this near
    n log n: a sample's key only worsens as its neighbours are taken (fewer neighbours), and it is
    re-pushed with its new key when popped stale. Every sample enters with an optimistic key
    (its full neighbourhood, distance 0), so the first pop computes its real one."""
    pairs = space.close_pairs(tau)
    if not len(pairs):
        return []
    count = len(space.samples)
    # Neighbours as compressed rows: sample i's are indices[start[i]:start[i + 1]].
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    order = np.argsort(rows, kind="stable")
    indices = np.concatenate([pairs[:, 1], pairs[:, 0]])[order]
    start = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=count))]).tolist()
    points = space.normalised_positions
    xs, ys = points[:, 0], points[:, 1]
    names = [sample.name for sample in space.samples]
    free = np.ones(count, dtype=bool)

    def free_neighbours(index: int) -> np.ndarray:
        around = indices[start[index] : start[index + 1]]
        return around[free[around]]

    def key(index: int) -> tuple[int, float, str] | None:
        group = free_neighbours(index)
        if not group.size:
            return None
        size = group.size + 1
        cx = (float(xs[group].sum()) + float(xs[index])) / size
        cy = (float(ys[group].sum()) + float(ys[index])) / size
        # Rounded so that equal distances (both ends of a pair, always) fall to the name, not to float noise.
        return (-size, round(math.hypot(float(xs[index]) - cx, float(ys[index]) - cy), 9), names[index])

    degree = np.diff(start).tolist()
    heap = [((-(degree[i] + 1), -1.0, ""), i) for i in range(count) if degree[i]]
    heapq.heapify(heap)
    groups = []
    while heap:
        stale, index = heapq.heappop(heap)
        if not free[index]:
            continue
        current = key(index)
        if current is None:
            continue
        if current != stale:
            heapq.heappush(heap, (current, index))
            continue
        members = sorted([index, *free_neighbours(index).tolist()])
        free[members] = False
        groups.append((index, members))
    return groups
