"""Time `blendspace check` with a cold and a warm measurement cache, and the per-run overhead.

    python benchmarks/bench_check.py [--clips 100] [--repeat 5]

Procedural clips (speeds 0..5 m/s forward and backward, turn rates -170..170 deg/s, 1 s at
30 fps) are written as USD into a temporary folder with one manifest. `check` runs in-process
through `blendspace_pipeline.cli.main`, the same code path as the console script:
- cold: an empty cache folder (`BLENDSPACE_CACHE_DIR`) for each run, so every clip is read and
  measured;
- warm: the cache is filled, so clips are hashed and not parsed;
- the same for a one-clip manifest, which is the fixed cost of one run (manifest, rule loading,
  triangulation, rules, printing).
The first call in the process is timed on its own: it pays for imports (scipy, pxr). The
script prints the median of `--repeat` runs for each case, in seconds, plus the warm/cold ratio.
It asserts nothing, and the numbers go in the issue notes.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from blendspace_pipeline.cli import main as cli_main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip


def write_project(folder: Path, count: int) -> Path:
    """``count`` clips spread over the default space, and a manifest globbing them."""
    rng = np.random.default_rng(11)
    (folder / "clips").mkdir(parents=True)
    for index in range(count):
        spec = GaitSpec(
            f"clip_{index:03d}",
            speed=float(rng.uniform(0.0, 5.0)),
            direction=180.0 if rng.random() < 0.25 else 0.0,
            turn_rate=float(rng.uniform(-170.0, 170.0)),
            duration=1.0,
        )
        path = folder / "clips" / f"{spec.name}.usda"
        write_usd_clip(generate(spec, source=path), path, meters_per_unit=1.0, up_axis="y")
    manifest = folder / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: bench\nclips:\n  - path: clips/*.usda\n", encoding="utf-8")
    return manifest


def check_seconds(manifest: Path, cache: Path) -> float:
    os.environ["BLENDSPACE_CACHE_DIR"] = str(cache)
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = cli_main(["check", str(manifest), "--jobs", "1"])  # as before `auto` was the default
    seconds = time.perf_counter() - start
    if code not in (0, 1):
        raise SystemExit(f"check failed with exit code {code}")
    return seconds


def median_of(repeat: int, run: Callable[[int], float]) -> float:
    return statistics.median(run(attempt) for attempt in range(repeat))


def bench(manifest: Path, scratch: Path, repeat: int) -> tuple[float, float]:
    """Median cold and warm seconds of `check` on ``manifest``."""
    cold = median_of(repeat, lambda n: check_seconds(manifest, scratch / f"cold-{n}"))
    warm_cache = scratch / "warm"
    check_seconds(manifest, warm_cache)  # fill it
    warm = median_of(repeat, lambda n: check_seconds(manifest, warm_cache))
    return cold, warm


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    saved = os.environ.get("BLENDSPACE_CACHE_DIR")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            start = time.perf_counter()
            many = write_project(root / "many", args.clips)
            one = write_project(root / "one", 1)
            print(f"wrote {args.clips + 1} clips in {time.perf_counter() - start:.2f} s")
            first = check_seconds(one, root / "first")
            print(f"{'first check in the process (imports)':<40} {first:8.3f} s")
            for label, manifest in ((f"{args.clips} clips", many), ("1 clip", one)):
                cold, warm = bench(manifest, root / label.replace(" ", "-"), args.repeat)
                print(f"{label + ', cold cache':<40} {cold:8.3f} s")
                print(f"{label + ', warm cache':<40} {warm:8.3f} s   warm/cold = {warm / cold:.2f}")
    finally:
        if saved is None:
            os.environ.pop("BLENDSPACE_CACHE_DIR", None)
        else:
            os.environ["BLENDSPACE_CACHE_DIR"] = saved


if __name__ == "__main__":
    main()
