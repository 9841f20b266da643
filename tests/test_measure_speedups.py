"""The vectorised helpers of measurement answer exactly as the frame-by-frame loops they replaced.

Each reference below is the loop as it was (issue 15 vectorised them for speed); they are run on
random signals, noisy sinusoids and hand-made edge cases, and must agree to the last bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from blendspace_pipeline.motion import contacts, detect, stats
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip_ops import phase, sway
from blendspace_pipeline.motion.quaternions import FloatArray


def crossings_loop(signal: FloatArray, hysteresis: float) -> tuple[FloatArray, FloatArray]:
    ups, downs = [], []
    state = 0
    last_zero = 0.0
    for i in range(1, len(signal)):
        a, b = float(signal[i - 1]), float(signal[i])
        if (a < 0.0) != (b < 0.0):
            last_zero = i - 1 + a / (a - b)
        if b > hysteresis:
            if state < 0:
                ups.append(last_zero)
            state = 1
        elif b < -hysteresis:
            if state > 0:
                downs.append(last_zero)
            state = -1
    return np.array(ups, dtype=np.float64), np.array(downs, dtype=np.float64)


def upward_crossings_loop(signal: FloatArray, hysteresis: float) -> FloatArray:
    below = signal < -hysteresis
    ups = []
    armed = False
    for i in range(1, len(signal)):
        if below[i - 1]:
            armed = True
        a, b = float(signal[i - 1]), float(signal[i])
        if armed and a < 0.0 <= b:
            ups.append(i - 1 + a / (a - b) if a != b else float(i))
            armed = False
    return np.array(ups, dtype=np.float64)


def hysteresis_loop(low: FloatArray, near: float, speed: FloatArray, limit: float) -> FloatArray:
    inside = np.zeros(len(low), dtype=bool)
    state = False
    for i in range(len(low)):
        if state:
            state = bool(low[i] <= near * contacts._RELEASE and speed[i] <= limit * contacts._RELEASE)
        else:
            state = bool(low[i] <= near and speed[i] <= limit)
        inside[i] = state
    return inside


def intervals_loop(mask: FloatArray, fps: float) -> list[tuple[float, float]]:
    frames = len(mask)
    runs: list[list[int]] = []
    start = None
    for i in range(frames + 1):
        on = bool(mask[i]) if i < frames else False
        if on and start is None:
            start = i
        elif not on and start is not None:
            runs.append([start, i - 1])
            start = None
    shortest = contacts._MIN_EVENT * fps
    merged: list[list[int]] = []
    for run in runs:
        if merged and run[0] - merged[-1][1] - 1 < shortest:
            merged[-1][1] = run[1]
        else:
            merged.append(run)
    kept = [r for r in merged if r[1] - r[0] + 1 >= shortest or r[0] == 0 or r[1] == frames - 1]
    return [(r[0] / fps, r[1] / fps) for r in kept if r[1] > r[0]]


def anchors_loop(
    ups: FloatArray, downs: FloatArray, rate: float, offset: float
) -> tuple[FloatArray, FloatArray]:
    fractions = [
        (down - ups[ups < down][-1]) / (ups[ups > down][0] - ups[ups < down][-1])
        for down in downs
        if (ups < down).any() and (ups > down).any()
    ]
    half = float(np.median(fractions)) if fractions else 0.5
    marks = np.concatenate([ups, downs])
    is_up = np.concatenate([np.ones(len(ups), bool), np.zeros(len(downs), bool)])
    order = np.argsort(marks, kind="stable")
    marks, is_up = marks[order], is_up[order]
    if not len(marks):
        return marks, marks
    steps = np.where(is_up[1:], 1.0 - half, half)
    relative = np.concatenate([[0.0 if is_up[0] else half], (0.0 if is_up[0] else half) + np.cumsum(steps)])
    whole = float(np.round(np.median(rate * marks + offset - relative)))
    return marks, relative + whole


def signals() -> list[FloatArray]:
    rng = np.random.default_rng(15)
    found: list[FloatArray] = [
        np.zeros(0),
        np.zeros(1),
        np.zeros(5),
        np.array([-1.0, 1.0]),
        np.array([1.0, -1.0, 1.0, -1.0]),
        np.array([-0.0, 0.0, -0.0, 0.5, -0.5]),
        np.array([-2.0, 0.0, 0.0, 2.0, 0.0, -2.0, -2.0, 0.0, 3.0]),
    ]
    for _ in range(40):
        frames = int(rng.integers(2, 400))
        t = np.arange(frames) / 30.0
        wave = np.sin(2.0 * np.pi * rng.uniform(0.3, 3.0) * t + rng.uniform(0, 6.3))
        found.append(wave + rng.normal(0.0, rng.uniform(0.0, 0.6), frames))
        found.append(rng.normal(0.0, 1.0, frames))
        found.append(np.round(rng.normal(0.0, 1.0, frames)))  # exact zeros and repeated values
    return found


@pytest.mark.parametrize("hysteresis", [0.0, 0.1, 0.25, 0.8, 5.0])
def test_crossings_match_the_loop(hysteresis: float) -> None:
    for signal in signals():
        for got, want in zip(
            phase._crossings(signal, hysteresis), crossings_loop(signal, hysteresis), strict=True
        ):
            assert got.dtype == want.dtype
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("hysteresis", [0.0, 0.1, 0.25, 0.8, 5.0])
def test_upward_crossings_match_the_loop(hysteresis: float) -> None:
    for signal in signals():
        np.testing.assert_array_equal(
            sway._upward_crossings(signal, hysteresis), upward_crossings_loop(signal, hysteresis)
        )


@pytest.mark.parametrize("hysteresis", [0.0, 0.2, 0.6])
def test_anchors_match_the_loop(hysteresis: float) -> None:
    """`_anchors` finds each down crossing's neighbouring up crossings by binary search."""
    for signal in signals():
        ups, downs = crossings_loop(signal, hysteresis)
        for got, want in zip(
            phase._anchors(ups, downs, 0.013, 0.3), anchors_loop(ups, downs, 0.013, 0.3), strict=True
        ):
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("near, limit", [(0.05, 0.4), (0.03, 0.35), (0.1, 1.2), (float("nan"), 0.4)])
def test_hysteresis_matches_the_loop(near: float, limit: float) -> None:
    rng = np.random.default_rng(7)
    for _ in range(60):
        frames = int(rng.integers(0, 300))
        low = np.abs(rng.normal(0.0, 2.0 * np.nan_to_num(near, nan=0.05), frames))
        speed = np.abs(rng.normal(0.0, limit, frames))
        if frames > 3:
            low[rng.integers(0, frames)] = np.nan
        np.testing.assert_array_equal(
            contacts._hysteresis(low, near, speed, limit), hysteresis_loop(low, near, speed, limit)
        )


