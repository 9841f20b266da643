"""Geometry of the blend space: axis normalisation, point location and barycentric weights.

Shared by triangulation, the rules, the evaluator and the report so that all of them agree on
what "inside a triangle" and "the weights the engine would use" mean.
Normalised space maps each axis range to 0..100 (Unreal normalises by min/max the same way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.motion.quaternions import FloatArray

IntArray = NDArray[np.int64]

NORMALISED_EXTENT = 100.0
_EPS = 1e-9
# Normalised distance (axes 0..100) under which points count as on a line or on each other.
_COINCIDENT = 1e-6


@dataclass(frozen=True)
class AxisRange:
    minimum: float
    maximum: float

    @property
    def span(self) -> float:
        return self.maximum - self.minimum


def normalise(points: FloatArray, axes: tuple[AxisRange, AxisRange]) -> FloatArray:
    """Axis units → normalised 0..100 per axis."""
    lows = np.array([axes[0].minimum, axes[1].minimum])
    spans = np.array([axes[0].span, axes[1].span])
    return np.asarray((np.asarray(points, dtype=np.float64) - lows) / spans * NORMALISED_EXTENT)


def denormalise(points: FloatArray, axes: tuple[AxisRange, AxisRange]) -> FloatArray:
    """Normalised 0..100 per axis → axis units."""
    lows = np.array([axes[0].minimum, axes[1].minimum])
    spans = np.array([axes[0].span, axes[1].span])
    return np.asarray(np.asarray(points, dtype=np.float64) / NORMALISED_EXTENT * spans + lows)


def barycentric(points: FloatArray, triangle: FloatArray) -> FloatArray:
    """Barycentric coordinates (Q, 3) of ``points`` (Q, 2) in one ``triangle`` (3, 2)."""
    a, b, c = triangle
    v0, v1 = b - a, c - a
    v2 = points - a
    den = v0[0] * v1[1] - v1[0] * v0[1]
    if abs(den) < _EPS:
        return np.full((len(points), 3), np.nan)
    wb = (v2[:, 0] * v1[1] - v1[0] * v2[:, 1]) / den
    wc = (v0[0] * v2[:, 1] - v2[:, 0] * v0[1]) / den
    return np.stack([1.0 - wb - wc, wb, wc], axis=-1)


def locate(points: FloatArray, vertices: FloatArray, triangles: IntArray) -> tuple[IntArray, FloatArray]:
    """For each query point: the index of a triangle containing it (-1 if none) and its
    barycentric weights (NaN rows outside). Points on a shared edge go to the first triangle
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(points) * len(triangles) >= _LOCATOR_WORK:
        return TriangleLocator(vertices, triangles).locate(points)
    return _locate_each(points, vertices, triangles)


# Above this many point-triangle tests, indexing the mesh first pays for itself.
_LOCATOR_WORK = 200_000
_INSIDE_TOLERANCE = 1e-9


def _locate_each(
    points: FloatArray, vertices: FloatArray, triangles: IntArray
) -> tuple[IntArray, FloatArray]:
    """`locate` by testing the triangles in order: the first that holds a point takes it."""
    found = np.full(len(points), -1, dtype=np.int64)
    weights = np.full((len(points), 3), np.nan)
    for index, tri in enumerate(triangles):
        pending = found < 0
        if not pending.any():
            break
        w = barycentric(points[pending], vertices[tri])
        inside = np.all(w >= -_INSIDE_TOLERANCE, axis=1)
        if inside.any():
            rows = np.flatnonzero(pending)[inside]
            found[rows] = index
            clipped = np.clip(w[inside], 0.0, None)
            weights[rows] = clipped / clipped.sum(axis=1, keepdims=True)
    return found, weights


