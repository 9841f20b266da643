"""Recall and precision of the five spec rules, checked against an independent brute force.

Many random blend spaces are generated from a seeded numpy RNG: positions on the axis grid,
some jittered by less than half a grid step so that snapping matters, some crowded near the main
axes or near each other so that every rule has work to do. Three axis layouts are used, one of
them without a speed = 0 line. The thresholds are random too, so no grid distance lands exactly
on a threshold, where float rounding alone would decide. The expected findings are computed here
from the definitions in spec.md and in the rules' docstrings. The code uses exact rational
arithmetic (`fractions.Fraction`) on the grid indices (angles alone in floating point) and shares
nothing with the rules except the triangulation they are given. The test compares those findings with what the rules report:
recall and precision must both be 1.0, and a failure lists the findings that were missed or
spurious, with the space that produced them.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import pytest
from blendspace_pipeline.rules.acute_triangle import AcuteTriangle
from blendspace_pipeline.rules.crossing_axis import CrossingAxis
from blendspace_pipeline.rules.misalignment import Misalignment
from blendspace_pipeline.rules.too_close import TooClose
from blendspace_pipeline.rules.uncovered_area import UncoveredArea
from scipy.spatial import ConvexHull, QhullError

from blendspace_pipeline.api import Rule, SpaceView
from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.space.placement import Axis
from blendspace_pipeline.testing import run_rule, space_from_positions

SPACES = 200
SEED = 20240611
AXIS_LAYOUTS = (
    (Axis("x", "turn_rate", -180.0, 180.0, 100), Axis("y", "speed", -3.0, 6.0, 90)),  # the default
    (Axis("x", "direction", -120.0, 240.0, 60), Axis("y", "speed", -2.0, 8.0, 50)),  # zeros off-centre
    (Axis("x", "turn_rate", -180.0, 180.0, 100), Axis("y", "speed", 0.5, 6.5, 60)),  # no speed = 0 line
)
Key = tuple[object, ...]
Exact = tuple[Fraction, Fraction]


@dataclass
class RandomSpace:
    """A generated space: grid indices per sample, the exact normalised points, and the view."""

    number: int
    axes: tuple[Axis, Axis]
    indices: dict[str, tuple[int, int]]
    thresholds: dict[str, float]
    view: SpaceView
    measured: dict[str, tuple[float, float]]

    def zero_index(self, k: int) -> int | None:
        """Grid index of 0 on axis k (None when 0 is outside the range); all layouts keep 0 on the grid."""
        axis = self.axes[k]
        if not axis.minimum <= 0.0 <= axis.maximum:
            return None
        ratio = Fraction(-axis.minimum) / Fraction(axis.maximum - axis.minimum) * axis.divisions
        assert ratio.denominator == 1
        return int(ratio)

    def line(self, k: int) -> Fraction | None:
        zero = self.zero_index(k)
        return None if zero is None else Fraction(zero * 100, self.axes[k].divisions)

    def point(self, name: str) -> Exact:
        i, j = self.indices[name]
        return Fraction(i * 100, self.axes[0].divisions), Fraction(j * 100, self.axes[1].divisions)

    def value(self, name: str, k: int) -> Fraction:
        """The snapped position on axis k, in axis units, exactly."""
        axis = self.axes[k]
        step = (Fraction(axis.maximum) - Fraction(axis.minimum)) / axis.divisions
        return Fraction(axis.minimum) + self.indices[name][k] * step

    def describe(self) -> str:
        axes = ", ".join(f"{a.feature} {a.minimum:g}..{a.maximum:g}/{a.divisions}" for a in self.axes)
        cells = ", ".join(f"{n}@{ij}" for n, ij in self.indices.items())
        return f"space {self.number}: axes {axes}; thresholds {self.thresholds}; grid cells {cells}"


def generate_space(number: int, rng: np.random.Generator) -> RandomSpace:
    axes = AXIS_LAYOUTS[number % len(AXIS_LAYOUTS)]
    size = (axes[0].divisions, axes[1].divisions)
    zeros = [round(-a.minimum / a.step) if a.minimum <= 0 <= a.maximum else None for a in axes]
    cells: list[tuple[int, int]] = []
    for _ in range(int(rng.integers(4, 16))):
        kind = rng.random()
        if kind < 0.45 or not cells:  # anywhere
            cell = (int(rng.integers(0, size[0] + 1)), int(rng.integers(0, size[1] + 1)))
        elif kind < 0.75:  # near a main axis: misalignment, or an edge hugging the axis
            k = int(rng.integers(0, 2))
            zero = zeros[k] if zeros[k] is not None else zeros[0]
            k = k if zeros[k] is not None else 0
            assert zero is not None
            near = zero + int(rng.integers(-4, 5))
            other = int(rng.integers(0, size[1 - k] + 1))
            cell = (near, other) if k == 0 else (other, near)
        else:  # next to an earlier sample: clusters
            base = cells[int(rng.integers(0, len(cells)))]
            cell = (base[0] + int(rng.integers(-4, 5)), base[1] + int(rng.integers(-4, 5)))
        cell = (min(max(cell[0], 0), size[0]), min(max(cell[1], 0), size[1]))
        if cell not in cells:
            cells.append(cell)
    indices = {f"c{n}": cell for n, cell in enumerate(cells)}
    measured = {}
    for name, (i, j) in indices.items():
        # Half the samples are measured up to 0.45 steps off their grid point: snapping puts them back.
        jitter = rng.uniform(-0.45, 0.45, size=2) if rng.random() < 0.5 else np.zeros(2)
        measured[name] = (
            axes[0].minimum + (i + jitter[0]) * axes[0].step,
            axes[1].minimum + (j + jitter[1]) * axes[1].step,
        )
    thresholds = {
        "crossing_axis": float(rng.uniform(2.0, 8.0)),
        "too_close": float(rng.uniform(4.0, 12.0)),
        "acute_angle": float(rng.uniform(8.0, 25.0)),
        "misalignment": float(rng.uniform(1.5, 5.0)),
    }
    view = space_from_positions(measured, axes=axes, thresholds=thresholds)
    return RandomSpace(number, axes, indices, thresholds, view, measured)


@pytest.fixture(scope="module")
def spaces() -> list[RandomSpace]:
    rng = np.random.default_rng(SEED)
    made = [generate_space(n, rng) for n in range(SPACES)]
    # The snapped positions are the generated grid cells (the jitter stayed under half a step).
    for space in made:
        for sample in space.view.samples:
            expected = tuple(float(space.value(sample.name, k)) for k in range(2))
            assert sample.position == pytest.approx(expected, abs=1e-9), space.describe()
    return made


# -- the brute force --------------------------------------------------------------------------------


def squared(a: Exact, b: Exact) -> Fraction:
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2


def below(distance_squared: Fraction, threshold: float) -> bool:
    """distance < threshold, exactly."""
    return distance_squared < Fraction(threshold) ** 2


def names_of(space: RandomSpace) -> list[str]:
    return [s.name for s in space.view.samples]


def edges_of(space: RandomSpace) -> set[frozenset[str]]:
    names = names_of(space)
    return {frozenset((names[t[a]], names[t[(a + 1) % 3]])) for t in space.view.triangles for a in range(3)}


def expected_crossings(space: RandomSpace) -> set[Key]:
    """Edges whose ends lie on opposite sides of x = 0 or y = 0, both farther than crossing_axis.

    When there is one, every key clip missing from the main axes is reported too: idle, the turns
    in place at plus and minus the largest |x| of the set, and the fastest forward and backward samples
    moved onto x = 0. A key clip counts as present when a sample is within crossing_axis of it.
    """
    tau = Fraction(space.thresholds["crossing_axis"])
    found: set[Key] = set()
    for edge in edges_of(space):
        a, b = sorted(edge)
        for k, axis_name in enumerate("xy"):
            line = space.line(k)
            if line is None:
                continue
            da, db = space.point(a)[k] - line, space.point(b)[k] - line
            if da * db < 0 and abs(da) > tau and abs(db) > tau:
                found.add(("edge", edge, axis_name))
    if not found or space.line(0) is None or space.line(1) is None:
        return found
    x_axis, y_axis = space.axes
    keys = [(Fraction(0), Fraction(0))]
    # Turns in place at the largest turn the set has (not at half the range), when it turns
    # farther than crossing_axis from the axis.
    reach = max(abs(space.value(n, 0)) for n in names_of(space))
    if reach / (Fraction(x_axis.maximum) - Fraction(x_axis.minimum)) * 100 > tau:
        keys += [
            (max(-reach, Fraction(x_axis.minimum)), Fraction(0)),
            (min(reach, Fraction(x_axis.maximum)), Fraction(0)),
        ]
    ys = [space.value(n, 1) for n in names_of(space)]
    if any(y > 0 for y in ys):
        keys.append((Fraction(0), max(ys)))
    if any(y < 0 for y in ys):
        keys.append((Fraction(0), min(ys)))
    for position in keys:
        target: Exact = (
            (position[0] - Fraction(x_axis.minimum))
            / (Fraction(x_axis.maximum) - Fraction(x_axis.minimum))
            * 100,
            (position[1] - Fraction(y_axis.minimum))
            / (Fraction(y_axis.maximum) - Fraction(y_axis.minimum))
            * 100,
        )
        if not any(squared(space.point(n), target) <= tau**2 for n in names_of(space)):
            found.add(("key", round(float(position[0]), 6), round(float(position[1]), 6)))
    return found


def actual_crossings(findings: list[Diagnostic]) -> set[Key]:
    found: set[Key] = set()
    for d in findings:
        if d.clips:
            assert d.fix_data is not None
            found.add(("edge", frozenset(d.clips), d.fix_data["axis"]))
        else:
            assert d.position is not None
            found.add(("key", round(d.position[0], 6), round(d.position[1], 6)))
    return found


def expected_acute(space: RandomSpace) -> set[Key]:
    """Triangles with an interior angle below acute_angle (law of cosines on the normalised sides)."""
    names = names_of(space)
    limit = math.radians(space.thresholds["acute_angle"])
    found: set[Key] = set()
    for triangle in space.view.triangles:
        corners = [names[i] for i in triangle]
        sides = [
            squared(space.point(corners[(n + 1) % 3]), space.point(corners[(n + 2) % 3])) for n in range(3)
        ]
        for n in range(3):  # the angle at corner n faces side n
            b2, c2 = sides[(n + 1) % 3], sides[(n + 2) % 3]
            cosine = (b2 + c2 - sides[n]) / (2 * math.sqrt(b2 * c2))
            if math.acos(max(-1.0, min(1.0, float(cosine)))) < limit:
                found.add(("triangle", frozenset(corners)))
    return found


def expected_too_close(space: RandomSpace) -> set[Key]:
    """Leader groups, by brute force in exact arithmetic: while some free sample has a free
    neighbour closer than too_close, the one with the most (then nearest the centre of its group,
    then first by name) takes them all and keeps its own name as the representative."""
    names = names_of(space)
    neighbours = {
        a: {
            b
            for b in names
            if b != a and below(squared(space.point(a), space.point(b)), space.thresholds["too_close"])
        }
        for a in names
    }
    free = set(names)
    found: set[Key] = set()
    while True:
        candidates = []
        for a in sorted(free):
            group = {a} | (neighbours[a] & free)
            if len(group) < 2:
                continue
            centre = (
                sum((space.point(n)[0] for n in group), Fraction(0)) / len(group),
                sum((space.point(n)[1] for n in group), Fraction(0)) / len(group),
            )
            candidates.append(((-len(group), squared(space.point(a), centre), a), group))
        if not candidates:
            return found
        (_, _, keep), group = min(candidates, key=lambda candidate: candidate[0])
        free -= group
        found.add(("cluster", frozenset(group), keep))


def actual_too_close(findings: list[Diagnostic]) -> set[Key]:
    return {("cluster", frozenset(d.clips), (d.fix_data or {}).get("keep")) for d in findings}


def expected_misalignment(space: RandomSpace) -> set[Key]:
    """Samples whose measured (unsnapped) position is off a main axis by more than noise (0.01)
    and at most misalignment, in normalised units: snapping onto the axis hides nothing."""
    tau = space.thresholds["misalignment"]
    found: set[Key] = set()
    for name in names_of(space):
        for k, axis_name in enumerate("xy"):
            line = space.line(k)
            if line is None:
                continue
            axis = space.axes[k]
            at = (space.measured[name][k] - axis.minimum) / (axis.maximum - axis.minimum) * 100
            if 0.01 < abs(at - float(line)) <= tau:
                found.add(("off-axis", name, axis_name))
    return found


def actual_misalignment(findings: list[Diagnostic]) -> set[Key]:
    return {("off-axis", d.clips[0], (d.fix_data or {}).get("axis")) for d in findings}


CANDIDATES = [
    (Fraction(x), Fraction(y))
    for x, y in ((0, 0), (100, 0), (100, 100), (0, 100), (50, 0), (100, 50), (50, 100), (0, 50))
]


def hull_of(space: RandomSpace) -> list[Exact]:
    """Convex hull vertices, counter-clockwise; empty when the samples enclose no area."""
    points = [space.point(n) for n in names_of(space)]
    try:
        return [points[i] for i in ConvexHull(np.array(points, dtype=np.float64)).vertices]
    except QhullError:  # fewer than three points off one line
        return []


def covered_percent(space: RandomSpace) -> Fraction:
    """Share of the 0..100 square inside the samples' convex hull (shoelace area), in percent."""
    hull = hull_of(space)
    edges = zip(hull, hull[1:] + hull[:1], strict=True)
    area = abs(sum((a[0] * b[1] - b[0] * a[1] for a, b in edges), Fraction(0))) / 2
    return area / 100


