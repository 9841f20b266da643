"""BVH reading speed against `bvhio.readAsHierarchy`, in the same process.

    python benchmarks/bench_bvh_read.py [--frames 10000 100000] [--small 1000] [--repeat 3]

Three workloads:

1. the CMU takes in ../shared/data/cmu (when present);
2. long synthetic takes (``--frames`` at 120 fps, 19 joints, written by our own writer);
3. ``--small`` one-second procedural clips in a temporary folder, to show the per-file overhead
   (bvhio reads only the first ``--bvhio-small`` of them; its per-file time is what is compared).

For each it prints the best of ``--repeat`` runs of our `read` (MB/s), of read + forward
kinematics, and of bvhio's ``readAsHierarchy``, and the speed ratio bvhio / ours. bvhio's time
grows faster than the file (10k frames, 5.5 MB: about 10 s; 100k frames, 55 MB: over 10 minutes
unfinished), so it is skipped on files above ``--bvhio-max-mb``. Targets: our read >= 20x faster than bvhio and >= 50 MB/s.
bvhio is the baseline, so the ratio means the same on any machine; MB/s does not.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers.bvh import read
from blendspace_pipeline.writers.bvh import write_bvh_clip

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
FPS = 120.0


def best(action: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return min(times)


def bench_file(path: Path, repeat: int, bvhio_max_mb: float) -> None:
    import bvhio

    size = path.stat().st_size / 1e6
    ours = best(lambda: read(path), repeat)
    with_fk = best(lambda: forward_kinematics(read(path)[0]), repeat)
    line = (
        f"{path.name:<18} {size:7.2f} MB  ours {ours * 1e3:8.1f} ms = {size / ours:5.0f} MB/s  "
        f"(+FK {with_fk * 1e3:8.1f} ms)"
    )
    if size > bvhio_max_mb:
        print(f"{line}  bvhio skipped (> {bvhio_max_mb:g} MB)")
        return
    theirs = best(lambda: bvhio.readAsHierarchy(str(path)), 1 if size > 2 else repeat)
    print(
        f"{line}  bvhio {theirs * 1e3:10.1f} ms  ratio {theirs / ours:6.1f}x  (with FK {theirs / with_fk:6.1f}x)"
    )


def bench_small(folder: Path, count: int, bvhio_count: int, repeat: int) -> None:
    import bvhio

    clip = generate(GaitSpec("small", speed=1.4, duration=1.0, fps=FPS))
    paths = [folder / f"small_{index:04d}.bvh" for index in range(count)]
    for path in paths:
        write_bvh_clip(clip, path)
    size = sum(p.stat().st_size for p in paths) / 1e6
    ours = best(lambda: [read(p) for p in paths], repeat)
    sample = paths[:bvhio_count]
    theirs = best(lambda: [bvhio.readAsHierarchy(str(p)) for p in sample], 1) if sample else float("nan")
    per_ours, per_theirs = ours / count, theirs / max(1, len(sample))
    print(
        f"{count} x 1 s clips {size:7.2f} MB  ours {ours * 1e3:8.1f} ms = {per_ours * 1e3:.3f} ms/file "
        f"({size / ours:5.0f} MB/s)  bvhio {per_theirs * 1e3:.2f} ms/file (first {len(sample)})  "
        f"ratio {per_theirs / per_ours:6.1f}x"
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--frames", type=int, nargs="*", default=[10_000, 100_000], help="frames of each synthetic take"
    )
    parser.add_argument("--bvhio-max-mb", type=float, default=10.0, help="larger files: ours only")
    parser.add_argument("--small", type=int, default=1000, help="number of one-second clips")
    parser.add_argument("--bvhio-small", type=int, default=100, help="small clips bvhio reads")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    files = sorted(SHARED.glob("*.bvh")) if SHARED.is_dir() else []
    if not files:
        print(f"({SHARED} not found: CMU files skipped)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for path in files:
            bench_file(path, args.repeat, args.bvhio_max_mb)
        for frames in args.frames:
            long = folder / f"walk_{frames}f.bvh"
            spec = GaitSpec("walk", speed=1.4, turn_rate=10.0, duration=(frames - 1) / FPS, fps=FPS)
            write_bvh_clip(generate(spec), long)
            bench_file(long, args.repeat, args.bvhio_max_mb)
            long.unlink()
        if args.small > 0:
            small = folder / "small"
            small.mkdir()
            bench_small(small, args.small, min(args.bvhio_small, args.small), args.repeat)


if __name__ == "__main__":
    main()
