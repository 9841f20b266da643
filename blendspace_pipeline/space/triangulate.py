"""Delaunay triangulation of the placed samples in axis-normalised space (as Unreal does).

Deterministic: duplicate positions are merged before Qhull sees them (the first sample of a
duplicate group stands for the group), triangles are made counter-clockwise, rotated to start
at their smallest index and sorted. Degenerate layouts (fewer than three distinct positions, or
all on one line) give no triangles and a reason the build reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from blendspace_pipeline.motion.quaternions import FloatArray


@dataclass
class Triangulation:
    triangles: list[tuple[int, int, int]]
    duplicates: list[list[int]] = field(default_factory=list)  # groups of samples sharing a position
    degenerate_reason: str | None = None


def triangulate(normalised: FloatArray) -> Triangulation:
    """Triangles over sample indices of ``normalised`` positions (N, 2), each axis 0..100."""
    points = np.asarray(normalised, dtype=np.float64)
    keys = [tuple(np.round(p, 6)) for p in points]
    first_of: dict[tuple[float, ...], int] = {}
    groups: dict[int, list[int]] = {}
    for index, key in enumerate(keys):
        owner = first_of.setdefault(key, index)
        groups.setdefault(owner, []).append(index)
    unique = sorted(groups)
    duplicates = [members for members in groups.values() if len(members) > 1]
    if len(unique) < 3:
        return Triangulation([], duplicates, f"only {len(unique)} distinct position(s); a 2D space needs 3")
    distinct = points[unique]
    centred = distinct - distinct.mean(axis=0)
    if np.linalg.matrix_rank(centred, tol=1e-6) < 2:
        return Triangulation(
            [], duplicates, "all samples lie on one line; a 2D space needs a third direction"
        )
    from scipy.spatial import Delaunay  # local import: scipy loads only when a build triangulates

    mesh = Delaunay(distinct)
    triangles = [_canonical(tuple(unique[i] for i in simplex), points) for simplex in mesh.simplices]
    triangles = [tri for tri in triangles if _area(points[list(tri)]) > 1e-9]
    return Triangulation(sorted(triangles), duplicates)


def _area(corners: FloatArray) -> float:
    (ax, ay), (bx, by), (cx, cy) = corners
    return float(0.5 * ((bx - ax) * (cy - ay) - (cx - ax) * (by - ay)))


def _canonical(tri: tuple[int, ...], points: FloatArray) -> tuple[int, int, int]:
    a, b, c = (int(i) for i in tri)
    if _area(points[[a, b, c]]) < 0:
        b, c = c, b
    rotations = [(a, b, c), (b, c, a), (c, a, b)]
    return min(rotations)
