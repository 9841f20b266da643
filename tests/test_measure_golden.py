"""Measurement is pinned: every number `measure` produced before it was made faster (issue 15).

`measurement_golden.py` lists the clips (generated ones covering every branch of measurement,
and the CMU, Khronos and Godot takes of shared/data) and recorded their full `Measurement` and
gait cycle into ``measurement_golden.json`` from the code before the speed-up. A change that
moves any number by more than 1e-9 fails here; a deliberate change re-records the fixture and
bumps the measurement revision in `pipeline/cache.py`.
"""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from conftest import shared_data
from measurement_golden import FIXTURE, Case, generated_cases, record, shared_cases

from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import TimeRange

TOLERANCE = 1e-9
GOLDEN: dict[str, Any] = json.loads(FIXTURE.read_text())


def assert_same(actual: Any, expected: Any, where: str) -> None:
    if isinstance(expected, dict):
        assert isinstance(actual, dict) and sorted(actual) == sorted(expected), where
        for key in expected:
            assert_same(actual[key], expected[key], f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(actual) == len(expected), (
            f"{where}: {actual!r} != {expected!r}"
        )
        for index, (a, e) in enumerate(zip(actual, expected, strict=True)):
            assert_same(a, e, f"{where}[{index}]")
    elif isinstance(expected, float) and not isinstance(actual, bool):
        assert isinstance(actual, int | float), f"{where}: {actual!r} != {expected!r}"
        assert math.isclose(actual, expected, rel_tol=TOLERANCE, abs_tol=TOLERANCE), (
            f"{where}: {actual!r} != {expected!r}"
        )
    else:
        assert actual == expected, f"{where}: {actual!r} != {expected!r}"


def _check(name: str, clip: Clip, settings: RigSettings, time_range: TimeRange) -> None:
    assert_same(record(clip, settings, time_range), GOLDEN[name], name)


def test_the_fixture_covers_every_case() -> None:
    names = [name for name, *_ in [*generated_cases(), *shared_cases()]]
    assert sorted(names) == sorted(GOLDEN)


@pytest.mark.parametrize("case", list(generated_cases()), ids=lambda case: case[0])
def test_generated_clips_measure_as_before(case: Case) -> None:
    name, build, settings, time_range = case
    _check(name, build(), settings, time_range)


@pytest.mark.parametrize("case", list(shared_cases()), ids=lambda case: case[0])
def test_real_takes_measure_as_before(case: Case) -> None:
    name, build, settings, time_range = case
    shared_data()  # skips without ../shared/data
    _check(name, build(), settings, time_range)


def test_the_comparison_notices_a_change() -> None:
    """The oracle can fail: a feature off by 1e-8 (relative) is caught, and so is a new note."""
    expected = GOLDEN["walk"]
    moved = json.loads(json.dumps(expected))
    moved["measurement"]["features"]["speed"] *= 1.0 + 1e-8
    with pytest.raises(AssertionError, match="speed"):
        assert_same(moved, expected, "walk")
    noted = json.loads(json.dumps(expected))
    noted["measurement"]["notes"].append("extra")
    with pytest.raises(AssertionError, match="notes"):
        assert_same(noted, expected, "walk")
