"""`range: auto` on long takes of several steady parts (LaFAN1 or 100STYLE style: a walk, then a
turn, then a run, in one file). Truth by construction (`motion.hostile.joined`): each part is a
planted-feet procedural clip of known speed, turn and direction. Auto must measure one part, and
all of it but its ends, never an average of two: a straight walk then a turning one read 22.5
deg/s (neither part), a walk then a run read 1.9 m/s (the whole take, "no steady cycles")."""

from __future__ import annotations

import pytest

from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.hostile import joined
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec

WALK = GaitSpec("walk", speed=1.4, duration=6.0, fps=60.0)
TURN = GaitSpec("turn", speed=1.4, turn_rate=45.0, duration=6.0, fps=60.0)
RIGHT = GaitSpec("right", speed=1.4, turn_rate=-20.0, duration=5.0, fps=60.0)
RUN = GaitSpec("run", speed=3.5, duration=3.0, fps=60.0, stride_length=2.8)
SLOW = GaitSpec("slow", speed=0.9, duration=4.0, fps=60.0, stride_length=1.0)
STRAFE = GaitSpec("strafe", speed=1.2, direction=90.0, duration=5.0, fps=60.0, stride_length=1.0)
LONG_WALK = GaitSpec("long walk", speed=1.4, duration=9.0, fps=60.0)

TAKES = {
    "walk then turn": [WALK, TURN],
    "turn then walk": [TURN, WALK],
    "long walk then run": [LONG_WALK, RUN],
    "run then long walk": [RUN, LONG_WALK],
    "walk, right turn, run": [WALK, RIGHT, RUN],
    "slow then walk": [SLOW, WALK],
    "walk then strafe": [WALK, STRAFE],
}


def _start(parts: list[GaitSpec], index: int) -> float:
    return sum(p.duration for p in parts[:index])


@pytest.mark.parametrize("name", list(TAKES))
def test_range_auto_measures_one_steady_part_of_a_long_take(name: str) -> None:
    parts = TAKES[name]
    m = measure(joined(name, parts), RigSettings(), "auto")
    assert m.range_used is not None
    first, last = m.range_used
    inside = [
        i
        for i, part in enumerate(parts)
        if _start(parts, i) - 1e-6 <= first and last <= _start(parts, i + 1) + 1e-6
    ]
    assert len(inside) == 1, (name, m.range_used)  # one part, not across a change
    part = parts[inside[0]]
    assert m.features["speed"] == pytest.approx(part.speed, rel=0.03), name
    assert m.features["turn_rate"] == pytest.approx(part.turn_rate, abs=1.5), name
    assert m.features["direction"] == pytest.approx(part.direction, abs=3.0), name
    # All of the part but a cycle or so at either end (the change of gait is no steady cycle).
    period = part.stride_length / part.speed
    assert last - first >= part.duration - 2.5 * period, name


def test_range_auto_takes_the_longest_steady_part() -> None:
    """Of a 9 s walk and a 3 s run the walk is measured (the longest steady part), in either order."""
    for parts in ([LONG_WALK, RUN], [RUN, LONG_WALK]):
        m = measure(joined("take", parts), RigSettings(), "auto")
        assert m.features["speed"] == pytest.approx(1.4, rel=0.03)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("spread", [3.0, 5.0])
def test_range_auto_keeps_a_walk_whose_heading_wanders(spread: float, seed: int) -> None:
    """An actor's straight walk turns a few degrees one way or the other every cycle. A fixed
    5-degree band cut such a 16 s walk to the 8 s whose cycles curved alike, and read a turn of
    the wrong sign; the band follows the take's own cycle-to-cycle noise."""
    import numpy as np

    per_cycle = np.random.default_rng(seed).normal(0.0, spread, 16)  # degrees each cycle turns
    parts = [
        GaitSpec("walk", speed=1.4, stride_length=1.4, duration=1.0, fps=60.0, turn_rate=float(t))
        for t in per_cycle
    ]
    m = measure(joined("walk", parts), RigSettings(), "auto")
    assert m.range_used is not None and m.range_used[1] - m.range_used[0] >= 11.0
    assert m.features["speed"] == pytest.approx(1.4, rel=0.02)
    assert m.features["turn_rate"] == pytest.approx(float(per_cycle.mean()), abs=1.5)
