"""Time `blendspace build` / `check` on a 1,000-clip manifest (the issue's target: < 10 s on 2 cores).

    python benchmarks/bench_build.py [--clips 1000] [--format bvh|usda] [--jobs 2]

Clips are procedural locomotion (1 s at 30 fps, speeds and turn rates spread over the space),
written once into a temporary folder. The run reports, in one process:
- baseline: reading + measuring the same files in a plain loop (`measure_file`, no cache), the
  floor any build must pay;
- `check` cold (empty cache) and warm (cache filled), and a full `build --no-fix`;
and prints each as seconds and as a ratio to the baseline, so machines of different speed can be
compared. Nothing here asserts a time; the numbers go in the issue notes.
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
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.measure_stage import measure_file


def write_library(folder: Path, count: int, fmt: str) -> list[Path]:
    rng = np.random.default_rng(7)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for index in range(count):
        speed = float(rng.uniform(0.0, 5.0))
        direction = 180.0 if rng.random() < 0.25 else 0.0
        spec = GaitSpec(
            f"clip_{index:04d}",
            speed=speed,
            direction=direction,
            turn_rate=float(rng.uniform(-170, 170)),
            duration=1.0,
        )
        clip = generate(spec)
        path = folder / f"{spec.name}.{fmt}"
        if fmt == "bvh":
            from blendspace_pipeline.writers.bvh import write_bvh_clip

            write_bvh_clip(clip, path)
        else:
            from blendspace_pipeline.writers.usd_clip import write_usd_clip

            write_usd_clip(clip, path, meters_per_unit=1.0, up_axis="y")
        paths.append(path)
    return paths


def timed(label: str, action: object, baseline: float | None) -> float:
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        action()  # type: ignore[operator]
    seconds = time.perf_counter() - start
    ratio = f"  ({seconds / baseline:.2f}x baseline)" if baseline else ""
    print(f"{label:<34} {seconds:8.2f} s{ratio}")
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=1000)
    parser.add_argument("--format", choices=("bvh", "usda"), default="bvh")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        start = time.perf_counter()
        paths = write_library(root / "clips", args.clips, args.format)
        size = sum(p.stat().st_size for p in paths) / 1e6
        print(
            f"wrote {len(paths)} {args.format} clips ({size:.1f} MB) in {time.perf_counter() - start:.1f} s"
        )
        manifest = root / "manifest.yaml"
        manifest.write_text(
            f"schema_version: 1\nname: big\nclips:\n  - path: clips/*.{args.format}\n"
            "output: {formats: [json, usd, html, png]}\n"
        )
        os.environ["BLENDSPACE_CACHE_DIR"] = "off"
        baseline = timed(
            "baseline: read + measure loop",
            lambda: [measure_file(p, RigSettings(), None) for p in paths],
            None,
        )
        os.environ["BLENDSPACE_CACHE_DIR"] = str(root / "cache")
        jobs = ["--jobs", str(args.jobs)]
        timed(
            f"check, cold cache, --jobs {args.jobs}",
            lambda: cli_main(["check", str(manifest), *jobs]),
            baseline,
        )
        timed("check, warm cache", lambda: cli_main(["check", str(manifest), *jobs]), baseline)
        os.environ["BLENDSPACE_CACHE_DIR"] = str(root / "cache2")
        timed(
            f"build --no-fix, cold, --jobs {args.jobs}",
            lambda: cli_main(["build", str(manifest), "--no-fix", *jobs]),
            baseline,
        )
        timed(
            "build --no-fix, warm cache",
            lambda: cli_main(["build", str(manifest), "--no-fix", *jobs]),
            baseline,
        )


if __name__ == "__main__":
    main()
