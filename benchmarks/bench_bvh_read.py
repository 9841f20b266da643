"""BVH reading speed: parse throughput per core, read + FK, against the previous parser and bvhio.

    python benchmarks/bench_bvh_read.py [--frames 840 10000 100000] [--small 1000] [--repeat 5]

Three workloads:

1. the CMU takes in ../shared/data/cmu (when present);
2. long synthetic takes (``--frames`` at 120 fps, 19 joints, written by our own writer; 840
   frames is the 7 s, 0.46 MB clip of the 1,000-clip library);
3. ``--small`` one-second procedural clips in a temporary folder, to show the per-file overhead
   (bvhio reads only the first ``--bvhio-small`` of them; its per-file time is what is compared);
4. ``--library`` distinct 7 s 120 fps takes (0.46 MB each, random speeds and turns, as
   `bench_rebuild.write_library` writes the 1,000-clip library), each parsed once in turn after a
   warm-up: the mean CPU time per take of ``parse``, ``read`` and ``+FK``, and parse MB/s. This
   is what a build pays per file (a new file every time, nothing warm but the rig), where the
   best of repeated runs on one file (above) hides the per-file costs.

For each file, the best of ``--repeat`` runs in CPU time (``time.process_time``: one core, so
the figures hold on a shared machine) of:

- ``parse``: the text to the header and the (channels, frames) MOTION values, `bvh.parse`
  (the compiled kernel, `native`, when built); the issue's "BVH parse throughput" row, in MB of
  file per second;
- ``pyarrow``: the same without the kernels (pyarrow's CSV reader), and ``numpy``: with pyarrow
  hidden too (numpy ``fromstring``), with their ratios to ``parse``;
- ``read``: to a `Clip` (Euler angles to quaternions included), and ``+FK``: read and forward
  kinematics, the floor under every cold build, and its ratio without the kernels;
- bvhio's ``readAsHierarchy`` and the ratios bvhio / read and bvhio / read+FK. bvhio's time grows
  faster than the file (10k frames, 5.5 MB: about 50 s), so it is skipped above ``--bvhio-max-mb``.

Targets: parse >= 100 MB/s per core; read + FK >= 20x faster than bvhio. bvhio and the numpy
parser are baselines run in the same process, so the ratios mean the same on any machine; MB/s
does not.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from blendspace_pipeline import native
from blendspace_pipeline.motion.clip import forward_kinematics
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import bvh
from blendspace_pipeline.readers.bvh import parse, read
from blendspace_pipeline.writers.bvh import write_bvh_clip

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
FPS = 120.0


def best(action: Callable[[], object], repeat: int) -> float:
    """The least CPU time of ``repeat`` runs (after one warm-up run)."""
    action()
    times = []
    for _ in range(repeat):
        start = time.process_time()
        action()
        times.append(time.process_time() - start)
    return min(times)


def without_kernels(action: Callable[[], object]) -> Callable[[], object]:
    """``action`` without the compiled kernels (`native`): the reader's pyarrow parser and numpy FK."""

    def run() -> object:
        saved = native.kernels
        native.kernels = None
        try:
            return action()
        finally:
            native.kernels = saved

    return run


def without_pyarrow(action: Callable[[], object]) -> Callable[[], object]:
    """``action`` without the kernels and with ``import pyarrow.csv`` failing: the reader falls
    back to numpy's parser."""

    @without_kernels
    def run() -> object:
        saved = sys.modules.get("pyarrow.csv")
        sys.modules["pyarrow.csv"] = None  # type: ignore[assignment]
        try:
            return action()
        finally:
            if saved is None:
                del sys.modules["pyarrow.csv"]
            else:
                sys.modules["pyarrow.csv"] = saved

    return run


