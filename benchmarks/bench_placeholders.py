"""Cost of checking placeholders by simulation (issue 11), as a ratio to the same check without it.

    python benchmarks/bench_placeholders.py [--clips 13 100 300] [--repeat 3]

Procedural clips (speeds -2..5 m/s, turn rates -150..150 deg/s, 1 s at 30 fps) are written as
USD into a temporary folder; the measurement cache is filled first. For each size the script
times `analyse(converge=False)` (the baseline: read the cache, place, triangulate, run the rules)
and `analyse(converge=True)` in the same process, and prints the medians and their ratio. The
simulation budget (`pipeline.placeholders.BUDGET`) caps the large sets. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.writers.usd_clip import write_usd_clip


def _project(root: Path, count: int) -> Path:
    rng = np.random.default_rng(11)
    folder = root / "clips"
    folder.mkdir(parents=True)
    for index in range(count):
        speed = float(rng.uniform(-2.0, 5.0))
        turn = float(rng.uniform(-150.0, 150.0))
        spec = GaitSpec(
            f"c{index:04d}", speed=abs(speed), direction=180.0 if speed < 0 else 0.0, turn_rate=turn
        )
        write_usd_clip(generate(spec), folder / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = root / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: bench\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
        "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n"
    )
    return manifest


def _median(manifest: Path, converge: bool, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        analyse(manifest, converge=converge)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--clips", type=int, nargs="+", default=[13, 100, 300])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        os.environ["BLENDSPACE_CACHE_DIR"] = str(Path(temporary) / "cache")
        for count in args.clips:
            manifest = _project(Path(temporary) / f"n{count}", count)
            analyse(manifest, converge=False)  # fill the cache, pay the imports
            base = _median(manifest, False, args.repeat)
            simulated = _median(manifest, True, args.repeat)
            print(
                f"{count:5d} clips: check {base:.3f} s, with placeholder simulation {simulated:.3f} s, "
                f"ratio {simulated / base:.2f}"
            )


if __name__ == "__main__":
    main()
