"""Trajectory error: how far the blend's real root motion is from what the game asked for.

At a query (x, y) the engine blends the clips of the triangle containing it with barycentric
weights computed from the clips' *placed* positions. What the character then really does is
the same weighted mix of the clips' *measured* features. Where placement equals measurement
(and features mix linearly) the two agree; snapping or hand placement moves the positions away
from what the clips do, and the difference is the drift a player sees. Outside the hull engines
clamp the query to the boundary, so those grid points are marked (NaN) rather than measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.report.diagram import axis_ranges
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.geometry import NORMALISED_EXTENT, AxisRange, locate, normalise
from blendspace_pipeline.space.triangulate import triangulate

BoolArray = NDArray[np.bool_]
DEFAULT_RESOLUTION = 41


@dataclass(frozen=True)
class TrajectoryErrorGrid:
    """Errors on a regular grid over the axis rectangle; rows go along y, columns along x."""

    xs: FloatArray  # (nx,) grid x values, axis units
    ys: FloatArray  # (ny,) grid y values, axis units
    error_x: FloatArray  # (ny, nx) |requested - delivered| along x, axis units; NaN outside the hull
    error_y: FloatArray  # (ny, nx) same along y
    distance: FloatArray  # (ny, nx) the error as a distance in normalised units (each axis 0..100)
    inside: BoolArray  # (ny, nx) whether the engine blends there without clamping

    @property
    def max_distance(self) -> float:
        """Largest normalised error inside the hull (0 when no point is inside)."""
        return float(np.nanmax(self.distance)) if self.inside.any() else 0.0

    @property
    def mean_distance(self) -> float:
        return float(np.nanmean(self.distance)) if self.inside.any() else 0.0


def trajectory_error(
    positions: FloatArray,
    measured: FloatArray,
    triangles: list[list[int]] | list[tuple[int, int, int]],
    axes: tuple[AxisRange, AxisRange],
    resolution: int | tuple[int, int] = DEFAULT_RESOLUTION,
) -> TrajectoryErrorGrid:
    """Trajectory error over the axis rectangle.

    ``positions`` (N, 2) are where the samples are placed (the engine's view) and ``measured``
    (N, 2) what each clip really does, both in axis units; ``triangles`` index the samples.
    """
    nx, ny = (resolution, resolution) if isinstance(resolution, int) else resolution
    if nx < 2 or ny < 2:
        raise ValueError(f"trajectory-error grid needs at least 2x2 points, got {nx}x{ny}")
    unit = np.linspace(0.0, NORMALISED_EXTENT, nx), np.linspace(0.0, NORMALISED_EXTENT, ny)
    grid_x, grid_y = np.meshgrid(*unit)
    requested = np.stack([grid_x.ravel(), grid_y.ravel()], axis=-1)  # normalised
    delivered = _delivered(requested, normalise(positions, axes), normalise(measured, axes), triangles)
    difference = np.abs(requested - delivered)
    spans = np.array([axes[0].span, axes[1].span]) / NORMALISED_EXTENT
    shape = (ny, nx)
    return TrajectoryErrorGrid(
        xs=np.linspace(axes[0].minimum, axes[0].maximum, nx),
        ys=np.linspace(axes[1].minimum, axes[1].maximum, ny),
        error_x=(difference[:, 0] * spans[0]).reshape(shape),
        error_y=(difference[:, 1] * spans[1]).reshape(shape),
        distance=np.hypot(difference[:, 0], difference[:, 1]).reshape(shape),
        inside=~np.isnan(delivered[:, 0]).reshape(shape),
    )


def _delivered(
    requested: FloatArray,
    placed: FloatArray,
    measured: FloatArray,
    triangles: list[list[int]] | list[tuple[int, int, int]],
) -> FloatArray:
    """The measured features blended with the engine's weights at each query; NaN outside."""
    delivered = np.full_like(requested, np.nan)
    if len(triangles) == 0:
        return delivered
    tris = np.asarray(triangles, dtype=np.int64)
    found, weights = locate(requested, placed, tris)
    rows = found >= 0
    corners = measured[tris[found[rows]]]  # (Q, 3, 2)
    delivered[rows] = np.einsum("qk,qkd->qd", weights[rows], corners)
    return delivered


def measured_positions(doc: BlendSpaceDocument) -> FloatArray:
    """What each clip really does along the two axes, axis units (N, 2).

    The axis feature when the sample carries it; otherwise the snapped position minus the
    snapping error, which is the same number by definition.
    """
    rows = []
    for sample in doc.samples:
        row = []
        for index, axis in enumerate(doc.axes):
            value = sample.features.get(axis.feature)
            row.append(value if value is not None else sample.position[index] - sample.snapping_error[index])
        rows.append(row)
    return np.asarray(rows, dtype=np.float64).reshape(-1, 2)


def has_manual_positions(doc: BlendSpaceDocument) -> bool:
    return any(sample.manual_position is not None for sample in doc.samples)


def manual_positions(doc: BlendSpaceDocument) -> FloatArray:
    """Positions as the authors placed them by hand; clips without one keep the snapped position."""
    return np.asarray(
        [s.manual_position if s.manual_position is not None else s.position for s in doc.samples],
        dtype=np.float64,
    ).reshape(-1, 2)


def manual_triangles(doc: BlendSpaceDocument) -> list[list[int]]:
    """The Delaunay triangles an engine would build from the hand-placed positions."""
    mesh = triangulate(normalise(manual_positions(doc), axis_ranges(doc)))
    return [list(t) for t in mesh.triangles]


def document_trajectory_error(
    doc: BlendSpaceDocument, *, manual: bool = False, resolution: int | tuple[int, int] = DEFAULT_RESOLUTION
) -> TrajectoryErrorGrid:
    """The error of the document's placement, or of the authors' hand placement with ``manual``.

    Hand-placed positions get their own Delaunay triangulation, as the engine would build it
    from them; the snapped placement uses the document's triangles.
    """
    if manual:
        positions, triangles = manual_positions(doc), manual_triangles(doc)
    else:
        positions = np.asarray([s.position for s in doc.samples], dtype=np.float64).reshape(-1, 2)
        triangles = [list(t) for t in doc.triangles]
    return trajectory_error(positions, measured_positions(doc), triangles, axis_ranges(doc), resolution)
