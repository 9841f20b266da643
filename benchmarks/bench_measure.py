"""Measurement of long clips: linear in the clip's length, and at most twice the read time.

    python benchmarks/bench_measure.py [--seconds 10 60 300]

Each clip is a procedural walk at 120 fps written as BVH once into a temporary folder (a take that
does not loop: it is cut mid-stride, so the stride period comes from the frequency fit, the part
that used to be quadratic). For every length the run reports, in one process: the read time (the
baseline), the measure time and their ratio (the issue's goal: <= 2x), and the measure time per
second of clip, which stays flat when measurement is linear. The quadratic grid fit the chirp-z
transform replaced is timed beside it on the same signal, as a second baseline. Nothing here
asserts a time; the numbers go in the issue notes.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion.clip_ops import phase
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.writers.bvh import write_bvh_clip


def direct_grid_seconds(signal: np.ndarray, fps: float) -> float:
    """The coarse grid as it was: every frequency fitted on its own (n products per frequency)."""
    duration = (len(signal) - 1) / fps
    low, step = phase.MIN_CYCLES / duration, 0.02 / duration
    grid = np.arange(low, min(1.0 / phase.MIN_PERIOD_S, fps / 4.0) + step, step)
    thin = max(1, int(fps // 30))
    times = np.arange(len(signal))[::thin] / fps
    start = time.perf_counter()
    for i in range(0, len(grid), 256):
        phase._sinusoid_fit(signal[::thin], times, grid[i : i + 256])
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, nargs="+", default=[10.0, 60.0, 300.0])
    parser.add_argument(
        "--skip-direct-above", type=float, default=60.0, help="the old grid takes minutes there"
    )
    args = parser.parse_args()
    settings = RigSettings()
    print(
        f"{'clip':>8} {'MB':>6} {'read s':>8} {'measure s':>10} {'measure/read':>13} {'ms per clip s':>14} {'old grid s':>11}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for seconds in args.seconds:
            path = Path(tmp) / f"walk_{seconds:g}.bvh"
            # Cut 37 frames in and before the loop's end so the take does not loop.
            whole = generate(GaitSpec("walk", speed=1.5, duration=seconds + 1.0, fps=120.0, turn_rate=10.0))
            write_bvh_clip(whole.trimmed(37, 37 + round(seconds * 120.0) + 1), path)
            start = time.perf_counter()
            clip = read_clips(path)[0]
            read = time.perf_counter() - start
            start = time.perf_counter()
            measure(clip, settings)
            measured = time.perf_counter() - start
            old = "-"
            if seconds <= args.skip_direct_above:
                found = phase.foot_signal(clip, settings)
                assert found is not None
                old = f"{direct_grid_seconds(found[0], clip.fps):.2f}"
            print(
                f"{seconds:>7g}s {path.stat().st_size / 1e6:>6.1f} {read:>8.3f} {measured:>10.3f} "
                f"{measured / read:>12.2f}x {1000.0 * measured / seconds:>14.2f} {old:>11}"
            )


if __name__ == "__main__":
    main()
