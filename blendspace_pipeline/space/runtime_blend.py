"""What the engine delivers over the hull, from the document alone (no clip is read).

At a query the engine weights the samples of the triangle holding it (barycentric weights on
the placed positions), syncs them (`motion.blend_model.playback_rates`) and plays each at its
rate. Root motion extracted from a clip played at rate r moves r times as fast and turns r times
as fast, so over whole cycles the character moves with

    forward = sum w_i r_i forward_i,  left = sum w_i r_i lateral_i,  turn = sum w_i r_i turn_rate_i

and the axis features follow from those (speed, direction). The snapping-only map
(`report.trajectory_error`) is the special case r_i = 1 (sync ``none``). The error at a query is
the distance between what it asks and what that delivers, per axis and normalised; the drift is
how far apart the requested and delivered paths end after ``horizon`` seconds of that motion
(what a player sees: the character ends up metres away and turned).

The foot-skate map needs poses; `pipeline.blend_quality` plays the blend on the clips
(`motion.blend_model.play`) on the same grid.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from blendspace_pipeline.motion.blend_model import DEFAULT_SYNC, SyncMode, playback_rates
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.space.document import BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.geometry import NORMALISED_EXTENT, AxisRange, locate, normalise

DEFAULT_HORIZON = 6.0  # seconds of play the drift is measured over
DEFAULT_GRID = 21  # grid points per axis in the document and the report
VELOCITY_FEATURES = frozenset({"forward_speed", "lateral_speed", "turn_rate", "speed", "direction"})


@dataclass(frozen=True)
class Motion:
    """Steady motion in the character's frame: m/s forward and to the left, deg/s to the left."""

    forward: float
    lateral: float
    turn_rate: float

    def feature(self, name: str) -> float | None:
        speed = math.hypot(self.forward, self.lateral)
        direction = math.degrees(math.atan2(self.lateral, self.forward)) if speed > 1e-9 else 0.0
        values = {
            "forward_speed": self.forward,
            "lateral_speed": self.lateral,
            "turn_rate": self.turn_rate,
            "direction": direction,
            "speed": -speed if abs(direction) > 90.0 + 1e-6 else speed,
        }
        return values.get(name)

    def end_point(self, seconds: float) -> tuple[float, float, float]:
        """(x, y, heading deg) after ``seconds`` from the origin facing +x (exact arc)."""
        omega = math.radians(self.turn_rate)
        if abs(omega) < 1e-9:
            return self.forward * seconds, self.lateral * seconds, 0.0
        theta = omega * seconds
        # Integral of R(omega t) (f, l) dt: the body-frame velocity turning with the heading.
        s, c = math.sin(theta), math.cos(theta)
        x = (self.forward * s - self.lateral * (1.0 - c)) / omega
        y = (self.forward * (1.0 - c) + self.lateral * s) / omega
        return x, y, math.degrees(theta)


def sample_motion(sample: SampleDoc) -> Motion | None:
    f = sample.features
    if "forward_speed" not in f or "lateral_speed" not in f or "turn_rate" not in f:
        return None
    return Motion(f["forward_speed"], f["lateral_speed"], f["turn_rate"])


def sample_period(sample: SampleDoc) -> float | None:
    info = sample.clip
    return info.gait_period if info is not None and info.gait_period else None


def delivered(samples: Sequence[SampleDoc], weights: Sequence[float], sync: SyncMode) -> Motion | None:
    """The steady motion of the blend of ``samples`` under ``sync``; None when a sample lacks
    the velocity features."""
    motions = [sample_motion(s) for s in samples]
    if any(m is None for m in motions):
        return None
    durations = [s.features.get("duration", 1.0) for s in samples]
    rates = playback_rates(weights, durations, [sample_period(s) for s in samples], sync)
    total = sum(weights)
    parts = [(w / total * r, m) for w, r, m in zip(weights, rates, motions, strict=True) if m is not None]
    return Motion(
        sum(k * m.forward for k, m in parts),
        sum(k * m.lateral for k, m in parts),
        sum(k * m.turn_rate for k, m in parts),
    )


def delivered_at_rates(
    samples: Sequence[SampleDoc], weights: Sequence[float], rates: Sequence[float]
) -> Motion | None:
    """The steady motion of the blend when each sample plays at the given ``rates`` (what
    `eval` prescribes); None when a sample lacks the velocity features."""
    motions = [sample_motion(s) for s in samples]
    total = sum(weights)
    if total <= 0.0 or any(m is None for m in motions):
        return None
    parts = [(w / total * r, m) for w, r, m in zip(weights, rates, motions, strict=True) if m is not None]
    return Motion(
        sum(k * m.forward for k, m in parts),
        sum(k * m.lateral for k, m in parts),
        sum(k * m.turn_rate for k, m in parts),
    )


