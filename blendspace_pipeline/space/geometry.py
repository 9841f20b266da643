"""Geometry of the blend space: axis normalisation, point location and barycentric weights.

Shared by triangulation, the rules, the evaluator and the report so that all of them agree on
what "inside a triangle" and "the weights the engine would use" mean.
Normalised space maps each axis range to 0..100 (Unreal normalises by min/max the same way).
"""

from __future__ import annotations

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
    barycentric weights (NaN rows outside). Points on a shared edge go to the first triangle.
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    found = np.full(len(points), -1, dtype=np.int64)
    weights = np.full((len(points), 3), np.nan)
    tolerance = 1e-9
    for index, tri in enumerate(np.asarray(triangles, dtype=np.int64)):
        pending = found < 0
        if not pending.any():
            break
        w = barycentric(points[pending], vertices[tri])
        inside = np.all(w >= -tolerance, axis=1)
        if inside.any():
            rows = np.flatnonzero(pending)[inside]
            found[rows] = index
            clipped = np.clip(w[inside], 0.0, None)
            weights[rows] = clipped / clipped.sum(axis=1, keepdims=True)
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