def expected_uncovered(space: RandomSpace) -> set[Key]:
    """When less than the whole square is covered: one finding."""
    if covered_percent(space) >= 100:
        return set()
    return {("uncovered",)}


def actual_uncovered(space: RandomSpace, findings: list[Diagnostic]) -> set[Key]:
    """One key per finding, after checking the covered percentage it prints and that every
    suggested placeholder is a reachable one: outside the hull, inside the rectangle and within
    the extents of the set (never a bare corner of the rectangle the set does not reach)."""
    found: set[Key] = set()
    exact = covered_percent(space)
    hull = hull_of(space)
    names = names_of(space)
    for d in findings:
        match = re.search(r"cover (\d+\.\d)%", d.message)
        assert match, d.message
        # Printed with one decimal: within half a unit of the last digit of the exact share.
        assert abs(Fraction(match[1]) - exact) <= Fraction(1, 20) + Fraction(1, 10**9), (
            f"{d.message}, but the exact share is {float(exact):.4f}% in {space.describe()}"
        )
        for mark in d.placeholders:
            p = space.view.to_normalised(mark.position)
            assert -1e-9 <= p[0] <= 100 + 1e-9 and -1e-9 <= p[1] <= 100 + 1e-9, space.describe()
            for k in (0, 1):
                values = [space.measured[n][k] for n in names]
                if space.axes[k].feature == "turn_rate":  # a body turns both ways as fast
                    values += [-v for v in values]
                assert min(values) - 1e-9 <= mark.position[k] <= max(values) + 1e-9, space.describe()
            edges = zip(hull, hull[1:] + hull[:1], strict=True)
            exact_p = (Fraction(p[0]), Fraction(p[1]))
            assert len(hull) < 3 or any(
                (b[0] - a[0]) * (exact_p[1] - a[1]) - (b[1] - a[1]) * (exact_p[0] - a[0]) < 0
                for a, b in edges
            ), f"{mark.position} is inside the hull in {space.describe()}"
        found.add(("uncovered",))
    return found


