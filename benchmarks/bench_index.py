"""`blendspace index` at library scale on Dask: 1 and 2 local workers, and the 100,000-take plan.

    python benchmarks/bench_index.py [--clips 10000] [--seconds 1.0] [--fps 30]

Generates ``--clips`` procedural takes (random speeds and turn rates, BVH, in 100 sub-folders)
once, then indexes them, in one process, into fresh stores: with 1 local worker (the baseline),
with 2, and again with 2 into the filled store (every take already measured: the cost of a
re-index that finds nothing new). Prints each time, the speed-up of 2 workers over 1, the
measured per-clip cost (worker-seconds per take) and what 100,000 takes would cost on N workers
at that rate. The machine is shared: compare the ratios, not the seconds. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from blendspace_pipeline.cli import main as cli_main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip


def write_library(folder: Path, count: int, seconds: float, fps: float) -> int:
    rng = np.random.default_rng(9)
    size = 0
    for index in range(count):
        shard = folder / f"day_{index % 100:02d}"
        shard.mkdir(parents=True, exist_ok=True)
        spec = GaitSpec(
            f"take_{index:06d}",
            speed=float(rng.uniform(0.0, 5.0)),
            turn_rate=float(rng.uniform(-170, 170)),
            duration=seconds,
            fps=fps,
        )
        path = shard / f"{spec.name}.bvh"
        write_bvh_clip(generate(spec), path)
        size += path.stat().st_size
    # Flushed now: the kernel's writeback of the new files must not run during the timed builds.
    os.sync()
    return size


def index(library: Path, store: Path, workers: int) -> float:
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = cli_main(["index", str(library), "--store", str(store), "--workers", str(workers)])
    assert code == 0, code
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=10_000)
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--fps", type=float, default=30.0)
    args = parser.parse_args()
    os.environ.pop("DASK_SCHEDULER_ADDRESS", None)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        start = time.perf_counter()
        size = write_library(root / "library", args.clips, args.seconds, args.fps)
        print(f"wrote {args.clips} takes ({size / 1e6:.0f} MB) in {time.perf_counter() - start:.0f} s")
        one = index(root / "library", root / "store1", 1)
        two = index(root / "library", root / "store2", 2)
        again = index(root / "library", root / "store2", 2)
        per_clip = one / args.clips
        print(f"index, 1 worker (baseline)        {one:8.1f} s   {1000 * per_clip:6.2f} ms per take")
        print(f"index, 2 workers                  {two:8.1f} s   {one / two:.2f}x faster than 1 worker")
        print(f"index again, 2 workers (all known) {again:7.1f} s   {again / one:.3f}x the baseline")
        print(f"100,000 takes at {1000 * per_clip:.2f} ms per take and worker:")
        for workers in (1, 2, 8, 32, 128):
            print(
                f"  {workers:4d} workers: {100_000 * per_clip / workers / 60:8.1f} min (linear; scheduler overhead excluded)"
            )


if __name__ == "__main__":
    main()
