"""Trajectory error: requested (x, y) vs what the engine's blend of the measured clips delivers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from blendspace_pipeline.report.trajectory_error import document_trajectory_error, trajectory_error
from blendspace_pipeline.space.document import AxisDoc, BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.geometry import AxisRange

SQUARE = (AxisRange(0.0, 100.0), AxisRange(0.0, 100.0))


def _at(values: np.ndarray, xs: np.ndarray, ys: np.ndarray, x: float, y: float) -> float:
    column = int(np.argmin(np.abs(xs - x)))
    row = int(np.argmin(np.abs(ys - y)))
    assert xs[column] == pytest.approx(x) and ys[row] == pytest.approx(y), "query is not a grid point"
    return float(values[row, column])


def test_exact_placement_has_zero_error_inside_the_hull() -> None:
    rng = np.random.default_rng(7)
    points = np.vstack([[[5.0, 10.0], [95.0, 5.0], [90.0, 92.0], [8.0, 85.0]], rng.uniform(10, 90, (20, 2))])
    triangles = Delaunay(points).simplices.tolist()
    grid = trajectory_error(points, points, triangles, SQUARE, resolution=41)
    assert grid.inside.sum() > 0.6 * grid.inside.size  # the hull covers most of the square
    assert np.nanmax(grid.distance) < 1e-9
    assert np.nanmax(grid.error_x) < 1e-9 and np.nanmax(grid.error_y) < 1e-9
    # The corners of the square lie outside this hull: engines clamp there, so no figure.
    assert not grid.inside[0, 0] and np.isnan(grid.distance[0, 0])
    assert np.isnan(grid.error_x[~grid.inside]).all()


def test_hand_placed_clip_gives_the_expected_drift() -> None:
    # x: 0..200 deg/s, y: 0..10 m/s. Clip B really turns at 200 deg/s but the author put it at 100.
    axes = (AxisRange(0.0, 200.0), AxisRange(0.0, 10.0))
    measured = np.array([[0.0, 0.0], [200.0, 0.0], [0.0, 10.0]])
    placed = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 10.0]])
    grid = trajectory_error(placed, measured, [[0, 1, 2]], axes, resolution=5)
    xs, ys = grid.xs, grid.ys
    assert xs.tolist() == [0.0, 50.0, 100.0, 150.0, 200.0] and ys.tolist() == [0.0, 2.5, 5.0, 7.5, 10.0]
    # (50, 2.5): weights by placed positions A 0.25, B 0.5, C 0.25 -> delivers (100, 2.5).
    assert _at(grid.error_x, xs, ys, 50, 2.5) == pytest.approx(50.0)
    assert _at(grid.error_y, xs, ys, 50, 2.5) == pytest.approx(0.0, abs=1e-12)
    assert _at(grid.distance, xs, ys, 50, 2.5) == pytest.approx(25.0)  # 50 of a 200 span = 25 normalised
    # (100, 0) is B's placed position: the blend plays B alone, which turns at 200.
    assert _at(grid.error_x, xs, ys, 100, 0) == pytest.approx(100.0)
    assert _at(grid.distance, xs, ys, 100, 0) == pytest.approx(50.0)
    # A and C are placed where they measure: no drift there.
    assert _at(grid.distance, xs, ys, 0, 0) == pytest.approx(0.0, abs=1e-12)
    assert _at(grid.distance, xs, ys, 0, 10) == pytest.approx(0.0, abs=1e-12)
    # (150, 0) lies beyond the placed triangle: the engine clamps, so it is marked, not measured.
    assert not grid.inside[0, 3] and np.isnan(_at(grid.distance, xs, ys, 150, 0))


def test_uniform_shift_shows_as_constant_error() -> None:
    corners = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    placed = corners + np.array([10.0, 0.0])  # every clip placed 10 units right of what it does
    grid = trajectory_error(placed, corners, [[0, 1, 2], [0, 2, 3]], SQUARE, resolution=11)
    inside = grid.inside
    assert not inside[:, 0].any() and inside[:, 1:].all()  # x = 0 lies left of the shifted hull
    np.testing.assert_allclose(grid.error_x[inside], 10.0)
    np.testing.assert_allclose(grid.error_y[inside], 0.0, atol=1e-12)
    assert grid.max_distance == pytest.approx(10.0) and grid.mean_distance == pytest.approx(10.0)


def test_no_triangles_means_no_point_is_blended() -> None:
    points = np.array([[0.0, 0.0], [50.0, 50.0]])
    grid = trajectory_error(points, points, [], SQUARE, resolution=3)
    assert not grid.inside.any() and grid.max_distance == 0.0


def test_grid_must_have_two_points_per_axis() -> None:
    with pytest.raises(ValueError, match="2x2"):
        trajectory_error(np.zeros((3, 2)), np.zeros((3, 2)), [], SQUARE, resolution=1)


def _document(manual: dict[str, list[float]]) -> BlendSpaceDocument:
    """Idle, forward run and two turns measured exactly on the grid, some placed by hand too."""
    measured = {
        "idle": (0.0, 0.0),
        "run": (0.0, 6.0),
        "left": (90.0, 3.0),
        "right": (-90.0, 3.0),
        "back": (0.0, -3.0),
    }
    samples = [
        SampleDoc(
            name=name,
            source=f"{name}.bvh",
            features={"turn_rate": x, "speed": y},
            position=[x, y],
            manual_position=manual.get(name),
        )
        for name, (x, y) in measured.items()
    ]
    axes = [
        AxisDoc(name="x", feature="turn_rate", min=-90, max=90, divisions=18, unit="deg/s"),
        AxisDoc(name="y", feature="speed", min=-3, max=6, divisions=9, unit="m/s"),
    ]
    return BlendSpaceDocument(
        schema_version=1,
        name="t",
        axes=axes,
        samples=samples,
        triangles=[[0, 2, 1], [0, 1, 3], [0, 3, 4], [0, 4, 2]],
    )


def test_document_compares_measured_and_manual_placement() -> None:
    doc = _document({"run": [0.0, 4.5]})  # the author put the 6 m/s run at 4.5 m/s
    measured = document_trajectory_error(doc, resolution=(19, 10))
    assert measured.inside.any() and measured.max_distance < 1e-9
    manual = document_trajectory_error(doc, manual=True, resolution=(19, 19))
    # At (0, 4.5) the hand-placed triangulation plays `run` alone: it delivers 6 m/s, 1.5 too fast.
    assert _at(manual.error_y, manual.xs, manual.ys, 0, 4.5) == pytest.approx(1.5)
    assert _at(manual.error_x, manual.xs, manual.ys, 0, 4.5) == pytest.approx(0.0, abs=1e-9)
    assert _at(manual.distance, manual.xs, manual.ys, 0, 4.5) == pytest.approx(1.5 / 9 * 100)
    # Queries above 4.5 m/s are now outside the hand-placed hull.
    assert not manual.inside[manual.ys > 4.5 + 1e-9].any()
    # Idle is placed where it measures: no drift at the origin.
    assert _at(manual.distance, manual.xs, manual.ys, 0, 0) == pytest.approx(0.0, abs=1e-9)


def test_document_falls_back_to_position_minus_snapping_error() -> None:
    doc = _document({})
    doc.samples[1].features = {}  # a generated clip may carry no features; its placement record still says
    doc.samples[1].position = [0.0, 6.0]
    doc.samples[1].snapping_error = [0.0, 0.3]  # snapped 0.3 above what it does (5.7 m/s)
    grid = document_trajectory_error(doc, resolution=(19, 10))
    assert _at(grid.error_y, grid.xs, grid.ys, 0, 6) == pytest.approx(0.3)
