"""Stages that scale: the rule API's vectorised views, too-close with a k-d tree, and the
geometry used on whole grids, each checked against the all-pairs / per-item computation."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from blendspace_pipeline.rules.too_close import TooClose

from blendspace_pipeline.api import SpaceView
from blendspace_pipeline.testing import run_rule, space_from_positions


def _random_space(count: int, seed: int, **options: object) -> SpaceView:
    rng = np.random.default_rng(seed)
    positions = {
        f"c{i:04d}": (float(rng.uniform(-180, 180)), float(rng.uniform(-3, 6))) for i in range(count)
    }
    return space_from_positions(positions, snap=False, **options)  # type: ignore[arg-type]


def test_vectorised_views_match_the_sample_views_and_are_read_only() -> None:
    space = _random_space(50, 1)
    assert space.positions.shape == (50, 2)
    assert space.positions.tolist() == [list(s.position) for s in space.samples]
    assert space.normalised_positions.tolist() == [list(s.normalised) for s in space.samples]
    assert space.measured_positions.tolist() == [list(s.measured) for s in space.samples]
    assert space.triangle_array.tolist() == [list(t) for t in space.triangles]
    assert space.feature_array("duration").tolist() == [1.0] * 50
    assert np.isnan(space.feature_array("no_such_feature")).all()
    with pytest.raises(ValueError, match="read-only"):
        space.positions[0, 0] = 1.0
    assert space.positions is space.positions  # computed once per view


@pytest.mark.parametrize("radius", [0.0, 1.0, 4.0, 8.0, 30.0])
def test_close_pairs_are_exactly_the_pairs_closer_than_the_radius(radius: float) -> None:
    space = _random_space(300, 2)
    points = [s.normalised for s in space.samples]
    brute = [
        [i, j]
        for i, j in itertools.combinations(range(len(points)), 2)
        if math.hypot(points[i][0] - points[j][0], points[i][1] - points[j][1]) < radius
    ]
    assert space.close_pairs(radius).tolist() == brute


def test_close_pairs_on_a_grid_leave_out_pairs_exactly_at_the_radius() -> None:
    """Samples 10 normalised units apart: radius 10 must not pair them (strictly closer)."""
    positions = {f"g{i}": (-180.0 + 36.0 * i, 0.0) for i in range(5)}  # 36 deg/s = 10 normalised
    space = space_from_positions(positions, snap=False)
    assert space.close_pairs(10.0).tolist() == []
    assert space.close_pairs(10.0 + 1e-9).tolist() == [[0, 1], [1, 2], [2, 3], [3, 4]]


def _too_close_all_pairs(space: SpaceView, tau: float) -> list[list[str]]:
    """The groups the rule must find, testing all pairs and rescanning every free sample at each
    step (no k-d tree, no heap): the free sample with the most free neighbours closer than tau
    (then nearest its group's centre, then by name) takes them."""
    count = len(space.samples)
    at = [space.samples[i].normalised for i in range(count)]
    neighbours: list[set[int]] = [set() for _ in range(count)]
    for i, j in itertools.combinations(range(count), 2):
        if math.hypot(at[i][0] - at[j][0], at[i][1] - at[j][1]) < tau:
            neighbours[i].add(j)
            neighbours[j].add(i)
    free = set(range(count))
    groups: list[list[str]] = []
    while True:
        best: tuple[tuple[int, float, str], set[int]] | None = None
        for i in free:
            group = {i} | (neighbours[i] & free)
            if len(group) < 2:
                continue
            cx = sum(at[m][0] for m in group) / len(group)
            cy = sum(at[m][1] for m in group) / len(group)
            key = (-len(group), round(math.hypot(at[i][0] - cx, at[i][1] - cy), 9), space.samples[i].name)
            if best is None or key < best[0]:
                best = (key, group)
        if best is None:
            return groups
        free -= best[1]
        groups.append([space.samples[m].name for m in sorted(best[1])])


def test_too_close_finds_the_same_clusters_as_all_pairs() -> None:
    space = _random_space(400, 3, thresholds={"too_close": 4.0})
    found = run_rule(TooClose, space)
    assert found, "400 random samples at tau 4 must hold close clusters"
    assert sorted(list(d.clips) for d in found) == sorted(_too_close_all_pairs(space, 4.0))


def test_too_close_on_10000_samples_finds_planted_pairs() -> None:
    """10,000 samples on a lattice 1 normalised unit apart per axis step, too_close 0.5: no
    finding; then 20 planted twins 0.1 away from lattice points: exactly those 20 pairs."""
    axis_steps = np.linspace(0.0, 99.0, 100)
    lattice = [(x, y) for x in axis_steps for y in axis_steps]
    to_axes = lambda p: (p[0] / 100 * 360 - 180, p[1] / 100 * 9 - 3)  # noqa: E731
    positions = {f"l{i:05d}": to_axes(p) for i, p in enumerate(lattice)}
    thresholds = {"too_close": 0.5}
    assert (
        run_rule(TooClose, space_from_positions(positions, snap=False, thresholds=thresholds, triangles=[]))
        == []
    )
    rng = np.random.default_rng(4)
    planted = rng.choice(len(lattice), size=20, replace=False)
    for k in planted:
        x, y = lattice[int(k)]
        positions[f"twin_{k:05d}"] = to_axes((x + 0.1, y))
    space = space_from_positions(positions, snap=False, thresholds=thresholds, triangles=[])
    found = run_rule(TooClose, space)
    assert sorted(sorted(d.clips) for d in found) == sorted(
        sorted([f"l{k:05d}", f"twin_{k:05d}"]) for k in planted
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_triangle_locator_gives_locate_s_answers(seed: int) -> None:
    """Bucketed location equals testing every triangle in order: same triangle (the first that
    holds the point, so shared edges and vertices agree too), same weights, same misses."""
    from blendspace_pipeline.space.geometry import TriangleLocator, _locate_each
    from blendspace_pipeline.space.triangulate import triangulate

    rng = np.random.default_rng(seed)
    vertices = np.round(rng.uniform(0, 100, size=(400, 2)) / 2.5) * 2.5  # duplicates and collinear runs
    triangles = np.array(triangulate(vertices).triangles)
    queries = [rng.uniform(-10, 110, size=(3000, 2)), vertices]
    corners = vertices[triangles]
    queries.append((corners[:, 0] + corners[:, 1]) / 2)  # midpoints of shared edges
    points = np.concatenate(queries)
    want_found, want_weights = _locate_each(points, vertices, triangles)
    found, weights = TriangleLocator(vertices, triangles).locate(points)
    assert (found == want_found).all()
    assert np.allclose(weights, want_weights, atol=1e-12, equal_nan=True)
    # A hand-made, non-Delaunay triangulation (a square cut along the other diagonal) too.
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    cut = np.array([[0, 1, 3], [1, 2, 3]])
    grid = np.stack(np.meshgrid(np.linspace(-5, 105, 23), np.linspace(-5, 105, 23)), -1).reshape(-1, 2)
    assert (TriangleLocator(square, cut).locate(grid)[0] == _locate_each(grid, square, cut)[0]).all()
