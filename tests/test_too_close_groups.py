"""too-close on dense libraries: a finding never chains across the space.

Single linkage (clusters = chains of close pairs) made one 1,000-clip finding of a random
1,000-clip library, and `keep-representative` would have dropped 999 clips. The hostile class is
any set where close pairs chain: uniform random libraries of growing density, evenly spaced lines
and grids just under the threshold, and dense blobs joined by bridges. On each, every finding's
members lie within too_close of its representative; keeping the representatives leaves no pair
closer than too_close; and every close pair has a member in some finding.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from blendspace_pipeline.rules.too_close import TooClose
from hypothesis import given, settings
from hypothesis import strategies as st

from blendspace_pipeline.space.placement import Axis
from blendspace_pipeline.testing import run_rule, space_from_positions

AXES = (Axis("x", "turn_rate", -180.0, 180.0, 3600), Axis("y", "speed", 0.0, 6.0, 600))


def _library(points: np.ndarray) -> dict[str, tuple[float, float]]:
    """Normalised 0..100 points as axis values (fine grid: snapping moves them by < 0.015)."""
    return {f"take_{i:05d}": (-180.0 + 3.6 * float(x), 0.06 * float(y)) for i, (x, y) in enumerate(points)}


def _check(points: np.ndarray, tau: float) -> int:
    view = space_from_positions(_library(points), axes=AXES, thresholds={"too_close": tau})
    findings = run_rule(TooClose, view)
    at = {s.name: np.asarray(s.normalised) for s in view.samples}
    in_finding: set[str] = set()
    kept: set[str] = set()
    for finding in findings:
        keep = finding.fix_data["keep"]  # type: ignore[index]
        assert keep in finding.clips
        for name in finding.clips:
            assert name not in in_finding, f"{name} is in two findings"
            assert math.dist(at[name], at[keep]) < tau, (
                f"{name} is {math.dist(at[name], at[keep])} from {keep}"
            )
        in_finding.update(finding.clips)
        kept.add(keep)
    survivors = [name for name in at if name in kept or name not in in_finding]
    for i, j in view.close_pairs(tau).tolist():
        a, b = view.samples[i].name, view.samples[j].name
        assert a in in_finding or b in in_finding, f"{a} and {b} are closer than {tau} and not reported"
    remaining = space_from_positions(
        {n: p for n, p in _library(points).items() if n in survivors},
        axes=AXES,
        thresholds={"too_close": tau},
    )
    assert not len(remaining.close_pairs(tau)), "keeping the representatives left clips too close"
    return max((len(f.clips) for f in findings), default=0)


@pytest.mark.parametrize("count", [100, 1000, 4000])
def test_a_random_library_makes_small_findings(count: int) -> None:
    points = np.random.default_rng(count).uniform(0.0, 100.0, size=(count, 2))
    largest = _check(points, 8.0)
    # A representative's group is its disc of radius 8: at 4,000 clips about 4000 * pi * 64 / 1e4 = 80.
    assert largest <= 2 * count * math.pi * 64 / 1e4 + 10


def test_a_line_just_under_the_threshold_is_not_one_finding() -> None:
    points = np.column_stack([np.linspace(2.0, 98.0, 200), np.full(200, 50.0)])  # 0.48 apart
    assert _check(points, 8.0) <= 2 * 8.0 / 0.48 + 2
    chain = np.column_stack([np.arange(0.0, 100.0, 7.9), np.full(13, 30.0)])  # each 7.9 from the next
    assert _check(chain, 8.0) == 3


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0, 100), st.floats(0, 100)), min_size=2, max_size=120),
    st.floats(0.5, 20.0),
)
def test_any_set_keeps_the_groups_within_the_threshold(points: list[tuple[float, float]], tau: float) -> None:
    _check(np.asarray(points, dtype=np.float64), tau)