class TriangleLocator:
    """Point location in a fixed triangulation, for many queries at once, with `locate`'s
    answers (the first triangle that holds a point, within the same tolerance).

    The triangles are bucketed by bounding box into a uniform grid of about four cells
    per triangle; a query tests only the triangles of its cell, all queries together in one
    vectorised pass, so locating Q points among T triangles costs about T + Q work instead of
    T x Q. Any triangulation works (a hand-edited document's too), no Delaunay property assumed.
    """

    def __init__(self, vertices: FloatArray, triangles: IntArray):
        self.vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        corners = self.vertices[self.triangles]  # (T, 3, 2)
        self.origin = corners[:, 0]
        self.edge_b = corners[:, 1] - corners[:, 0]
        self.edge_c = corners[:, 2] - corners[:, 0]
        self.den = self.edge_b[:, 0] * self.edge_c[:, 1] - self.edge_c[:, 0] * self.edge_b[:, 1]
        count = len(self.triangles)
        self.cells = max(1, int(2.0 * math.sqrt(count)))  # about 4 cells per triangle: few candidates
        if not count:
            self.low, self.high, self.size = np.zeros(2), np.zeros(2), np.ones(2)
            self.cell_start = np.zeros(2, dtype=np.int64)
            self.cell_triangles = np.zeros(0, dtype=np.int64)
            return
        # Bounding boxes grown by more than the inside tolerance, so a point on an edge is in a
        # cell of every triangle that holds it.
        margin = 1e-7
        tri_low, tri_high = corners.min(axis=1) - margin, corners.max(axis=1) + margin
        self.low, self.high = tri_low.min(axis=0), tri_high.max(axis=0)
        self.size = np.maximum(self.high - self.low, 1e-12) / self.cells
        first_cell, last_cell = self._cell(tri_low), self._cell(tri_high)
        wide = last_cell[:, 0] - first_cell[:, 0] + 1
        per_triangle = wide * (last_cell[:, 1] - first_cell[:, 1] + 1)
        owner = np.repeat(np.arange(count), per_triangle)
        step = np.arange(int(per_triangle.sum())) - (np.cumsum(per_triangle) - per_triangle)[owner]
        cx = first_cell[owner, 0] + step % wide[owner]
        cy = first_cell[owner, 1] + step // wide[owner]
        cell = cy * self.cells + cx
        order = np.lexsort((owner, cell))  # by cell, then by triangle index ("first triangle")
        self.cell_triangles = owner[order]
        self.cell_start = np.searchsorted(cell[order], np.arange(self.cells * self.cells + 1))

    def _cell(self, points: FloatArray) -> IntArray:
        index = np.floor((points - self.low) / self.size).astype(np.int64)
        clipped: IntArray = np.clip(index, 0, self.cells - 1)
        return clipped

    def barycentric(self, points: FloatArray, tris: IntArray) -> FloatArray:
        """Barycentric weights (Q, 3) of ``points[q]`` in triangle ``tris[q]`` (NaN: degenerate)."""
        offset = points - self.origin[tris]
        eb, ec, den = self.edge_b[tris], self.edge_c[tris], self.den[tris]
        flat = np.abs(den) < _EPS
        safe = np.where(flat, 1.0, den)
        wb = (offset[:, 0] * ec[:, 1] - ec[:, 0] * offset[:, 1]) / safe
        wc = (eb[:, 0] * offset[:, 1] - offset[:, 0] * eb[:, 1]) / safe
        weights = np.stack([1.0 - wb - wc, wb, wc], axis=-1)
        weights[flat] = np.nan
        return weights

    def locate(self, points: FloatArray) -> tuple[IntArray, FloatArray]:
        """As `locate`: (triangle index or -1, barycentric weights or NaN) per point."""
        points = np.atleast_2d(np.asarray(points, dtype=np.float64))
        found = np.full(len(points), -1, dtype=np.int64)
        weights = np.full((len(points), 3), np.nan)
        if not len(self.triangles) or not len(points):
            return found, weights
        within = np.all((points >= self.low) & (points <= self.high), axis=1)
        cell = self._cell(points) @ np.array([1, self.cells])
        counts = np.where(within, self.cell_start[cell + 1] - self.cell_start[cell], 0)
        query = np.repeat(np.arange(len(points)), counts)
        slot = (
            self.cell_start[cell][query] + np.arange(int(counts.sum())) - (np.cumsum(counts) - counts)[query]
        )
        candidate = self.cell_triangles[slot]
        w = self.barycentric(points[query], candidate)
        inside = np.flatnonzero(np.all(w >= -_INSIDE_TOLERANCE, axis=1))
        # Candidates of a query come in triangle order: its first inside one is `locate`'s.
        hit_queries, first = np.unique(query[inside], return_index=True)
        chosen = inside[first]
        clipped = np.clip(w[chosen], 0.0, None)
        found[hit_queries] = candidate[chosen]
        weights[hit_queries] = clipped / clipped.sum(axis=1, keepdims=True)
        return found, weights


def closest_point_on_segment(point: FloatArray, a: FloatArray, b: FloatArray) -> tuple[FloatArray, float]:
    """The point of segment ab closest to ``point`` and its parameter t in [0, 1]."""
    ab = b - a
    length_sq = float(ab @ ab)
    t = 0.0 if length_sq < _EPS else float(np.clip((point - a) @ ab / length_sq, 0.0, 1.0))
    return a + t * ab, t


def hull_edges(triangles: IntArray) -> list[tuple[int, int]]:
    """Edges used by exactly one triangle: the boundary of the triangulation."""
    count: dict[tuple[int, int], int] = {}
    for tri in np.asarray(triangles, dtype=np.int64):
        for i in range(3):
            a, b = int(tri[i]), int(tri[(i + 1) % 3])
            key = (min(a, b), max(a, b))
            count[key] = count.get(key, 0) + 1
    return sorted(edge for edge, n in count.items() if n == 1)


