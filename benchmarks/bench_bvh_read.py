"""BVH read + FK + measurement against `bvhio.readAsHierarchy`, in the same process.

    python benchmarks/bench_bvh_read.py [--seconds 60] [--repeat 3]

Files: the CMU takes in ../shared/data/cmu (when present) and a long procedural clip
(`--seconds` at 120 fps, 20 joints, written by our own writer). For each file it prints the best
of `--repeat` runs of: our read; our read + forward kinematics + measurement; bvhio's
`readAsHierarchy`; and the ratios (targets from the issue: read + FK >= 20x faster than bvhio,
parsing >= 50 MB/s). bvhio is the baseline, so the ratios hold on any machine.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from blendspace_pipeline.clip import forward_kinematics
from blendspace_pipeline.detect import RigSettings
from blendspace_pipeline.measure import measure
from blendspace_pipeline.procedural import GaitSpec, generate
from blendspace_pipeline.readers.bvh import read
from blendspace_pipeline.writers.bvh import write_bvh_clip

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"


def best(action: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return min(times)


def bench(path: Path, repeat: int) -> None:
    import bvhio

    size = path.stat().st_size / 1e6
    ours = best(lambda: read(path), repeat)
    full = best(lambda: measure(read(path)[0], RigSettings()), repeat)  # measure runs FK itself
    fk = best(lambda: forward_kinematics(read(path)[0]), repeat)
    theirs = best(lambda: bvhio.readAsHierarchy(str(path)), max(1, repeat // 2))
    print(
        f"{path.name:<16} {size:6.2f} MB  read {ours * 1e3:8.1f} ms ({size / ours:5.0f} MB/s)  "
        f"read+FK {fk * 1e3:8.1f} ms  read+FK+measure {full * 1e3:8.1f} ms  "
        f"bvhio {theirs * 1e3:9.1f} ms  -> read+FK {theirs / fk:5.1f}x faster"
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    files = sorted(SHARED.glob("*.bvh")) if SHARED.is_dir() else []
    with tempfile.TemporaryDirectory() as tmp:
        long = Path(tmp) / "long_walk.bvh"
        spec = GaitSpec("long_walk", speed=1.4, turn_rate=10.0, duration=args.seconds, fps=120.0)
        write_bvh_clip(generate(spec), long)
        for path in [*files, long]:
            bench(path, args.repeat)


if __name__ == "__main__":
    main()