def test_hysteresis_negative_thresholds_match_the_loop() -> None:
    low = np.array([-1.0, -0.5, -0.2, -0.9, -0.1])
    speed = np.zeros(5)
    np.testing.assert_array_equal(
        contacts._hysteresis(low, -0.3, speed, 0.1), hysteresis_loop(low, -0.3, speed, 0.1)
    )


@pytest.mark.parametrize("fps", [24.0, 30.0, 120.0])
def test_intervals_match_the_loop(fps: float) -> None:
    rng = np.random.default_rng(3)
    masks = [np.zeros(0, dtype=bool), np.ones(1, dtype=bool), np.ones(9, dtype=bool), np.zeros(9, dtype=bool)]
    for _ in range(60):
        frames = int(rng.integers(1, 400))
        runs = rng.integers(1, 30, frames)  # alternating runs of random length
        masks.append((np.repeat(np.arange(frames) % 2, runs)[:frames] == rng.integers(0, 2)).astype(bool))
        masks.append(rng.random(frames) < rng.uniform(0.1, 0.9))
    for mask in masks:
        assert contacts._intervals(mask, fps) == intervals_loop(mask, fps)


def test_refinement_finds_the_exact_best_of_its_grid() -> None:
    """`_best_on_grid` (chirp-z, then exact fits near its maximum) picks the frequency fitting
    every grid point exactly picks, on noisy strides of real-take lengths and rates."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(30):
        fps = float(rng.choice([30.0, 60.0, 120.0]))
        frames = int(rng.integers(60, 1500))
        times = np.arange(frames) / fps
        stride = rng.uniform(0.6, 3.0)
        drift = 1.0 + rng.uniform(-0.1, 0.1) * times / times[-1]  # a cadence that wanders
        signal = np.sin(2.0 * np.pi * stride * drift * times) + rng.normal(0.0, rng.uniform(0.0, 0.8), frames)
        duration = times[-1]
        for centre in (stride, stride * rng.uniform(0.7, 1.3)):
            step = 0.02 / duration
            for _refinement in range(2):
                grid = np.linspace(centre - step, centre + step, 41)
                exact = phase._sinusoid_fit(signal, times, grid)
                assert phase._best_on_grid(signal, times, grid, fps) == grid[int(np.argmax(exact))]
                centre, step = float(grid[int(np.argmax(exact))]), float(grid[1] - grid[0])
                checked += 1
    assert checked == 120


def stat_arrays() -> list[FloatArray]:
    rng = np.random.default_rng(21)
    found: list[FloatArray] = [
        np.array([3.0]),
        np.array([2.0, -1.0]),
        np.array([-0.0, 0.0, -0.0]),
        np.zeros(4),
    ]
    for _ in range(200):
        count = int(rng.integers(1, 900))
        values = rng.normal(0.0, rng.uniform(1e-3, 1e3), count)
        if rng.random() < 0.3:
            values = np.round(values)  # ties
        found.append(values)
    found.append(np.array([1.0, np.inf, 2.0]))
    found.append(np.array([1.0, np.nan, 2.0]))
    return found


@pytest.mark.parametrize("q", [0.0, 5.0, 50.0, 90.0, 95.0, 99.0, 100.0, 37.3])
def test_percentile_is_numpys(q: float) -> None:
    for values in stat_arrays():
        with np.errstate(invalid="ignore"):  # inf - inf in numpy's interpolation: NaN, as ours
            want = np.percentile(values, q)
        got = stats.percentile(values, q)
        assert got == want or (np.isnan(got) and np.isnan(want)), (q, values)
        assert np.signbit(got) == np.signbit(want)
    for values in stat_arrays()[:50]:
        both = stats.percentiles(values, (5.0, 95.0))
        assert both == [stats.percentile(values, 5.0), stats.percentile(values, 95.0)]


def test_median_is_numpys() -> None:
    for values in stat_arrays():
        with np.errstate(invalid="ignore"):
            want = np.median(values)
        got = stats.median(values)
        assert got == want or (np.isnan(got) and np.isnan(want)), values
        assert np.signbit(got) == np.signbit(want)


@pytest.mark.parametrize("joints", [1, 2, 19, 31, 60])
def test_joint_mean_is_numpys(joints: int) -> None:
    world_pos = np.random.default_rng(joints).normal(0.0, 30.0, (300, joints, 3))
    np.testing.assert_array_equal(contacts._joint_mean(world_pos, 0.0254), (world_pos * 0.0254).mean(axis=1))


def test_written_out_norms_are_numpys() -> None:
    rng = np.random.default_rng(4)
    for shape in [(500, 3), (500, 2), (200, 19, 3), (3,)]:
        vectors = rng.normal(0.0, 50.0, shape)
        np.testing.assert_array_equal(quat.vector_norm(vectors), np.linalg.norm(vectors, axis=-1))
    vectors = rng.normal(0.0, 50.0, (200, 19, 3))
    np.testing.assert_array_equal(
        detect._length(np.moveaxis(vectors, 2, 0)), np.linalg.norm(vectors, axis=-1)
    )
    np.testing.assert_array_equal(
        quat.cross(vectors, np.array([0.0, 1.0, 0.0])), np.cross(vectors, [0.0, 1.0, 0.0])
    )


def test_quaternion_product_is_the_stacked_one() -> None:
    """`quaternions.multiply` writes its components into one array; the values are the stacked
    expressions' to the last bit, broadcasting and dtype included."""
    rng = np.random.default_rng(8)
    a, b = rng.normal(size=(300, 7, 4)), rng.normal(size=(300, 7, 4))
    for left, right in [(a, b), (a[:, 2], b[:, 5]), (a, quat.IDENTITY), (a[:5].astype(np.float32), b[:5])]:
        ax, ay, az, aw = (left[..., i] for i in range(4))
        bx, by, bz, bw = (right[..., i] for i in range(4))
        stacked = np.stack(
            [
                aw * bx + ax * bw + ay * bz - az * by,
                aw * by - ax * bz + ay * bw + az * bx,
                aw * bz + ax * by - ay * bx + az * bw,
                aw * bw - ax * bx - ay * by - az * bz,
            ],
            axis=-1,
        )
        product = quat.multiply(left, right)
        assert product.dtype == stacked.dtype
        np.testing.assert_array_equal(product, stacked)


def test_rotation_is_the_vector_form() -> None:
    """`quaternions.rotate` written out per component equals v + w t + u x t, t = 2 u x v."""
    rng = np.random.default_rng(9)
    q = quat.normalize(rng.normal(size=(300, 7, 4)))
    v = rng.normal(0.0, 20.0, (300, 7, 3))
    for rotation, vectors in [(q, v), (q[:, 3], v[:, 1]), (q[0, 0], v), (q, v[0, 0])]:
        u, w = rotation[..., :3], rotation[..., 3:4]
        t = 2.0 * np.cross(u, vectors)
        np.testing.assert_array_equal(quat.rotate(rotation, vectors), vectors + w * t + np.cross(u, t))
