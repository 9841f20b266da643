"""Delaunay triangulation of the placed samples in axis-normalised space (as Unreal does).

Deterministic: duplicate positions are merged before Qhull sees them (the first sample of a
duplicate group stands for the group), triangles are made counter-clockwise, rotated to start
at their smallest index and sorted. Degenerate layouts (fewer than three distinct positions, or
all on one line) give no triangles and a reason the build reports.
"""

from __future__ import annotations

from collections.abc import Sequence
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
    points = np.asarray(normalised, dtype=np.float64).reshape(-1, 2)
    # Positions equal to 6 decimals are one (+ 0.0 makes -0.0 and 0.0 the same bytes for unique).
    rounded = np.round(points, 6) + 0.0
    if len(points):
        _, first, inverse = np.unique(rounded, axis=0, return_index=True, return_inverse=True)
        owner = first[inverse.reshape(-1)]  # the first sample at each sample's position
    else:
        owner = np.zeros(0, dtype=np.int64)
    unique = sorted(int(i) for i in np.unique(owner))
    counts = np.bincount(owner, minlength=len(points)) if len(points) else np.zeros(0, dtype=np.int64)
    duplicates = [np.flatnonzero(owner == i).tolist() for i in unique if counts[i] > 1]
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
    return Triangulation(_canonical_triangles(np.asarray(unique)[mesh.simplices], points), duplicates)


def _canonical_triangles(triangles: np.ndarray, points: FloatArray) -> list[tuple[int, int, int]]:
    """Counter-clockwise, starting at the smallest index, degenerate ones dropped, sorted."""
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3).copy()
    area = _areas(points, tris)
    clockwise = area < 0
    tris[clockwise, 1], tris[clockwise, 2] = tris[clockwise, 2], tris[clockwise, 1].copy()
    start = np.argmin(tris, axis=1)
    rotated = np.take_along_axis(tris, (start[:, None] + np.arange(3)[None, :]) % 3, axis=1)
    rotated = rotated[np.abs(area) > 1e-9]
    return sorted((int(a), int(b), int(c)) for a, b, c in rotated.tolist())


def _areas(points: FloatArray, tris: np.ndarray) -> FloatArray:
    """Signed areas of triangles ``tris`` (T, 3) over ``points``: positive counter-clockwise."""
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    area: FloatArray = 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    )
    return area


def triangle_edges(triangles: Sequence[Sequence[int]]) -> list[tuple[int, int]]:
    """Each triangle edge once, (low, high) sample indices, sorted."""
    if not len(triangles):
        return []
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    pairs = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    pairs.sort(axis=1)
    span = int(pairs.max()) + 1
    keys = np.unique(pairs[:, 0] * span + pairs[:, 1])  # one integer per edge: a 1-D sort
    return list(zip((keys // span).tolist(), (keys % span).tolist(), strict=True))
