"""Time `blendspace --version` and `blendspace --help` (the issue's target: under 0.3 s).

    python benchmarks/bench_cli_startup.py [--runs 10]

Each command runs as a fresh interpreter (`python -m blendspace_pipeline ...`), the way a shell or
pre-commit starts it. The baseline, in the same process and on the same machine, is a bare
interpreter (`python -c pass`); the eager parser (every command imported, what `--version` used to
cost) is timed too. Prints the median seconds and the ratio to the baseline; asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

from installed import compile_package

CASES = {
    "baseline: python -c pass": [sys.executable, "-c", "pass"],
    "blendspace --version": [sys.executable, "-m", "blendspace_pipeline", "--version"],
    "blendspace --help": [sys.executable, "-m", "blendspace_pipeline", "--help"],
    "eager parser (all commands imported)": [
        sys.executable,
        "-c",
        "from blendspace_pipeline.cli import build_parser; build_parser()",
    ],
}


def median_seconds(command: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(command, capture_output=True, check=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    args = parser.parse_args()
    compile_package()  # bytecode, as an installed tool has it (see installed.py)
    results = {name: median_seconds(command, args.runs) for name, command in CASES.items()}
    baseline = results["baseline: python -c pass"]
    for name, seconds in results.items():
        print(f"{name:40s} {seconds:6.3f} s  x{seconds / baseline:5.1f} baseline")


if __name__ == "__main__":
    main()