def requested(promise: Motion, features: Sequence[str], query: Sequence[float]) -> Motion:
    """The motion a query asks for: the placement's promise (the blend at rate 1) with the axis
    features set to the query's values."""
    forward, lateral, turn = promise.forward, promise.lateral, promise.turn_rate
    for feature, value in zip(features, query, strict=True):
        if feature == "forward_speed":
            forward = value
        elif feature == "lateral_speed":
            lateral = value
        elif feature == "turn_rate":
            turn = value
        elif feature == "speed":
            size = math.hypot(forward, lateral)
            if size > 1e-9:
                forward, lateral = forward / size * abs(value), lateral / size * abs(value)
            else:
                forward = value
        elif feature == "direction":
            size = math.hypot(forward, lateral)
            forward, lateral = size * math.cos(math.radians(value)), size * math.sin(math.radians(value))
    return Motion(forward, lateral, turn)


@dataclass(frozen=True)
class RuntimeGrid:
    """The engine's blend on a grid over the axis rectangle; rows along y, columns along x.
    NaN outside the hull (engines clamp there) and where the features are unknown."""

    sync: SyncMode
    horizon: float
    xs: FloatArray
    ys: FloatArray
    error_x: FloatArray  # |requested - delivered| along x, axis units
    error_y: FloatArray
    distance: FloatArray  # the error in normalised units (% of an axis range)
    drift: FloatArray  # metres between requested and delivered paths after `horizon` seconds
    drift_turn: FloatArray  # degrees between their headings then
    inside: FloatArray  # bool (ny, nx)
    weights: list[list[tuple[int, float]] | None]  # per grid point (row-major): (sample, weight)

    @property
    def max_distance(self) -> float:
        return float(np.nanmax(self.distance)) if np.isfinite(self.distance).any() else 0.0

    @property
    def mean_distance(self) -> float:
        return float(np.nanmean(self.distance)) if np.isfinite(self.distance).any() else 0.0


def _ranges(doc: BlendSpaceDocument) -> tuple[AxisRange, AxisRange]:
    x, y = doc.axes
    return AxisRange(x.min, x.max), AxisRange(y.min, y.max)


def runtime_grid(
    doc: BlendSpaceDocument,
    sync: SyncMode = DEFAULT_SYNC,
    resolution: int = DEFAULT_GRID,
    horizon: float = DEFAULT_HORIZON,
) -> RuntimeGrid:
    axes = _ranges(doc)
    nx = ny = resolution
    unit = np.linspace(0.0, NORMALISED_EXTENT, nx), np.linspace(0.0, NORMALISED_EXTENT, ny)
    gx, gy = np.meshgrid(*unit)
    queries = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    xs = np.linspace(axes[0].minimum, axes[0].maximum, nx)
    ys = np.linspace(axes[1].minimum, axes[1].maximum, ny)
    axis_query = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    count = len(queries)
    error = np.full((count, 2), np.nan)
    drift = np.full(count, np.nan)
    drift_turn = np.full(count, np.nan)
    inside = np.zeros(count, dtype=bool)
    weights_out: list[list[tuple[int, float]] | None] = [None] * count
    features = [a.feature for a in doc.axes]
    if doc.triangles and doc.samples:
        placed = normalise(np.asarray([s.position for s in doc.samples], dtype=np.float64), axes)
        tris = np.asarray(doc.triangles, dtype=np.int64)
        found, bary = locate(queries, placed, tris)
        for q in np.flatnonzero(found >= 0):
            corners = [int(i) for i in tris[found[q]]]
            w = [max(0.0, float(v)) for v in bary[q]]
            pairs = [(i, wi) for i, wi in zip(corners, w, strict=True) if wi > 1e-9]
            inside[q] = True
            weights_out[q] = pairs
            chosen = [doc.samples[i] for i, _ in pairs]
            ws = [wi for _, wi in pairs]
            got = delivered(chosen, ws, sync)
            promise = delivered(chosen, ws, "none")
            if got is None or promise is None:
                continue
            wanted = requested(promise, features, axis_query[q])
            values = [got.feature(f) for f in features]
            for k, (feature, value) in enumerate(zip(features, values, strict=True)):
                if value is None:  # not a velocity feature: the rate does not change it
                    value = sum(
                        wi * s.features.get(feature, 0.0) for wi, s in zip(ws, chosen, strict=True)
                    ) / sum(ws)
                error[q, k] = abs(axis_query[q][k] - value)
                del feature
            a, b = wanted.end_point(horizon), got.end_point(horizon)
            drift[q] = math.hypot(a[0] - b[0], a[1] - b[1])
            drift_turn[q] = abs(a[2] - b[2])
    spans = np.array([axes[0].span, axes[1].span]) / NORMALISED_EXTENT
    normalised = error / spans
    shape = (ny, nx)
    return RuntimeGrid(
        sync=sync,
        horizon=horizon,
        xs=xs,
        ys=ys,
        error_x=error[:, 0].reshape(shape),
        error_y=error[:, 1].reshape(shape),
        distance=np.hypot(normalised[:, 0], normalised[:, 1]).reshape(shape),
        drift=drift.reshape(shape),
        drift_turn=drift_turn.reshape(shape),
        inside=inside.reshape(shape),
        weights=weights_out,
    )
