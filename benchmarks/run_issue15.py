"""Every row of the speed-and-scale table (issue 15) in one run, one benchmark script per row.

    python benchmarks/run_issue15.py [--quick] [--only ROW ...]

Each script runs in its own fresh interpreter, one after another (never two at once: they
would time each other), and prints its baseline and ratios; this runner prints them under
the table's rows and the wall time each took. `--quick` shrinks every workload (fewer clips,
shorter takes) for a smoke run; the issue's numbers come from the full run. The index row
(10,000 takes, 1 and 2 Dask workers) is the longest, about ten minutes on two cores.
Nothing is asserted: the numbers go in the issue notes.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# row -> (the table's row, full arguments, quick arguments)
ROWS: dict[str, tuple[str, list[str], list[str]]] = {
    "read": (
        "BVH read + FK vs bvhio; BVH parse throughput per core",
        ["bench_bvh_read.py", "--frames", "840", "7200", "--small", "0", "--repeat", "3"],
        ["bench_bvh_read.py", "--frames", "840", "--small", "0", "--repeat", "1"],
    ),
    "measure": (
        "measure one 60 s / 300 s clip vs its read time",
        ["bench_measure.py", "--seconds", "60", "300"],
        ["bench_measure.py", "--seconds", "60", "--library-clips", "10"],
    ),
    "cold": (
        "1,000 clips cold, --jobs 1 / --jobs 2",
        ["bench_build.py", "--clips", "1000", "--seconds", "7", "--fps", "120"],
        ["bench_build.py", "--clips", "100", "--seconds", "7", "--fps", "120"],
    ),
    "rebuild": (
        "1,000 clips no-op rebuild; one clip edited",
        ["bench_rebuild.py", "--clips", "1000"],
        ["bench_rebuild.py", "--clips", "100"],
    ),
    "server": (
        "1,000 clips, one clip edited, new process: without and with the build server, --jobs 1",
        ["bench_server.py", "--clips", "1000", "--jobs", "1"],
        ["bench_server.py", "--clips", "100", "--edits", "1", "--jobs", "1"],
    ),
    "server-jobs2": (
        "the same with --jobs 2 (writers in parallel; what --jobs auto gives on 2 CPUs)",
        ["bench_server.py", "--clips", "1000", "--jobs", "2"],
        ["bench_server.py", "--clips", "100", "--edits", "1", "--jobs", "2"],
    ),
    "scale": (
        "10,000 samples, stages after measurement",
        ["bench_scale.py", "--samples", "10000", "--browser"],
        ["bench_scale.py", "--samples", "2000"],
    ),
    "eval": (
        "eval: one query vs the batch evaluator, 100k queries",
        ["bench_eval.py", "--samples", "100", "--queries", "100000"],
        ["bench_eval.py", "--samples", "100", "--queries", "10000", "--runs", "1"],
    ),
    "index": (
        "library index on Dask: 1 and 2 workers, the 100,000-take plan",
        ["bench_index.py", "--clips", "10000"],
        ["bench_index.py", "--clips", "200"],
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="small workloads, for a smoke run")
    parser.add_argument("--only", nargs="+", choices=sorted(ROWS), help="run these rows only")
    args = parser.parse_args()
    failed = []
    for name in args.only or list(ROWS):
        title, full, quick = ROWS[name]
        command = [
            sys.executable,
            str(HERE / (quick if args.quick else full)[0]),
            *(quick if args.quick else full)[1:],
        ]
        print(
            f"\n## {title}\n$ python benchmarks/{' '.join(command[1:]).replace(str(HERE) + '/', '')}",
            flush=True,
        )
        start = time.perf_counter()
        done = subprocess.run(command, check=False)
        print(f"(row took {time.perf_counter() - start:.0f} s)", flush=True)
        if done.returncode:
            failed.append(name)
    if failed:
        sys.exit(f"failed: {', '.join(failed)}")


if __name__ == "__main__":
    main()