def bench_file(path: Path, repeat: int, bvhio_max_mb: float) -> None:
    import bvhio

    size = path.stat().st_size / 1e6
    parsed = best(lambda: parse(path), repeat)
    arrow = best(without_kernels(lambda: parse(path)), repeat)
    numpy = best(without_pyarrow(lambda: parse(path)), repeat)
    ours = best(lambda: read(path), repeat)
    with_fk = best(lambda: forward_kinematics(read(path)[0]), repeat)
    plain_fk = best(without_kernels(lambda: forward_kinematics(read(path)[0])), repeat)
    line = (
        f"{path.name:<20} {size:6.2f} MB  parse {parsed * 1e3:7.1f} ms = {size / parsed:4.0f} MB/s/core "
        f"(pyarrow {size / arrow:3.0f} MB/s, x{arrow / parsed:4.1f}; numpy {size / numpy:3.0f} MB/s, "
        f"x{numpy / parsed:4.1f})  read {ours * 1e3:7.1f} ms = {size / ours:4.0f} MB/s  "
        f"+FK {with_fk * 1e3:7.1f} ms = {size / with_fk:4.0f} MB/s (no kernels x{plain_fk / with_fk:4.1f})"
    )
    if size > bvhio_max_mb:
        print(f"{line}  bvhio skipped (> {bvhio_max_mb:g} MB)", flush=True)
        return
    start = time.process_time()
    bvhio.readAsHierarchy(str(path))
    theirs = time.process_time() - start
    if size < 2:
        theirs = min(theirs, best(lambda: bvhio.readAsHierarchy(str(path)), max(1, repeat // 2)))
    print(
        f"{line}  bvhio {theirs * 1e3:8.0f} ms: x{theirs / ours:5.1f} (with FK x{theirs / with_fk:5.1f})",
        flush=True,
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
        f"{count} x 1 s clips {size:7.2f} MB  read {ours * 1e3:8.1f} ms = {per_ours * 1e3:.3f} ms/file "
        f"({size / ours:5.0f} MB/s)  bvhio {per_theirs * 1e3:.2f} ms/file (first {len(sample)})  "
        f"ratio {per_theirs / per_ours:6.1f}x"
    )


def bench_library(folder: Path, count: int) -> None:
    """Mean CPU time per take over ``count`` distinct library takes (each read once per pass)."""
    rng = np.random.default_rng(5)
    paths = []
    for index in range(count + 5):
        spec = GaitSpec(
            f"take_{index:04d}",
            speed=float(rng.uniform(0.0, 5.0)),
            turn_rate=float(rng.uniform(-170, 170)),
            duration=7.0,
            fps=FPS,
        )
        paths.append(folder / f"{spec.name}.bvh")
        write_bvh_clip(generate(spec), paths[-1])
    warm, timed = paths[:5], paths[5:]
    for path in warm:
        forward_kinematics(read(path)[0])
    size = sum(p.stat().st_size for p in timed) / 1e6 / len(timed)

    def one_pass() -> dict[str, float]:
        totals = {"parse": 0.0, "read": 0.0, "+FK": 0.0}
        for path in timed:
            start = time.process_time()
            parse(path)
            middle = time.process_time()
            clip = read(path)[0]
            read_done = time.process_time()
            forward_kinematics(clip)
            end = time.process_time()
            totals["parse"] += middle - start
            totals["read"] += read_done - middle
            totals["+FK"] += end - middle
        return {key: value / len(timed) for key, value in totals.items()}

    for label, run in (("", one_pass), (" (no kernels)", without_kernels(one_pass))):
        run()  # warm: the files are in the page cache for both passes
        per: dict[str, float] = run()  # type: ignore[assignment]
        print(
            f"{len(timed)} library takes{label} {size:5.2f} MB each, mean CPU per take: parse "
            f"{per['parse'] * 1e3:6.2f} ms = {size / per['parse']:4.0f} MB/s/core  read {per['read'] * 1e3:6.2f} ms "
            f"= {size / per['read']:4.0f} MB/s  +FK {per['+FK'] * 1e3:6.2f} ms = {size / per['+FK']:4.0f} MB/s"
        )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--frames", type=int, nargs="*", default=[840, 10_000, 100_000], help="frames of each synthetic take"
    )
    parser.add_argument("--bvhio-max-mb", type=float, default=10.0, help="larger files: ours only")
    parser.add_argument("--small", type=int, default=1000, help="number of one-second clips")
    parser.add_argument("--bvhio-small", type=int, default=100, help="small clips bvhio reads")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--library", type=int, default=100, help="distinct 7 s library takes (0: skip)")
    args = parser.parse_args()
    # A build switches to pyarrow after its first few MB; measure it from the first file.
    bvh.ARROW_AFTER_BYTES = 0
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
        if args.library > 0:
            library = folder / "library"
            library.mkdir()
            bench_library(library, args.library)
        if args.small > 0:
            small = folder / "small"
            small.mkdir()
            bench_small(small, args.small, min(args.bvhio_small, args.small), args.repeat)


if __name__ == "__main__":
    main()
