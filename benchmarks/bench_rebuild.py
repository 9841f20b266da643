"""Rebuilds of a 1,000-clip library: no-op `build` / `check`, and one clip edited.

    python benchmarks/bench_rebuild.py [--clips 1000] [--jobs 1]

Procedural 7 s walks at 120 fps (about 0.46 MB of BVH each, like the issue's table) are written
once into a temporary folder; one manifest globs them. In one process, through the CLI, the run
times: a cold `build` (the baseline), the same `build` again (nothing moved: the stamp replays
it), `check` cold and again, and a `build` after one clip was edited (one clip re-measured,
the foot skate of only the blends that involve it played again), in process and as a new process.
Each is printed in wall and CPU seconds (this process and its children: on a shared machine the
steadier number) and as ratios to the cold build. The no-op cases are also timed
as a fresh `blendspace` process (`subprocess`), since Python's start-up and imports are part of
what a pre-commit hook pays. Targets: no-op <= 0.5 s, one edit <= 1 s. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from installed import compile_package

from blendspace_pipeline.cli import main as cli_main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip


def write_library(folder: Path, count: int, seconds: float) -> list[Path]:
    rng = np.random.default_rng(5)
    folder.mkdir(parents=True)
    paths = []
    for index in range(count):
        spec = GaitSpec(
            f"take_{index:04d}",
            speed=float(rng.uniform(0.0, 5.0)),
            turn_rate=float(rng.uniform(-170, 170)),
            duration=seconds,
            fps=120.0,
        )
        path = folder / f"{spec.name}.bvh"
        write_bvh_clip(generate(spec), path)
        paths.append(path)
    # Flushed now: the kernel's writeback of the new files must not run during the timed builds.
    os.sync()
    return paths


def _cpu() -> float:
    """CPU seconds of this process and its finished children (worker pools, `blendspace` runs)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def timed(action: Callable[[], object]) -> tuple[float, float]:
    """(wall, CPU) seconds: on a shared machine the CPU time is the steadier number."""
    start, cpu = time.perf_counter(), _cpu()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        action()
    return time.perf_counter() - start, _cpu() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=1000)
    parser.add_argument("--seconds", type=float, default=7.0)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    compile_package()  # bytecode, as an installed tool has it (see installed.py)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        os.environ["BLENDSPACE_CACHE_DIR"] = str(root / "cache")
        paths = write_library(root / "clips", args.clips, args.seconds)
        size = sum(p.stat().st_size for p in paths) / 1e6
        manifest = root / "manifest.yaml"
        manifest.write_text(
            "schema_version: 1\nname: library\nclips:\n  - path: clips/*.bvh\n"
            "output: {formats: [json, usd, html, png]}\n",
            encoding="utf-8",
        )
        build = ["build", str(manifest), "--no-fix", "--jobs", str(args.jobs)]
        check = ["check", str(manifest), "--jobs", str(args.jobs)]
        cold = timed(lambda: cli_main(build))
        rows = [(f"build, cold (baseline), {args.clips} clips, {size:.0f} MB", cold)]
        rows.append(("build, nothing changed (in process)", timed(lambda: cli_main(build))))
        command = [sys.executable, "-m", "blendspace_pipeline"]
        rows.append(
            (
                "build, nothing changed (new process)",
                timed(lambda: subprocess.run([*command, *build], capture_output=True, check=False)),
            )
        )
        rows.append(("check, first run (measurements cached)", timed(lambda: cli_main(check))))
        rows.append(
            (
                "check, nothing changed (new process)",
                timed(lambda: subprocess.run([*command, *check], capture_output=True, check=False)),
            )
        )
        edited = paths[len(paths) // 2]
        write_bvh_clip(generate(GaitSpec(edited.stem, speed=2.2, duration=args.seconds, fps=120.0)), edited)
        rows.append(("build, one clip edited", timed(lambda: cli_main(build))))
        rows.append(
            (
                "build, nothing changed after it (new process)",
                timed(lambda: subprocess.run([*command, *build], capture_output=True, check=False)),
            )
        )
        # The same edit as a pre-commit hook or an artist's save pays it: start-up and imports too.
        write_bvh_clip(generate(GaitSpec(edited.stem, speed=2.6, duration=args.seconds, fps=120.0)), edited)
        rows.append(
            (
                "build, one clip edited (new process)",
                timed(lambda: subprocess.run([*command, *build], capture_output=True, check=False)),
            )
        )
        print(f"{'':<52} {'wall':>9}  {'ratio':>8}   {'CPU':>9}  {'ratio':>8}")
        for label, (wall, cpu) in rows:
            print(f"{label:<52} {wall:8.3f}s  {wall / cold[0]:7.4f}x   {cpu:8.3f}s  {cpu / cold[1]:7.4f}x")


if __name__ == "__main__":
    main()