# -- the comparison ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    rule: type[Rule]
    severity: str
    expected: Callable[[RandomSpace], set[Key]]
    actual: Callable[[RandomSpace, list[Diagnostic]], set[Key]]
    at_least: int  # findings the generated spaces must produce, so the test cannot pass vacuously


CASES = {
    "crossing-axis": Case(CrossingAxis, "error", expected_crossings, lambda s, f: actual_crossings(f), 600),
    "acute-triangle": Case(
        AcuteTriangle,
        "warning",
        expected_acute,
        lambda s, f: {("triangle", frozenset(d.clips)) for d in f},
        500,
    ),
    "misalignment": Case(
        Misalignment, "warning", expected_misalignment, lambda s, f: actual_misalignment(f), 200
    ),
    "too-close": Case(TooClose, "warning", expected_too_close, lambda s, f: actual_too_close(f), 150),
    "uncovered-area": Case(UncoveredArea, "info", expected_uncovered, actual_uncovered, SPACES - 5),
}


@pytest.mark.parametrize("slug", list(CASES))
def test_recall_and_precision(slug: str, spaces: list[RandomSpace]) -> None:
    case = CASES[slug]
    expected_total = found_total = hits = 0
    missed: list[str] = []
    spurious: list[str] = []
    for space in spaces:
        findings = run_rule(case.rule, space.view)
        assert all(d.rule == slug and d.severity == case.severity for d in findings)
        expected = case.expected(space)
        actual = case.actual(space, findings)
        expected_total += len(expected)
        found_total += len(actual)
        hits += len(expected & actual)
        missed += [f"{key}\n      in {space.describe()}" for key in expected - actual]
        spurious += [f"{key}\n      in {space.describe()}" for key in actual - expected]
    recall = hits / expected_total if expected_total else 1.0
    precision = hits / found_total if found_total else 1.0
    report = (
        f"{slug}: recall {recall:.4f} ({hits}/{expected_total}), precision {precision:.4f} ({hits}/{found_total})\n"
        + "".join(f"  missed   {m}\n" for m in missed[:10])
        + "".join(f"  spurious {s}\n" for s in spurious[:10])
    )
    assert recall == 1.0 and precision == 1.0, report
    assert expected_total >= case.at_least, f"too few {slug} findings to mean anything: {report}"
    print(report)
