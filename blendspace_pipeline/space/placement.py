"""Placement: measured features → positions snapped to each axis's grid.

Engines store sample positions on a grid (Unreal: `GridNum` divisions per axis) and snap to the
nearest grid point; the snapping error is recorded so the report can show it. Values outside an
axis range are reported by the build, never silently clamped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Axis:
    name: str  # "x" or "y"
    feature: str
    minimum: float
    maximum: float
    divisions: int

    @property
    def step(self) -> float:
        return (self.maximum - self.minimum) / self.divisions

    def snap(self, value: float) -> float:
        """Nearest grid value; outside the range it keeps snapping on the same grid, so a value
        within half a step past an edge snaps onto the edge (see `contains`)."""
        scaled = (value - self.minimum) / self.step
        # Python's round is numpy's (half to even) on finite floats, without a numpy scalar per
        # call (placement snapped each of a thousand samples three times per build).
        index = round(scaled) if math.isfinite(scaled) else np.round(scaled)
        snapped = float(self.minimum + index * self.step)
        return round(snapped, 9) + 0.0  # "+ 0.0" turns -0.0 into 0.0

    def contains(self, value: float) -> bool:
        """Inside the range, or close enough past an edge to snap onto it: a 180.0002 deg/s spin
        (frame-time rounding) sits on the 180 edge, not outside. Half a step is what snapping
        moves any value by; beyond it the value would land on a grid point outside the axis."""
        tolerance = 0.5 * self.step * (1.0 - 1e-9)
        return self.minimum - tolerance <= value <= self.maximum + tolerance

    def inside(self, value: float) -> bool:
        """Strictly inside [minimum, maximum] (to rounding), without `contains`'s half step."""
        tolerance = 1e-9 * max(1.0, abs(self.maximum - self.minimum))
        return self.minimum - tolerance <= value <= self.maximum + tolerance

    def zero_on_grid(self) -> bool:
        """Whether 0 (the main axis through idle) is a grid value inside the range."""
        if not self.inside(0.0):
            return False
        return abs(self.snap(0.0)) < 1e-9


@dataclass(frozen=True)
class Placement:
    measured: tuple[float, float]
    position: tuple[float, float]

    @property
    def snapping_error(self) -> tuple[float, float]:
        return (self.position[0] - self.measured[0], self.position[1] - self.measured[1])


def place(features: dict[str, float], axes: tuple[Axis, Axis]) -> Placement:
    measured = (features[axes[0].feature], features[axes[1].feature])
    return Placement(measured=measured, position=(axes[0].snap(measured[0]), axes[1].snap(measured[1])))
