"""Cold builds of a 1,000-clip library, in one and two processes (the issue's row: <= 10 s at 2 jobs).

    python benchmarks/bench_build.py [--clips 1000] [--seconds 7] [--fps 120] [--format bvh|usda] [--rounds 5]

Clips are procedural locomotion (7 s at 120 fps by default, about 0.46 MB of BVH each, speeds
and turn rates spread over the space), written once into a temporary folder. In one process:
- baseline: reading + measuring the files in a plain loop (`measure_file`, no cache), the floor a
  single-process build must pay;
- the measure stage alone (`measure_files`, no cache) with 1 and 2 processes: how the parallel
  part scales (the issue's goal: >= 1.8x at 2 jobs);
- `build --no-fix`, cold (an empty cache and output folder each time, a new process), with
  `--jobs 1` and `--jobs 2`, alternating for `--rounds` rounds: everything a cold build does, and
  its speed-up (of the medians, and the median of each round's own speed-up);
- `check` and `build` again with the cache filled;
- the machine's own ceiling, before and after the cold builds: the same read + measure loop (100
  clips, no cache) in one process, then in two processes at once, each doing all of it. Two
  processes on two vCPUs do not run at twice the speed of one (shared caches and memory
  bandwidth, a host that lends the second vCPU late): on this project's 2-vCPU machines the
  ceiling measured 1.46-2.36x within single runs, and a build's speed-up can only be read
  against it.
Each is printed in wall seconds and as a ratio to the baseline. Nothing here asserts a time; on
a shared machine run it alone (the speed-up is meaningless when the other core is busy).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from installed import compile_package

from blendspace_pipeline.cli import main as cli_main
from blendspace_pipeline.manifest import load_manifest
from blendspace_pipeline.manifest.paths import resolve_clip_files
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import cache
from blendspace_pipeline.pipeline.measure_stage import measure_file, measure_files


def write_library(folder: Path, count: int, fmt: str, seconds: float, fps: float) -> list[Path]:
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
            duration=seconds,
            fps=fps,
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
    # Flushed now: the kernel's writeback of the new files must not run during the timed builds.
    os.sync()
    return paths


def timed(label: str, action: object, baseline: float | None) -> float:
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        action()  # type: ignore[operator]
    seconds = time.perf_counter() - start
    ratio = f"  ({seconds / baseline:.2f}x baseline)" if baseline else ""
    print(f"{label:<34} {seconds:8.2f} s{ratio}")
    return seconds


def _loop(paths: list[Path]) -> None:
    for path in paths:
        measure_file(path, RigSettings(), None)


def machine_ceiling(paths: list[Path]) -> float:
    """Two processes doing the same CPU-bound loop at once against one doing it alone: the
    speed-up this machine gives perfectly parallel work at 2 jobs (2.0 on two idle cores)."""
    context = multiprocessing.get_context("fork")

    def run(copies: int) -> float:
        workers = [context.Process(target=_loop, args=(paths,)) for _ in range(copies)]
        start = time.perf_counter()
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
        return time.perf_counter() - start

    run(1)  # warm: the files in the page cache, the modules imported
    alone = min(run(1), run(1))
    together = min(run(2), run(2))
    return 2.0 * alone / together


def _built(done: subprocess.CompletedProcess[bytes]) -> None:
    """A build ran to its end: exit 0, or 1 for findings (the library has some); not a crash."""
    if done.returncode not in (0, 1):
        raise SystemExit(f"the build failed ({done.returncode}): {done.stderr.decode()[-2000:]}")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=1000)
    parser.add_argument("--seconds", type=float, default=7.0)
    parser.add_argument("--fps", type=float, default=120.0)
    parser.add_argument("--format", choices=("bvh", "usda"), default="bvh")
    parser.add_argument("--rounds", type=int, default=5, help="cold builds of each --jobs (median)")
    args = parser.parse_args()
    compile_package()  # bytecode, as an installed tool has it (see installed.py)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        start = time.perf_counter()
        paths = write_library(root / "clips", args.clips, args.format, args.seconds, args.fps)
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
        loaded = load_manifest(manifest)
        files = resolve_clip_files(loaded)

        def measure_stage(jobs: int) -> object:
            cache.forget_digests()  # no file digest remembered from the run before
            return measure_files(loaded, files, jobs=jobs)

        stage = {
            jobs: timed(f"measure stage, --jobs {jobs}", functools.partial(measure_stage, jobs), baseline)
            for jobs in (1, 2)
        }
        print(f"{'  measure stage speed-up at 2 jobs':<34} {stage[1] / stage[2]:8.2f}x")
        before = machine_ceiling(paths[:100])
        print(f"{'machine ceiling at 2 jobs, before':<34} {before:8.2f}x")
        # Cold builds alternate --jobs 1 and --jobs 2 for --rounds rounds (a shared machine's speed
        # drifts over a minute), each with an empty cache and its own output folder (nothing to
        # reuse from the run before), as a fresh process, as a user or CI runs it; medians count.
        cold: dict[int, list[float]] = {1: [], 2: []}
        for round_ in range(args.rounds):
            for jobs in (1, 2):
                os.environ["BLENDSPACE_CACHE_DIR"] = str(root / f"cache{jobs}-{round_}")
                command = [
                    *[sys.executable, "-m", "blendspace_pipeline", "build", str(manifest), "--no-fix"],
                    *["--jobs", str(jobs), "--out", str(root / f"out{jobs}-{round_}")],
                ]
                cold[jobs].append(
                    timed(
                        f"build --no-fix, cold, --jobs {jobs}",
                        lambda command=command: _built(subprocess.run(command, capture_output=True)),
                        baseline,
                    )
                )
        median = {jobs: statistics.median(times) for jobs, times in cold.items()}
        for jobs in (1, 2):
            print(f"{f'  median of {args.rounds}, --jobs {jobs}':<34} {median[jobs]:8.2f} s")
        speed_up = median[1] / median[2]
        print(f"{'  cold build speed-up at 2 jobs':<34} {speed_up:8.2f}x")
        # Each round's two builds run back to back, so their ratio is less exposed to the machine's
        # drift over the whole run than the ratio of the medians.
        pairs = [one / two for one, two in zip(cold[1], cold[2], strict=True)]
        print(f"{'  median of the rounds speed-ups':<34} {statistics.median(pairs):8.2f}x")
        ceiling = [before, machine_ceiling(paths[:100])]
        print(f"{'machine ceiling at 2 jobs, after':<34} {ceiling[1]:8.2f}x")
        print(f"{'  speed-up / mean ceiling':<34} {speed_up / statistics.mean(ceiling):8.2f}")
        # --jobs 1 as in earlier runs of this benchmark (the command's default is now auto).
        timed("check, warm cache", lambda: cli_main(["check", str(manifest), "--jobs", "1"]), baseline)
        (root / "manifest.yaml").write_text(manifest.read_text() + "# edited: no stamp replay\n")
        warm = ["build", str(manifest), "--no-fix", "--jobs", "1"]
        timed("build --no-fix, warm cache", lambda: cli_main(warm), baseline)


if __name__ == "__main__":
    main()