def blend_weights(
    query: FloatArray, vertices: FloatArray, triangles: IntArray
) -> tuple[list[tuple[int, float]], bool]:
    """The (sample index, weight) pairs an engine blends at ``query`` (normalised space).

    Inside the triangulation: barycentric weights of the containing triangle. Outside: the
    query moves to the nearest point of the hull boundary, as Unreal and Godot do, and the
    second value says so. Without triangles (collinear samples, one sample) see
    `_weights_without_triangles`. Weights sum to 1; zero weights are dropped.
    """
    query = np.asarray(query, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    if len(triangles) == 0:
        return _weights_without_triangles(query, np.asarray(vertices, dtype=np.float64))
    found, weights = locate(query[None, :], vertices, triangles)
    if found[0] >= 0:
        tri = triangles[found[0]]
        return _pairs(tri, weights[0]), False
    best: tuple[float, int, int, float] | None = None
    for a, b in hull_edges(triangles):
        closest, t = closest_point_on_segment(query, vertices[a], vertices[b])
        distance = float(np.linalg.norm(query - closest))
        if best is None or distance < best[0] - _EPS:
            best = (distance, a, b, t)
    assert best is not None
    _, a, b, t = best
    return _pairs(np.array([a, b]), np.array([1.0 - t, t])), True


def space_dimension(vertices: FloatArray, triangles: IntArray) -> int:
    """2 for a triangulated space; else what its samples span: 1 on a line, 0 at one point.

    A space without triangles but with samples off one line (a hand-edited document) counts as 2.
    """
    if len(np.asarray(triangles).reshape(-1, 3)) > 0:
        return 2
    return _line_of(np.asarray(vertices, dtype=np.float64).reshape(-1, 2))[0]


def _line_of(vertices: FloatArray) -> tuple[int, FloatArray]:
    """The affine dimension of ``vertices`` (0, 1 or 2) and their main direction (unit vector)."""
    if len(vertices) == 0:
        return 0, np.array([1.0, 0.0])
    centred = vertices - vertices.mean(axis=0)
    # The first right singular vector is the direction of largest spread: the line, if any.
    direction = np.linalg.svd(centred)[2][0]
    along = centred @ direction
    across = centred @ np.array([-direction[1], direction[0]])
    if float(np.ptp(along)) <= _COINCIDENT:
        return 0, direction
    return (1 if float(np.abs(across).max()) <= _COINCIDENT else 2), direction


def _weights_without_triangles(
    query: FloatArray, vertices: FloatArray
) -> tuple[list[tuple[int, float]], bool]:
    """Weights in a space that has no triangles: what its samples span decides.

    Collinear samples (idle, walk, run all at turn 0) form a 1D space: the query projects onto
    the chain of segments between neighbouring samples and blends that segment's two ends, as
    Unreal does for a collinear 2D space and a 1D blend space does everywhere; it is outside when
    it is off the chain. One sample position (0D) takes the whole weight, outside unless the
    query is on it. A hand-edited document with samples off one line but no triangles gets the
    nearest sample. The second value says whether the query was moved.
    """
    if len(vertices) == 0:
        return [], False
    dimension, direction = _line_of(vertices)
    if dimension == 1:
        return _chain_weights(query, vertices, direction)
    nearest = int(np.argmin(np.linalg.norm(vertices - query, axis=1)))
    return [(nearest, 1.0)], bool(np.linalg.norm(vertices[nearest] - query) > _COINCIDENT)


def _chain_weights(
    query: FloatArray, vertices: FloatArray, direction: FloatArray
) -> tuple[list[tuple[int, float]], bool]:
    """Linear weights on the segment of the sorted collinear samples nearest to ``query``."""
    order = np.argsort(vertices @ direction, kind="stable")
    along = (vertices @ direction)[order]
    at = float(np.clip(query @ direction, along[0], along[-1]))
    # The segment whose far end is the first sample beyond the query's projection (the last
    # segment when it projects onto or past the last sample).
    upper = min(max(int(np.searchsorted(along, at, side="right")), 1), len(along) - 1)
    a, b = int(order[upper - 1]), int(order[upper])
    closest, t = closest_point_on_segment(query, vertices[a], vertices[b])
    outside = float(np.linalg.norm(query - closest)) > _COINCIDENT
    return _pairs(np.array([a, b]), np.array([1.0 - t, t])), outside


def _pairs(indices: IntArray, weights: FloatArray) -> list[tuple[int, float]]:
    merged: dict[int, float] = {}
    for index, weight in zip(indices, weights, strict=True):
        if weight > 1e-12:
            merged[int(index)] = merged.get(int(index), 0.0) + float(weight)
    total = sum(merged.values())
    return [(index, weight / total) for index, weight in sorted(merged.items())]
