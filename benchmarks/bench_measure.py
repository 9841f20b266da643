"""Measurement of long clips: linear in the clip's length, and at most twice the read time.

    python benchmarks/bench_measure.py [--seconds 10 60 300]

Each clip is a procedural walk at 120 fps written as BVH once into a temporary folder (a take that
does not loop: it is cut mid-stride, so the stride period comes from the frequency fit, the part
that used to be quadratic). For every length the run reports, in one process: the read time (the
baseline), the measure time and their ratio (the issue's goal: <= 2x), and the measure time per
second of clip, which stays flat when measurement is linear. The quadratic grid fit the chirp-z
transform replaced is timed beside it on the same signal, as a second baseline. Then the per-clip
row of the 1,000-clip library (`--library-clips` takes of 7 s at 120 fps, as
`bench_rebuild.write_library` writes them): read and measure CPU time per clip, and their ratio.
Times are CPU time (`time.process_time`): the machine is shared. Nothing here asserts a time; the
numbers go in the issue notes.
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
    start = time.process_time()
    for i in range(0, len(grid), 256):
        phase._sinusoid_fit(signal[::thin], times, grid[i : i + 256])
    return time.process_time() - start


def library_row(folder: Path, count: int, settings: RigSettings) -> None:
    """Read and measure CPU time per clip over ``count`` library takes (7 s at 120 fps, random
    speeds and turns), after one warm-up clip so imports and first calls are not counted."""
    rng = np.random.default_rng(5)
    paths = []
    for index in range(count + 1):
        spec = GaitSpec(
            f"take_{index:04d}",
            speed=float(rng.uniform(0.0, 5.0)),
            turn_rate=float(rng.uniform(-170, 170)),
            duration=7.0,
            fps=120.0,
        )
        paths.append(folder / f"{spec.name}.bvh")
        write_bvh_clip(generate(spec), paths[-1])
    measure(read_clips(paths[0])[0], settings)  # warm-up
    read = measured = 0.0
    for path in paths[1:]:
        start = time.process_time()
        clip = read_clips(path)[0]
        read += time.process_time() - start
        start = time.process_time()
        measure(clip, settings)
        measured += time.process_time() - start
    print(
        f"\n{count} library clips (7 s, 120 fps, {paths[1].stat().st_size / 1e6:.2f} MB each), CPU per clip: "
        f"read {1000.0 * read / count:.2f} ms, measure {1000.0 * measured / count:.2f} ms, "
        f"measure/read {measured / read:.2f}x"
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, nargs="+", default=[10.0, 60.0, 300.0])
    parser.add_argument(
        "--skip-direct-above", type=float, default=60.0, help="the old grid takes minutes there"
    )
    parser.add_argument("--library-clips", type=int, default=50, help="0 skips the per-clip row")
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
            start = time.process_time()
            clip = read_clips(path)[0]
            read = time.process_time() - start
            start = time.process_time()
            measure(clip, settings)
            measured = time.process_time() - start
            old = "-"
            if seconds <= args.skip_direct_above:
                found = phase.foot_signal(clip, settings)
                assert found is not None
                old = f"{direct_grid_seconds(found[0], clip.fps):.2f}"
            print(
                f"{seconds:>7g}s {path.stat().st_size / 1e6:>6.1f} {read:>8.3f} {measured:>10.3f} "
                f"{measured / read:>12.2f}x {1000.0 * measured / seconds:>14.2f} {old:>11}"
            )
        if args.library_clips > 0:
            library = Path(tmp) / "library"
            library.mkdir()
            library_row(library, args.library_clips, settings)


if __name__ == "__main__":
    main()
